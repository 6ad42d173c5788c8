"""Controller files (issue 40): design a controller into a document, write it, load it.

* :func:`design_controller` designs one controller of :data:`~robovib.control.design.DESIGNS`
  from *any* pose model along a :class:`~robovib.control.path_design.ControlPath` and returns
  the versioned, self-describing controller document (gains along the path, the modes they
  were designed on and which model output that is, the period tracker's and the guard's
  settings, the command period, sample rate and delay assumed, the band over which stability
  was checked, units, the model's provenance). :func:`write_controller_file` writes it.
* :func:`load_controller` reads that file into a
  :class:`~robovib.control.runtime.RuntimeController` (:mod:`~robovib.control.runtime`).

The document's format (tag, version, settings): :mod:`~robovib.control.controller_format`.
"""

from __future__ import annotations

import json
import math
import warnings
from pathlib import Path

import numpy as np

from .controller_format import (
    FORMAT,
    FORMAT_VERSION,
    LEARNER_DESIGN,
    _check_timing,
    _learner,
    _settings,
)
from .design import (
    DESIGNS,
    GUARD_DEFAULTS,
    TRACKER_DEFAULTS,
    TRACKER_DESIGN,
    PathTables,
    band_stable_feedback,
    check_controller_names,
    design_tables,
)
from .path_design import ControlPath, PathDesign
from .pose_plants import SECOND_MODE_HYPOTHESES, path_mode, plant_set
from .runtime import RuntimeController

__all__ = [
    "FORMAT",
    "FORMAT_VERSION",
    "design_controller",
    "load_controller",
    "write_controller_file",
]

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
    "gains.feedback": "[K_x m/m, K_v s, K_u1..K_ud m/m] per design point (adaptive+force's "
                      "feedback on the axes without a force model, format 3)",
    "stability.feedback_r": "1 (LQR input weight of gains.feedback: the smallest stable on "
                            "every plant of the band with every delay of true_delays_s and "
                            "every gain of feedback_actuator_gains)",
    "stability.feedback_actuator_gains": "1 (applied / commanded correction the feedback is "
                                         "checked stable with)",
    "timing": "s, Hz",
    "learner.delay_uncertainty_s": "s (unknown part of the delay each harmonic's learning "
                                   "gain is kept stable over)",
    "learner.fn_uncertainty_rel": "1 (1.96 std / fn of the model, worst along the path)",
    "learner.gain_uncertainty_rel": "1 (relative actuator-gain error the learning covers)",
    "learner.identify_loop": "bool (each harmonic's loop phase identified online, format 2)",
    "learner.identify_rel_error": "1 (standard error / |loop factor| below which it is used)",
    "learner.learning_time_s": "s (time constant of the tooth-line learning)",
    "learner.pause_when_faded": "bool (no learning while the guard fades the correction out)",
    "learner.pool_loop_phase": "bool (a harmonic's loop phase from a line fitted to the other "
                               "harmonics' phases until its own is known, format 3)",
    "tracker.lag_periods": "periods between the correlated windows of the period estimate "
                           "(format 3; 1 in older files)",
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
    tracker = _settings("tracker", TRACKER_DEFAULTS, {**TRACKER_DESIGN, **(tracker or {})})
    guard = _settings("guard", GUARD_DEFAULTS, guard)
    design = PathDesign(model, path, directions, n_points)
    axes = {_AXES[d]: d for d in directions}
    tab = design_tables(design, axes, design.grid_s_m, names=[name], s_start=path.s_m[0],
                        s_end=path.s_m[-1], period_s=period_s, delay_s=delay_s,
                        force_model_true_delays_s=_true_delays(delay_s, period_s))  # fmt: skip
    worst = tab.checks.get("force_model_worst_rms_ratio", {})
    tab.force_model_r = {a: r for a, r in tab.force_model_r.items() if worst.get(a, 0.0) < 1.0}
    if name == "adaptive+force":  # the axes left without a force model get a feedback
        for a, d in axes.items():
            if a in tab.force_model_r:
                continue
            fb = band_stable_feedback([plant_set(design, s, d) for s in tab.grid],
                                      [path_mode(design, s, d) for s in tab.grid], period_s,
                                      delay_s, _true_delays(delay_s, period_s),
                                      actuator_gains=FEEDBACK_ACTUATOR_GAINS)  # fmt: skip
            if fb is None:
                # The axis then runs on its learners alone: say so rather than drop it silently.
                warnings.warn(f"controller {name!r}, axis {d}: no force model (it amplifies "
                              "somewhere in the band) and no feedback weight is stable over the "
                              "band, the delays and the actuator gains; this axis has only the "
                              "learners", RuntimeWarning, stacklevel=2)  # fmt: skip
            else:
                tab.feedback[a] = fb[1]
                tab.checks.setdefault("feedback_r", {})[a] = fb[0]
                tab.checks.setdefault("feedback_worst_spectral_radius", {})[a] = fb[2]
    return _document(name, tab, design, period_s, delay_s, sample_rate_hz, spindle_rpm,
                     int(teeth), tracker, guard)  # fmt: skip


#: The unknown part of the delay a controller file's force model must not amplify with [s]:
#: twice the realistic 8 ms (``CutDisturbances``), so a 2x error stays inside the checked band.
DELAY_UNCERTAINTY_S = 0.016


#: The actuator gains (applied / commanded correction) ``gains.feedback`` must be stable with:
#: twice the realistic 10 % error (``CutDisturbances.actuator_gain_pct``) either way.
FEEDBACK_ACTUATOR_GAINS = (0.8, 0.9, 1.0, 1.1, 1.2)


def _true_delays(delay_s: float, period_s: float) -> tuple[float, ...]:
    """Nominal delay ± whole command periods up to :data:`DELAY_UNCERTAINTY_S`, >= 1 period."""
    n = round(DELAY_UNCERTAINTY_S / period_s)
    return tuple(d for d in (delay_s + j * period_s for j in range(-n, n + 1, max(1, n // 2)))
                 if d >= period_s - 1e-12)  # fmt: skip


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
    if tab.feedback:
        gains["feedback"] = {directions[a]: v.tolist() for a, v in tab.feedback.items()}
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
        if tab.feedback:
            stability["feedback_actuator_gains"] = list(FEEDBACK_ACTUATOR_GAINS)
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
        "learner": _learner({**LEARNER_DESIGN, "fn_uncertainty_rel": _fn_uncertainty(modes)}),
        "stability": stability,
        "provenance": design.provenance(),
        "units": _UNITS,
    }


_DESCRIPTIONS = {
    "adaptive+force": "period tracker + repetitive learner of the tooth (and runout) lines on "
                      "the tracker + delay-aware LQR feedforward of the measured force through "
                      "the pose model (the other axes: delay-aware LQR feedback stable over "
                      "the band and the delays), under a fade-out guard",
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
