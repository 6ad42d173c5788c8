"""The run-time controller a robot bridge calls (issue 40).

:class:`RuntimeController` is the controller of a controller document
(:mod:`~robovib.control.controller_file`): ``reset()`` then ``step(measurement)`` once per
command cycle (the force and tracker samples of the cycle and the path coordinate) -> the
correction [mm]. The same object runs in the closed-loop simulation
(:meth:`RuntimeController.planned`) and over a logged cut
(:func:`~robovib.control.cut_replay.replay`), so design, replay and simulation share one
controller.

The cycle budget is the RSI cycle, 4 ms (``timing.budget_s`` in the file);
``benchmarks/bench_control_runtime.py`` measures ``step`` at p50 / p99. The buffers of a run
are allocated by ``reset`` for ``max_duration_s`` (default 60 s of cutting); a longer run is
an error, not a reallocation. Wiring to a KUKA RSI/EKI bridge: ``docs/control_runtime.md``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .controller_format import (
    FORMAT,
    FORMAT_VERSION,
    _check_timing,
    _learner,
    _settings,
    _tables,
)
from .controllers import PathCursor
from .design import (
    DESIGNS,
    GUARD_DEFAULTS,
    TRACKER_DEFAULTS,
    assemble_controller,
    check_controller_names,
)
from .path_design import ControlPath

__all__ = ["Measurement", "RuntimeController", "model_poses_from_record"]


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
        The controller document
        (:func:`~robovib.control.controller_file.design_controller` / the JSON file).
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
