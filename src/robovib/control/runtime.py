"""Controller files and the run-time controller a robot bridge calls (issue 40).

* :func:`design_controller` designs one controller of :data:`~robovib.control.design.DESIGNS`
  from *any* pose model along a :class:`~robovib.control.path_design.ControlPath` and returns
  the versioned, self-describing controller document (gains along the path, the modes they
  were designed on and which model output that is, the period tracker's and the guard's
  settings, the command period, sample rate and delay assumed, the band over which stability
  was checked, units, the model's provenance). :func:`write_controller_file` writes it.
* :func:`load_controller` reads that file into a :class:`RuntimeController`: ``reset()`` then
  ``step(measurement)`` once per command cycle (the force and tracker samples of the cycle and
  the path coordinate) -> the correction [mm]. The same object runs in the closed-loop
  simulation (:meth:`RuntimeController.planned`) and over a logged cut (:func:`replay`), so
  design, replay and simulation share one controller.

The cycle budget is the RSI cycle, 4 ms (``timing.budget_s`` in the file);
``benchmarks/bench_control_runtime.py`` measures ``step`` at p50 / p99. The buffers of a run
are allocated by ``reset`` for ``max_duration_s`` (default 60 s of cutting); a longer run is
an error, not a reallocation. Wiring to a KUKA RSI/EKI bridge: ``docs/control_runtime.md``.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..modal.parameters import ModalParameters
from .controllers import PathCursor
from .design import (
    DESIGNS,
    GUARD_DEFAULTS,
    TRACKER_DEFAULTS,
    PathTables,
    assemble_controller,
    check_controller_names,
    design_tables,
)
from .path_design import ControlPath, PathDesign
from .pose_plants import SECOND_MODE_HYPOTHESES
from .schedule import GainSchedule

__all__ = [
    "FORMAT",
    "FORMAT_VERSION",
    "Measurement",
    "ReplayResult",
    "RuntimeController",
    "design_controller",
    "load_controller",
    "model_poses_from_record",
    "replay",
    "write_controller_file",
]

FORMAT = "robovib.controller"
FORMAT_VERSION = 1
_MAX_FILE_BYTES = 50_000_000
_AXES = {"x": 0, "y": 1, "z": 2}
_UNITS = {
    "grid_s_m": "m (tool-tip travel along the path)",
    "path.vertices": "the model's input units (path.input_names)",
    "path.s_m": "m",
    "modes.fn_hz": "Hz", "modes.fn_std_hz": "Hz", "modes.stiffness_n_per_m": "N/m",
    "modes.stiffness_std_n_per_m": "N/m", "modes.damping_ratio": "1",
    "modes.damping_std_ns_per_m": "N*s/m",
    "gains.schedule.w1": "m/m (correction per tool-tip displacement)",
    "gains.schedule.w2": "s (correction per tool-tip velocity, m per m/s)",
    "gains.schedule.r": "1 (LQR input weight)",
    "gains.constant": "[w1 m/m, w2 s]",
    "gains.robust": "[K_x m/m, K_v s, K_u1..K_ud m/m] per design point",
    "gains.lqg": "[K_x m/m, K_v s, K_u1..K_ud m/m] per design point",
    "gains.force_model_r": "1 (LQR input weight)",
    "timing": "s, Hz",
    "learner.delay_uncertainty_s": "s (unknown part of the delay each harmonic's learning "
                                   "gain is kept stable over)",
    "learner.fn_uncertainty_rel": "1 (1.96 std / fn of the model, worst along the path)",
    "learner.gain_uncertainty_rel": "1 (relative actuator-gain error the learning covers)",
    "guard.z_score": "1 (standard errors of the window's RMS, amplification_test)",
    "excitation.spindle_rpm": "rev/min",
    "stability.*_worst_spectral_radius": "1 (< 1: stable on every plant of the band)",
    "stability.force_model_worst_rms_ratio": "1 (< 1: the force-model feedforward reduces "
                                             "the vibration on every plant and delay)",
    "step.force_n": "N, base frame, (m, 3) samples of the cycle",
    "step.tracker_mm": "mm, base frame, (m, 3) samples of the cycle",
    "step.path_s_m": "m",
    "step.output": "mm, base frame, correction X, Y, Z",
}  # fmt: skip


# --------------------------------------------------------------------------- design
def design_controller(
    model,
    path: ControlPath,
    controller: str = "adaptive+force",
    *,
    directions=("x", "z"),
    n_points: int = 21,
    period_s: float = 0.004,
    delay_s: float = 0.032,
    sample_rate_hz: float = 1000.0,
    spindle_rpm: float | None = None,
    teeth: int = 2,
    tracker: dict | None = None,
    guard: dict | None = None,
) -> dict:
    """Design ``controller`` from a pose model along ``path``; the controller document.

    The modes at the ``n_points`` design points come from one ``model.modes(poses)`` call
    (:class:`~robovib.control.path_design.PathDesign`); a multi-mode model's mode that matters
    for control is chosen per direction and named (``provenance.control_modes``).

    Parameters
    ----------
    model
        A fitted pose model (``modes(X)``, ``input_names``): dominant or multi-mode.
    path
        The tool path in the model's inputs.
    controller
        A name of :data:`~robovib.control.design.DESIGNS` that can go to a file (not
        ``tuned``, whose design depends on the spindle speed).
    directions
        Controlled directions (``x``, ``y``, ``z``).
    n_points
        Design points along the path (>= 5).
    period_s, delay_s
        Command period (RSI: 4 ms) and the transport delay the design assumes (KRC4: 32 ms),
        in s; the delay a whole number of periods.
    sample_rate_hz
        Rate of the force and tracker samples [Hz] (a whole multiple of the command rate).
    spindle_rpm, teeth
        Nominal spindle speed [rev/min] (or None: given at ``reset``) and the cutter's teeth.
    tracker, guard
        Period-tracker and guard settings over the defaults.

    Returns
    -------
    dict
        The controller document (:func:`write_controller_file`, :func:`load_controller`).

    Raises
    ------
    ValueError
        Unknown or file-less controller, bad timing, a path the model cannot answer.
    """
    (name,) = check_controller_names([controller])
    if not DESIGNS[name].in_file:
        raise ValueError(f"the {name} controller is designed for one spindle speed and cut; "
                         "it cannot go to a controller file (use adaptive+force or repetitive)")  # fmt: skip
    _check_timing(period_s, delay_s, sample_rate_hz)
    if spindle_rpm is not None and not (math.isfinite(spindle_rpm) and spindle_rpm > 0):
        raise ValueError(f"spindle_rpm must be > 0 [rev/min], got {spindle_rpm!r}")
    if int(teeth) != teeth or teeth < 1:
        raise ValueError(f"teeth must be a whole number >= 1, got {teeth!r}")
    bad = [d for d in directions if d not in _AXES]
    if bad or not directions:
        raise ValueError(f"directions must be some of x, y, z, got {list(directions)}")
    tracker = _settings("tracker", TRACKER_DEFAULTS, tracker)
    guard = _settings("guard", GUARD_DEFAULTS, guard)
    design = PathDesign(model, path, directions, n_points)
    axes = {_AXES[d]: d for d in directions}
    tab = design_tables(design, axes, design.grid_s_m, names=[name], s_start=path.s_m[0],
                        s_end=path.s_m[-1], period_s=period_s, delay_s=delay_s,
                        force_model_true_delays_s=_true_delays(delay_s, period_s))  # fmt: skip
    worst = tab.checks.get("force_model_worst_rms_ratio", {})
    tab.force_model_r = {a: r for a, r in tab.force_model_r.items() if worst.get(a, 0.0) < 1.0}
    return _document(name, tab, design, period_s, delay_s, sample_rate_hz, spindle_rpm,
                     int(teeth), tracker, guard)  # fmt: skip


#: The unknown part of the delay a controller file's force model must not amplify with [s]:
#: twice the realistic 8 ms (``CutDisturbances``), so a 2x error stays inside the checked band.
DELAY_UNCERTAINTY_S = 0.016


def _true_delays(delay_s: float, period_s: float) -> tuple[float, ...]:
    """Nominal delay ± whole command periods up to :data:`DELAY_UNCERTAINTY_S`, >= 1 period."""
    n = round(DELAY_UNCERTAINTY_S / period_s)
    return tuple(d for d in (delay_s + j * period_s for j in range(-n, n + 1, max(1, n // 2)))
                 if d >= period_s - 1e-12)  # fmt: skip


def _settings(what: str, defaults: dict, given: dict | None) -> dict:
    unknown = set(given or {}) - set(defaults)
    if unknown:
        raise ValueError(f"unknown {what} settings {sorted(unknown)}; expected some of "
                         f"{sorted(defaults)}")  # fmt: skip
    return {**defaults, **{k: float(v) for k, v in (given or {}).items()}}


#: The repetitive learners' settings of a controller file (see ``TrackingRepetitive``).
LEARNER_DEFAULTS = {"divergence_ratio": 1.2, "divergence_test": "correction",
                    "n_harmonics": "auto", "model_at_tracked_period": True,
                    "delay_uncertainty_s": 0.008, "fn_uncertainty_rel": 0.0,
                    "gain_uncertainty_rel": 0.1}  # fmt: skip


def _learner(given: dict | None) -> dict:
    unknown = set(given or {}) - set(LEARNER_DEFAULTS)
    if unknown:
        raise ValueError(f"unknown learner settings {sorted(unknown)}; expected some of "
                         f"{sorted(LEARNER_DEFAULTS)}")  # fmt: skip
    out = {**LEARNER_DEFAULTS, **(given or {})}
    out["divergence_ratio"] = float(out["divergence_ratio"])
    out["model_at_tracked_period"] = bool(out["model_at_tracked_period"])
    for key in ("delay_uncertainty_s", "fn_uncertainty_rel", "gain_uncertainty_rel"):
        out[key] = float(out[key])
    if out["n_harmonics"] != "auto":
        out["n_harmonics"] = int(out["n_harmonics"])
    return out


def _check_timing(period_s: float, delay_s: float, sample_rate_hz: float) -> None:
    if not (math.isfinite(period_s) and period_s > 0 and math.isfinite(sample_rate_hz)
            and sample_rate_hz > 0 and math.isfinite(delay_s) and delay_s >= 0):  # fmt: skip
        raise ValueError("period_s > 0 [s], delay_s >= 0 [s] and sample_rate_hz > 0 [Hz]")
    every = period_s * sample_rate_hz
    if abs(every - round(every)) > 1e-9 or round(every) < 1:
        raise ValueError(f"the command period {period_s * 1e3:g} ms must be a whole number of "
                         f"samples at {sample_rate_hz:g} Hz")  # fmt: skip
    d = delay_s / period_s
    if abs(d - round(d)) > 1e-9:
        raise ValueError(f"the delay {delay_s * 1e3:g} ms must be a whole number of command "
                         f"periods ({period_s * 1e3:g} ms)")  # fmt: skip


def _fn_uncertainty(modes: dict) -> float:
    """The learners' relative fn band: the model's 1.96 std over fn, worst along the path."""
    rel = [1.96 * sd / fn for m in modes.values()
           for fn, sd in zip(m["fn_hz"], m["fn_std_hz"], strict=True) if fn > 0]  # fmt: skip
    return float(max(rel, default=0.0))


def _document(name, tab: PathTables, design: PathDesign, period_s, delay_s, fs, rpm, teeth,
              tracker, guard) -> dict:  # fmt: skip
    from .. import __version__

    directions = {a: d for a, d in tab.axes.items()}
    modes = {}
    for d in directions.values():
        pm = [design.modes(np.array([[s]]))[0][d] for s in tab.grid]
        modes[d] = {
            "model_output": design.mode_names[d],
            "fn_hz": [m.parameters.natural_frequency_hz for m in pm],
            "stiffness_n_per_m": [m.parameters.stiffness_n_per_m for m in pm],
            "damping_ratio": [m.parameters.damping_ratio for m in pm],
            "fn_std_hz": [m.fn_std_hz for m in pm],
            "stiffness_std_n_per_m": [m.stiffness_std_n_per_m for m in pm],
            "damping_std_ns_per_m": [m.damping_std_ns_per_m for m in pm],
            "extrapolating": [bool(m.extrapolating) for m in pm],
        }
    gains: dict = {}
    if tab.schedule:
        gains["schedule"] = {directions[a]: {"w1": s.w1.tolist(), "w2": s.w2.tolist(),
                                             "r": s.r.tolist(),
                                             "stable_with_delay": s.stable_with_delay.tolist(),
                                             "w1_poly_high_to_low": s.w1_poly.tolist(),
                                             "w2_poly_high_to_low": s.w2_poly.tolist()}
                             for a, s in tab.schedule.items()}  # fmt: skip
        gains["constant"] = {n: {directions[a]: list(g) for a, g in c.items()}
                             for n, c in tab.constant.items()}  # fmt: skip
    for key in ("robust", "lqg"):
        if getattr(tab, key):
            gains[key] = {directions[a]: v.tolist() for a, v in getattr(tab, key).items()}
    if "force_model_r" in DESIGNS[name].tables:  # the axes kept (may be none)
        gains["force_model_r"] = {directions[a]: r for a, r in tab.force_model_r.items()}
    stability = {
        "band": "posterior mean +- 1.96 std in fn, k and c (the 8 corners), each also with "
                "a second mode at (fn ratio, k ratio, zeta) of second_mode_hypotheses",
        "band_z_score": 1.96,
        "second_mode_hypotheses": [list(h) for h in SECOND_MODE_HYPOTHESES],
        "delay_s": delay_s,
    }  # fmt: skip
    stability.update({k: {directions[a]: v for a, v in c.items()} for k, c in tab.checks.items()})
    if name in ("adaptive+force",):
        stability["true_delays_s"] = list(_true_delays(delay_s, period_s))
    return {
        "format": FORMAT,
        "format_version": FORMAT_VERSION,
        "robovib_version": __version__,
        "controller": name,
        "description": _DESCRIPTIONS.get(name, name),
        "timing": {
            "command_period_s": period_s,
            "sample_rate_hz": fs,
            "delay_s": delay_s,
            "budget_s": period_s,
        },
        "excitation": {"spindle_rpm": rpm, "teeth": teeth},
        "path": design.path.to_dict(),
        "axes": {d: a for a, d in directions.items()},
        "grid_s_m": tab.grid.tolist(),
        "modes": modes,
        "gains": gains,
        "tracker": tracker,
        "guard": guard,
        "learner": _learner({"fn_uncertainty_rel": _fn_uncertainty(modes)}),
        "stability": stability,
        "provenance": design.provenance(),
        "units": _UNITS,
    }


_DESCRIPTIONS = {
    "adaptive+force": "period tracker + repetitive learner of the tooth (and runout) lines on "
                      "the tracker + delay-aware LQR feedforward of the measured force through "
                      "the pose model, under a fade-out guard",
    "feedforward+robust": "force feedforward (one tooth period ahead) + delay-aware LQR "
                          "feedback robust over the model band",
    "robust": "delay-aware LQR feedback robust over the model band",
    "thesis": "the thesis' state feedback u = -(w1 x + w2 v) scheduled along the path (Eq. 28-29)",
}  # fmt: skip


def write_controller_file(path, doc: dict, *, inputs=(), force: bool = False) -> Path:
    """Write a controller document as JSON, atomically (temporary file + rename).

    Parameters
    ----------
    path : path-like
        The ``.json`` file.
    doc : dict
        From :func:`design_controller`.
    inputs : sequence of path-like
        Files it was made from (never overwritten unless ``force``).
    force : bool
        Allow ``path`` to be one of ``inputs``.

    Returns
    -------
    Path
    """
    from ..files.provenance import plain_json
    from ..files.safe_write import atomic_output

    path = Path(path)
    with atomic_output(path, inputs=inputs, force=force) as tmp:
        tmp.write_text(json.dumps(plain_json(doc), indent=1, allow_nan=False) + "\n")
    return path


# --------------------------------------------------------------------------- load
def _tables(doc: dict) -> PathTables:
    try:
        grid = np.asarray(doc["grid_s_m"], float)
        axes = {int(a): d for d, a in doc["axes"].items()}
        t = doc["timing"]
        modes = {a: [ModalParameters(fn, k, z) for fn, k, z in zip(
            doc["modes"][d]["fn_hz"], doc["modes"][d]["stiffness_n_per_m"],
            doc["modes"][d]["damping_ratio"], strict=True)] for a, d in axes.items()}  # fmt: skip
        tab = PathTables(grid, axes, modes, float(t["command_period_s"]), float(t["delay_s"]))
        g = doc.get("gains", {})
        by_dir = {d: a for a, d in axes.items()}
        if "schedule" in g:
            tab.schedule = {by_dir[d]: GainSchedule(
                grid, np.asarray(v["w1"], float), np.asarray(v["w2"], float),
                np.asarray(v["r"], float), np.asarray(v["stable_with_delay"], bool),
                np.asarray(v["w1_poly_high_to_low"], float),
                np.asarray(v["w2_poly_high_to_low"], float)) for d, v in g["schedule"].items()}  # fmt: skip
            tab.constant = {n: {by_dir[d]: tuple(float(x) for x in w) for d, w in c.items()}
                            for n, c in g["constant"].items()}  # fmt: skip
        for key in ("robust", "lqg"):
            if key in g:
                setattr(tab, key, {by_dir[d]: np.asarray(v, float) for d, v in g[key].items()})
        if "force_model_r" in g:
            tab.force_model_r = {by_dir[d]: float(r) for d, r in g["force_model_r"].items()}
    except (KeyError, TypeError, ValueError) as exc:
        raise ValueError(f"controller file: missing or malformed design table ({exc})") from exc
    if grid.ndim != 1 or grid.size < 2 or not np.all(np.isfinite(grid)):
        raise ValueError("controller file: grid_s_m must be >= 2 finite path distances [m]")
    return tab


def load_controller(path) -> RuntimeController:
    """The run-time controller of a controller file (:func:`write_controller_file`).

    Parameters
    ----------
    path : path-like
        The ``.json`` controller file.

    Returns
    -------
    RuntimeController
        Reset and ready (for the file's spindle speed, if it has one).

    Raises
    ------
    ValueError
        Not a readable robovib controller file, a newer format version, or a malformed table.

    Examples
    --------
    >>> ctl = load_controller("ctl.json")  # doctest: +SKIP
    >>> ctl.reset(spindle_rpm=250)  # doctest: +SKIP
    >>> correction_mm = ctl.step(Measurement(force_n, tracker_mm, path_s_m))  # doctest: +SKIP
    """
    p = Path(path)
    if not p.is_file():
        raise ValueError(f"{p}: no such controller file (or not a regular file)")
    if p.stat().st_size > _MAX_FILE_BYTES:
        raise ValueError(f"{p}: {p.stat().st_size} bytes is too large for a controller file "
                         f"(limit {_MAX_FILE_BYTES})")  # fmt: skip
    try:
        doc = json.loads(p.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ValueError(f"{p}: not a readable JSON controller file ({exc})") from exc
    try:
        return RuntimeController(doc)
    except ValueError as exc:
        raise ValueError(f"{p}: {exc}") from exc


@dataclass
class Measurement:
    """One command cycle's measurement (what the RSI bridge hands to ``step``).

    Attributes
    ----------
    force_n
        (m, 3) or (3,) force-sensor samples of the cycle, base frame [N] (last row: now).
    tracker_mm
        (m, 3) or (3,) tracker samples of the tool tip, base frame [mm] (same rows).
    path_s_m
        Path coordinate of the tool now [m] (travel along the file's path).
    """

    force_n: np.ndarray
    tracker_mm: np.ndarray
    path_s_m: float


class RuntimeController:
    """The controller of a controller file, one ``step`` per command cycle.

    ``reset()`` starts a cut (buffers for ``max_duration_s``); ``step(measurement)`` returns
    the correction [mm] (X, Y, Z, base frame) to send now; it reaches the tool ``delay_s``
    later. The returned array is overwritten by the next step (copy it to keep it).

    Parameters
    ----------
    doc : dict
        The controller document (:func:`design_controller` / the JSON file).
    """

    def __init__(self, doc: dict):
        if not isinstance(doc, dict) or doc.get("format") != FORMAT:
            raise ValueError(f"not a robovib controller file (format tag {FORMAT!r} missing)")
        version = doc.get("format_version")
        if not isinstance(version, int) or version > FORMAT_VERSION or version < 1:
            raise ValueError(f"controller file format version {version!r}; this robovib reads "
                             f"1..{FORMAT_VERSION}")  # fmt: skip
        (self.name,) = check_controller_names([doc.get("controller")])
        self.doc = doc
        t = doc["timing"]
        self.period_s = float(t["command_period_s"])
        self.sample_rate_hz = float(t["sample_rate_hz"])
        self.delay_s = float(t["delay_s"])
        _check_timing(self.period_s, self.delay_s, self.sample_rate_hz)
        self.path = ControlPath.from_dict(doc["path"])
        self.tables = _tables(doc)
        if "force_model_r" in DESIGNS[self.name].tables and "force_model_r" not in doc["gains"]:
            raise ValueError("controller file: malformed design table (no force_model_r gains)")
        for table in DESIGNS[self.name].tables - {"plants", "force_model_r"}:
            have = getattr(self.tables, table)
            missing = [d for a, d in self.tables.axes.items() if a not in have]
            if missing:
                raise ValueError(f"controller file: malformed design table (no {table} gains "
                                 f"for {', '.join(missing)})")  # fmt: skip
        for a, d in self.tables.axes.items():
            if len(self.tables.modes[a]) != self.tables.grid.size:
                raise ValueError(f"controller file: malformed design table ({d} modes do not "
                                 "match grid_s_m)")  # fmt: skip
        self.spindle_rpm = doc.get("excitation", {}).get("spindle_rpm")
        self.teeth = int(doc.get("excitation", {}).get("teeth", 1))
        self.tracker_settings = _settings("tracker", TRACKER_DEFAULTS, doc.get("tracker"))
        self.guard_settings = _settings("guard", GUARD_DEFAULTS, doc.get("guard"))
        self.learner_settings = _learner(doc.get("learner"))
        self._inner = None
        self._out = np.zeros(3)
        if self.spindle_rpm is not None or not DESIGNS[self.name].needs_excitation:
            self.reset()

    @property
    def every(self) -> int:
        """Sensor samples per command cycle."""
        return round(self.period_s * self.sample_rate_hz)

    def reset(self, *, spindle_rpm: float | None = None, teeth: int | None = None,
              max_duration_s: float = 60.0, nominal_s_m: float | None = None) -> None:  # fmt: skip
        """Start a cut: fresh state, buffers for ``max_duration_s`` of it.

        Parameters
        ----------
        nominal_s_m
            Path coordinate of the cut [m] where a controller needs one value for the whole
            cut (the guard's open-loop model); default the middle of the designed path.
        spindle_rpm
            Nominal spindle speed [rev/min] of this cut (default the file's).
        teeth
            The cutter's teeth (default the file's).
        max_duration_s
            Longest cut before the next reset [s].

        Raises
        ------
        ValueError
            No spindle speed for a controller that needs one, bad values.
        """
        rpm = self.spindle_rpm if spindle_rpm is None else spindle_rpm
        teeth = self.teeth if teeth is None else int(teeth)
        if not (math.isfinite(max_duration_s) and max_duration_s > 0):
            raise ValueError(f"max_duration_s must be > 0 [s], got {max_duration_s!r}")
        needs = DESIGNS[self.name].needs_excitation
        if needs and rpm is None:
            raise ValueError(f"the {self.name} controller needs the spindle speed: "
                             "reset(spindle_rpm=...) or design it with one")  # fmt: skip
        if rpm is not None and not (math.isfinite(rpm) and rpm > 0):
            raise ValueError(f"spindle_rpm must be > 0 [rev/min], got {rpm!r}")
        if teeth < 1:
            raise ValueError(f"teeth must be >= 1, got {teeth}")
        period = None if rpm is None else 60.0 / (rpm * teeth)
        self._inner = assemble_controller(self.name, self.tables, excitation_period_s=period,
                                          teeth=teeth, tracker=self.tracker_settings,
                                          guard=self.guard_settings,
                                          learner=self.learner_settings)  # fmt: skip
        capacity = math.ceil(max_duration_s / self.period_s)
        nominal = float(np.median(self.tables.grid)) if nominal_s_m is None else float(nominal_s_m)
        if not math.isfinite(nominal):
            raise ValueError(f"nominal_s_m must be finite [m], got {nominal_s_m!r}")
        self._cursor = PathCursor(capacity, nominal)
        self._inner.reset(self._cursor, self.period_s, self.sample_rate_hz)
        self._k = 0
        self._scale = np.zeros(3)
        self.excitation_period_s = period

    def step(self, measurement) -> np.ndarray:
        """The correction [mm] (3,) to send this cycle.

        Parameters
        ----------
        measurement : Measurement
            The cycle's force [N] and tracker [mm] samples and the path coordinate [m].

        Returns
        -------
        numpy.ndarray
            (3,) correction X, Y, Z [mm] (a buffer overwritten by the next step).

        Raises
        ------
        ValueError
            Not reset, the run longer than the buffers, or a non-finite path coordinate.
        """
        return self.step_arrays(measurement.force_n, measurement.tracker_mm,
                                measurement.path_s_m)  # fmt: skip

    def step_arrays(self, force_n, tracker_mm, path_s_m: float) -> np.ndarray:
        """:meth:`step` with the three inputs as arguments (see :class:`Measurement`).

        Parameters
        ----------
        force_n : numpy.ndarray
            (m, 3) or (3,) force samples [N].
        tracker_mm : numpy.ndarray
            (m, 3) or (3,) tracker samples [mm].
        path_s_m : float
            Path coordinate [m].

        Returns
        -------
        numpy.ndarray
            (3,) correction [mm].
        """
        if self._inner is None:
            raise ValueError(f"the {self.name} controller needs reset(spindle_rpm=...) first")
        if self._k >= self._cursor.capacity:
            raise ValueError("the cut is longer than the buffers of reset(max_duration_s=...): "
                             "reset between cuts or give a longer max_duration_s")  # fmt: skip
        if not math.isfinite(path_s_m):
            raise ValueError(f"path coordinate must be finite [m], got {path_s_m!r}")
        f = np.asarray(force_n, float)
        y = np.asarray(tracker_mm, float)
        if f.ndim == 1:
            f, y = f[None, :], y[None, :]
        self._cursor.move_to(path_s_m)
        u = self._inner.command(self._k, y * 1e-3, f)
        self._k += 1
        np.multiply(u, 1e3, out=self._out)
        return self._out

    def events(self) -> list:
        """What the guard (and the learners) did and why.

        Returns
        -------
        list of GuardEvent
            In time order.
        """
        inner = self._inner
        if inner is None:
            return []
        if hasattr(inner, "all_events"):
            return inner.all_events()
        parts = getattr(inner, "parts", (inner,))
        return sorted([e for p in parts for e in getattr(p, "events", [])], key=lambda e: e.time_s)

    @property
    def guard_scale(self) -> float:
        """The guard's fade factor now (1: full correction; 1 for unguarded controllers)."""
        return float(getattr(self._inner, "scale", 1.0))

    def path_coordinate(self, coords) -> np.ndarray:
        """Path coordinates [m] of the simulator's / a record's poses.

        Parameters
        ----------
        coords : array_like
            (n,) chapter-4 path distances [m] or (n, 3) workspace poses ``(x_m, y_m,
            rz_deg)``.

        Returns
        -------
        numpy.ndarray
            (n,) travel along this file's path [m].
        """
        c = np.asarray(coords, float)
        if c.ndim == 1:
            if self.path.input_names != ("s_m",):
                raise ValueError("path-distance coordinates need a controller designed on a "
                                 "path model (input s_m)")  # fmt: skip
            return self.path.coordinate(c)
        return self.path.coordinate(model_poses_from_record(c, self.path.input_names))

    def planned(self, spindle_rpm: float | None = None, teeth: int | None = None) -> _Planned:
        """This controller as a planned-run controller (``reset(coords, ...)`` / ``command``)
        for :func:`robovib.sim.run_closed_loop`; every step goes through :meth:`step`.

        Parameters
        ----------
        spindle_rpm, teeth
            The cut's spindle speed [rev/min] and teeth (default the file's).

        Returns
        -------
        object
            The adapter; its ``commands_mm`` lists the corrections sent.
        """
        return _Planned(self, spindle_rpm, teeth)


class _Planned:
    """A :class:`RuntimeController` behind the planned-run protocol (the simulator's)."""

    def __init__(self, runtime: RuntimeController, spindle_rpm, teeth):
        self.runtime = runtime
        self.spindle_rpm = spindle_rpm
        self.teeth = teeth

    def reset(self, coords, period_s: float, sample_rate_hz: float) -> None:
        rt = self.runtime
        if abs(period_s - rt.period_s) > 1e-12 or abs(sample_rate_hz - rt.sample_rate_hz) > 1e-9:
            raise ValueError(f"the controller file assumes a {rt.period_s * 1e3:g} ms cycle at "
                             f"{rt.sample_rate_hz:g} Hz, the run has {period_s * 1e3:g} ms at "
                             f"{sample_rate_hz:g} Hz")  # fmt: skip
        self._s = rt.path_coordinate(coords)
        n = self._s.size
        rt.reset(spindle_rpm=self.spindle_rpm, teeth=self.teeth,
                 max_duration_s=(n + 2) * rt.period_s,
                 nominal_s_m=float(self._s[n // 2]))  # fmt: skip
        self.commands_mm = np.zeros((n, 3))

    def command(self, k: int, tracker_m: np.ndarray, force_n: np.ndarray) -> np.ndarray:
        u = self.runtime.step_arrays(force_n, tracker_m * 1e3, float(self._s[k]))
        self.commands_mm[k] = u
        return u * 1e-3

    def all_events(self) -> list:
        return self.runtime.events()


def model_poses_from_record(poses, input_names) -> np.ndarray:
    """A record's workspace poses ``(x_m, y_m, rz_deg)`` (n, 3) in a model's input units.

    Parameters
    ----------
    poses : array_like
        (n, 3) poses ``x_m, y_m, rz_deg``.
    input_names : sequence of str
        The model's inputs: some of ``x_mm, y_mm, rz_deg`` (in any order).

    Returns
    -------
    numpy.ndarray
        (n, len(input_names)).

    Raises
    ------
    ValueError
        A model input a record pose does not give.
    """
    p = np.atleast_2d(np.asarray(poses, float))
    cols = {"x_mm": p[:, 0] * 1e3, "y_mm": p[:, 1] * 1e3, "rz_deg": p[:, 2]}
    missing = [n for n in input_names if n not in cols]
    if missing:
        raise ValueError(f"a record pose (x_m, y_m, rz_deg) gives no {', '.join(missing)} for "
                         "the controller's path")  # fmt: skip
    return np.column_stack([cols[n] for n in input_names])


# --------------------------------------------------------------------------- replay
@dataclass(frozen=True)
class ReplayResult:
    """What a controller would have done over a logged cut (:func:`replay`).

    Attributes
    ----------
    time_s
        (n_cmd,) time of each command [s].
    path_s_m
        (n_cmd,) path coordinate at each command [m].
    commands_mm
        (n_cmd, 3) corrections it would have sent [mm].
    guard_scale
        (n_cmd,) the guard's fade factor after each step.
    events
        The guard's and learners' events (time [s], target, reason).
    rms_mm
        Direction -> ``{"measured", "predicted_open", "predicted_corrected"}`` RMS [mm] of
        the tracker and of the model's response to the measured force without and with the
        corrections (after the first fifth of the cut).
    tracker_fed_m
        (n, 3) the tracker signal the controller was given [m]: the record's, plus the model's
        response to the corrections where the record was made without the controller.
    """

    time_s: np.ndarray
    path_s_m: np.ndarray
    commands_mm: np.ndarray
    guard_scale: np.ndarray
    events: tuple
    rms_mm: dict
    tracker_fed_m: np.ndarray | None = None


def replay(runtime: RuntimeController, record: dict, *, spindle_rpm: float | None = None,
           teeth: int | None = None, record_made: str = "with") -> ReplayResult:  # fmt: skip
    """Run the controller over a logged cut, as the bridge would have run it.

    Commands fall at samples ``0, every, 2 every, ...`` (``every`` = samples per cycle); each
    step gets the samples since the previous one (the first: sample 0 alone), as in
    :func:`robovib.sim.run_closed_loop`. The predicted vibration runs the file's mode of each
    direction (at the record's middle path coordinate) on the measured force (high-passed at
    the force model's 1 Hz) and on the corrections, ``delay_s`` late.

    A cut logged *without* this controller (``record_made="without"``, the usual case before
    deployment) holds none of its corrections: fed as it is, the guard would see a tracker
    signal its corrections never reduced and fade the controller out, and the learners would
    chase a residual that never moves. There the tracker signal the controller is given is the
    logged one plus the model's response to the corrections already sent (``delay_s`` late,
    held for a cycle), computed sample by sample: a model-in-the-loop replay. A cut logged
    *with* the controller running (``"with"``, e.g. a closed-loop simulation's record) already
    holds their effect and is fed unchanged, so the replay reproduces its commands.

    Parameters
    ----------
    runtime : RuntimeController
        The controller (reset here).
    record : dict
        :func:`robovib.io.read_milling_record_csv`: ``time_s``, ``force_n``,
        ``displacement_m`` and ``path_s_m`` or ``pose``.
    spindle_rpm, teeth
        The cut's spindle speed [rev/min] and teeth (default the file's).
    record_made : {"with", "without"}
        Whether the record was logged with this controller running (see above).

    Returns
    -------
    ReplayResult

    Raises
    ------
    ValueError
        A record whose sample rate is not the file's, too short, or poses off the model.
    """
    if record_made not in ("with", "without"):
        raise ValueError(f"record_made must be 'with' or 'without', got {record_made!r}")
    t = np.asarray(record["time_s"], float)
    force = np.asarray(record["force_n"], float)
    tracker = np.asarray(record["displacement_m"], float)
    if t.size < 2:
        raise ValueError("the record needs at least 2 samples")
    fs = 1.0 / float(np.median(np.diff(t)))
    if abs(fs / runtime.sample_rate_hz - 1) > 1e-6:
        raise ValueError(f"the record is sampled at {fs:.6g} Hz, the controller file assumes "
                         f"{runtime.sample_rate_hz:g} Hz")  # fmt: skip
    coords = record["path_s_m"] if "path_s_m" in record else record["pose"]
    every = runtime.every
    idx = np.arange(0, t.size, every)
    s = runtime.path_coordinate(np.asarray(coords)[idx])
    runtime.reset(spindle_rpm=spindle_rpm, teeth=teeth,
                  max_duration_s=(idx.size + 2) * runtime.period_s,
                  nominal_s_m=float(s[idx.size // 2]))  # fmt: skip
    cmds = np.zeros((idx.size, 3))
    scale = np.zeros(idx.size)
    fed = tracker if record_made == "with" else tracker.copy()
    loop = None if record_made == "with" else _CorrectionResponse(runtime, float(np.median(s)), fs)
    for k, i in enumerate(idx):
        lo = max(0, i - every + 1)
        if loop is not None:  # the corrections sent so far reach these samples through the model
            loop.add(fed, cmds, lo, i + 1)
        cmds[k] = runtime.step_arrays(force[lo : i + 1], fed[lo : i + 1] * 1e3, float(s[k]))
        scale[k] = runtime.guard_scale
    rms = _predicted_rms(runtime, force, tracker, cmds, float(np.median(s)), fs)
    return ReplayResult(t[idx], s, cmds, scale, tuple(runtime.events()), rms, fed)


class _CorrectionResponse:
    """Causal response of the file's mode per axis (at path coordinate ``s_mid``) to the
    corrections already sent, ``delay_s`` late and held for a cycle, added to the tracker."""

    def __init__(self, runtime, s_mid: float, fs: float) -> None:
        from .lqr import continuous_model, discretize

        self.every, self.delay = runtime.every, round(runtime.delay_s * fs)
        self.axes = {}
        for a in runtime.tables.axes:
            fz = runtime.tables.fz(a).at(np.array([s_mid]))[0]
            k = runtime.tables.stiffness(a).at(np.array([s_mid]))[0, 0]
            phi, gam = discretize(*continuous_model(ModalParameters(fz[0], k, fz[1])), 1.0 / fs)
            self.axes[a] = (phi, gam[:, 0], np.zeros(2))

    def add(self, tracker_m: np.ndarray, cmds_mm: np.ndarray, lo: int, hi: int) -> None:
        for j in range(lo, hi):
            m = (j - self.delay) // self.every  # the command applied at sample j (< this step)
            for a, (phi, g, x) in self.axes.items():
                tracker_m[j, a] += x[0]
                u = cmds_mm[m, a] * 1e-3 if m >= 0 else 0.0
                x[:] = phi @ x + g * u


def _predicted_rms(runtime, force, tracker, cmds_mm, s_mid, fs) -> dict:
    from .lqr import continuous_model, discretize

    n = force.shape[0]
    every, delay = runtime.every, round(runtime.delay_s * fs)
    applied = np.zeros((n, 3))
    held = np.repeat(cmds_mm * 1e-3, every, axis=0)[:n]
    applied[delay:] = held[: max(0, n - delay)]
    alpha = math.exp(-2 * math.pi * 1.0 / fs)
    f_hp = np.zeros_like(force)
    for i in range(1, n):
        f_hp[i] = alpha * (f_hp[i - 1] + force[i] - force[i - 1])
    out = {}
    start = n // 5
    for a, d in runtime.tables.axes.items():
        fz = runtime.tables.fz(a).at(np.array([s_mid]))[0]
        k = runtime.tables.stiffness(a).at(np.array([s_mid]))[0, 0]
        phi, gam = discretize(*continuous_model(ModalParameters(fz[0], k, fz[1])), 1.0 / fs)
        x = np.zeros(2)
        xo = np.zeros(2)
        y_c = np.zeros(n)
        y_o = np.zeros(n)
        g = gam[:, 0]
        for i in range(n):
            y_c[i], y_o[i] = x[0], xo[0]
            x = phi @ x + g * (f_hp[i, a] / k + applied[i, a])
            xo = phi @ xo + g * (f_hp[i, a] / k)
        out[d] = {"measured": 1e3 * float(np.std(tracker[start:, a])),
                  "predicted_open": 1e3 * float(np.std(y_o[start:])),
                  "predicted_corrected": 1e3 * float(np.std(y_c[start:]))}  # fmt: skip
    return out
