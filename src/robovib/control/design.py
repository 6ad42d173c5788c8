"""Controller design from a pose model along a path (thesis ch. 4, Tables 7 and 10).

:func:`build_controllers` designs the controllers compared in the closed-loop studies
(:data:`CONTROLLERS`) from a path model only (a :class:`robovib.gp.PoseModalModel` over the
path distance ``s_m``; the virtual robot's is :func:`robovib.sim.path_modal_model`): the
thesis' Eq. 28-29 schedule, constant designs, LQG, the robust design over the GP band
(:func:`robovib.control.pose_plants.plant_set`), force feedforward, a tuned state feedback,
repetitive and adaptive controllers. The studies (:mod:`robovib.studies.control`)
run them on the virtual robot.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from ..modal.parameters import ModalParameters
from .adaptive import PeriodTracker, TrackingFeedforward, TrackingRepetitive
from .controllers import (
    Combined,
    DelayAwareFeedback,
    ForceFeedforward,
    RepetitiveFeedback,
    ScheduledTable,
    StateFeedback,
    design_kalman,
    design_tuned_state_feedback,
    implemented_loop_matrix,
    lqg_loop_matrix,
    spectral_radius,
)
from .force_model import ForceModelFeedforward, force_model_r
from .guard import FadeGuard
from .lqr import design_delay_aware_lqr
from .pose_plants import path_mode
from .pose_plants import plant_set as _model_set
from .schedule import GainSchedule, schedule_gains

if TYPE_CHECKING:
    from ..gp import PoseModalModel

__all__ = [
    "CONTROLLERS",
    "DEFAULT_CONTROLLER",
    "DESIGNS",
    "GUARD_DEFAULTS",
    "RUNOUT_LEARNING_REVS",
    "THESIS_PRINTED_END_GAINS",
    "THESIS_PRINTED_START_GAINS",
    "TRACKER_DEFAULTS",
    "TRACKER_DESIGN",
    "Design",
    "PathTables",
    "assemble_controller",
    "build_controllers",
    "check_controller_names",
    "design_tables",
    "thesis_printed_gains",
]

#: The controllers compared in the studies (names used in the result rows and the CLI).
CONTROLLERS = (
    "thesis",
    "constant-start",
    "constant-end",
    "tuned",
    "lqg",
    "robust",
    "feedforward",
    "feedforward+robust",
    "repetitive",
    "adaptive",
    "adaptive+robust",
    "adaptive-feedforward",
    "adaptive+force",
)

#: The controller recommended for real cuts (period tracking, adaptive harmonics, guard).
DEFAULT_CONTROLLER = "adaptive+force"


#: Designs already made in this process (the studies design the same gains for every cut).
_DESIGN_CACHE: dict = {}


def _schedule(model: PoseModalModel, direction: str, s_grid) -> GainSchedule:
    modes = tuple(path_mode(model, si, direction) for si in s_grid)
    key = ("schedule", tuple(np.asarray(s_grid, float)), modes)  # keyed by the design inputs
    if key not in _DESIGN_CACHE:
        _DESIGN_CACHE[key] = schedule_gains(s_grid, list(modes))
    return _DESIGN_CACHE[key]


def _robust_r(plants, nominal: ModalParameters, period_s, delay_s, r_grid, velocity="difference"):
    """R whose delay-aware gains (designed on the nominal mode) minimise the worst spectral
    radius of the implemented loop over ``plants`` (lists of modes). ``velocity="kalman"``:
    the loop with the 1 kHz Kalman filter of :func:`design_kalman` (LQG)."""
    d = round(delay_s / period_s)
    key = (nominal, tuple(tuple(p) for p in plants), period_s, delay_s, tuple(r_grid), velocity)
    if key in _DESIGN_CACHE:
        return _DESIGN_CACHE[key]
    kf = design_kalman(nominal) if velocity == "kalman" else None

    def radius(p, g):
        if kf is not None:
            return spectral_radius(lqg_loop_matrix(p, g, kf, period_s, 1e-3, round(delay_s * 1e3)))
        return spectral_radius(implemented_loop_matrix(p, g, period_s, d, velocity=velocity))

    best = None
    for r in r_grid:
        g = design_delay_aware_lqr(nominal, period_s, delay_s, r=[[r]]).gains
        rho = max(radius(p, g) for p in plants)
        if best is None or rho < best[0]:
            best = (rho, g, r)
    _DESIGN_CACHE[key] = best
    return best


#: Learning time of the runout lines [revolutions]: slow against the one-revolution window.
RUNOUT_LEARNING_REVS = 4.0


def _force_model_r(model: PoseModalModel, s_m: float, direction: str, period_s, delay_s) -> float:
    """LQR weight of the force-model feedforward: best worst case over the band, the second-mode
    hypotheses and the unknown delay (nominal ± 8 ms), at ``s_m`` (:func:`force_model_r`)."""
    return _force_model_design(model, s_m, direction, period_s, delay_s)[0]


def _force_model_design(model, s_m: float, direction: str, period_s, delay_s, true_delays_s=None):
    """(r, worst RMS ratio) of :func:`_force_model_r` (over ``true_delays_s`` when given)."""
    plants = _model_set(model, s_m, direction)
    nominal = path_mode(model, s_m, direction)
    key = ("force-model", nominal, tuple(tuple(p) for p in plants), period_s, delay_s)
    if true_delays_s is not None:
        key = (*key, tuple(true_delays_s))
    if key not in _DESIGN_CACHE:
        _DESIGN_CACHE[key] = force_model_r(plants, nominal, period_s=period_s, delay_s=delay_s,
                                           true_delays_s=true_delays_s)  # fmt: skip
    return _DESIGN_CACHE[key]


@dataclass(frozen=True)
class Design:
    """One entry of the design registry :data:`DESIGNS`.

    Attributes
    ----------
    tables
        The design tables the controller is assembled from (``"schedule"``, ``"robust"``,
        ``"lqg"``, ``"force_model_r"``; the modes along the path are always there).
    needs_excitation
        The controller needs the excitation (tooth) period at assembly.
    in_file
        It can be written to a controller file (its design does not depend on the spindle
        speed: ``tuned`` does, and is designed per cut).
    """

    tables: frozenset
    needs_excitation: bool
    in_file: bool = True


#: Registry of the controller designs over one path design: name -> :class:`Design`.
DESIGNS: dict[str, Design] = {
    "thesis": Design(frozenset({"schedule"}), False),
    "constant-start": Design(frozenset({"schedule"}), False),
    "constant-end": Design(frozenset({"schedule"}), False),
    "tuned": Design(frozenset({"plants"}), True, in_file=False),
    "lqg": Design(frozenset({"lqg"}), False),
    "robust": Design(frozenset({"robust"}), False),
    "feedforward": Design(frozenset(), True),
    "feedforward+robust": Design(frozenset({"robust"}), True),
    "repetitive": Design(frozenset(), True),
    "adaptive": Design(frozenset(), True),
    "adaptive+robust": Design(frozenset({"robust"}), True),
    "adaptive-feedforward": Design(frozenset({"robust"}), True),
    "adaptive+force": Design(frozenset({"force_model_r"}), True),
}
assert tuple(DESIGNS) == CONTROLLERS


def check_controller_names(names) -> tuple[str, ...]:
    """The names as a tuple, or a ValueError naming the unknown ones (before any design runs).

    Parameters
    ----------
    names : iterable of str
        Controller names.

    Returns
    -------
    tuple of str
        The names.

    Raises
    ------
    ValueError
        A name not in :data:`DESIGNS`.
    """
    names = tuple(names)
    unknown = set(names) - set(CONTROLLERS)
    if unknown:
        raise ValueError(f"unknown controllers {sorted(unknown)}; expected some of {CONTROLLERS}")
    return names


@dataclass
class PathTables:
    """Everything the controllers of :data:`DESIGNS` are assembled from, designed once per path.

    Attributes
    ----------
    grid
        (n,) path distances [m] of the design points.
    axes
        Controlled tool-tip axis (0 = X, 1 = Y, 2 = Z) -> model direction.
    modes
        Axis -> the model's mode at each design point.
    schedule
        Axis -> :class:`~robovib.control.schedule.GainSchedule` (the thesis' Eq. 28-29 design).
    constant
        ``"constant-start"`` / ``"constant-end"`` -> axis -> (w1, w2).
    robust
        Axis -> (n, 2 + d) delay-aware gains of the robust design.
    lqg
        Axis -> (n, 2 + d) delay-aware gains of the LQG design.
    force_model_r
        Axis -> LQR weight of the force-model feedforward.
    feedback
        Axis -> (n, 2 + d) delay-aware gains of ``adaptive+force``'s feedback on the axes
        without a force model (a controller file; :func:`band_stable_feedback`).
    plants
        Axis -> the plant set (band corners, second modes) at each design point; not stored
        in a controller file.
    checks
        What the stability check over the band found: ``"robust_worst_spectral_radius"`` /
        ``"lqg_worst_spectral_radius"`` (axis -> per design point) and
        ``"force_model_worst_rms_ratio"`` (axis -> value).
    period_s, delay_s
        Command period and the delay the designs assume [s].
    """

    grid: np.ndarray
    axes: dict
    modes: dict
    period_s: float
    delay_s: float
    schedule: dict = field(default_factory=dict)
    constant: dict = field(default_factory=dict)
    robust: dict = field(default_factory=dict)
    lqg: dict = field(default_factory=dict)
    force_model_r: dict = field(default_factory=dict)
    feedback: dict = field(default_factory=dict)
    plants: dict = field(default_factory=dict)
    checks: dict = field(default_factory=dict)

    def fz(self, a: int) -> ScheduledTable:
        """(fn [Hz], zeta) rows of axis ``a`` along the path.

        Parameters
        ----------
        a : int
            Tool-tip axis (0 = X, 1 = Y, 2 = Z).

        Returns
        -------
        ScheduledTable
        """
        return ScheduledTable(self.grid, np.array([[m.natural_frequency_hz, m.damping_ratio]
                                                   for m in self.modes[a]]))  # fmt: skip

    def stiffness(self, a: int) -> ScheduledTable:
        """Static stiffness [N/m] rows of axis ``a`` along the path.

        Parameters
        ----------
        a : int
            Tool-tip axis (0 = X, 1 = Y, 2 = Z).

        Returns
        -------
        ScheduledTable
        """
        return ScheduledTable(self.grid, np.array([[m.stiffness_n_per_m] for m in self.modes[a]]))


def design_tables(
    model: PoseModalModel,
    axes: dict[int, str],
    s_grid,
    *,
    names=CONTROLLERS,
    s_start: float | None = None,
    s_end: float | None = None,
    period_s: float = 0.004,
    delay_s: float = 0.032,
    lqg_r: float | None = None,
    robust_r_grid=None,
    force_model_true_delays_s=None,
) -> PathTables:
    """The design tables the ``names`` need, with the modes along the path computed once.

    Parameters
    ----------
    model
        A path model over ``input_names=("s_m",)`` (or a
        :class:`~robovib.control.path_design.PathDesign`).
    axes
        Controlled axes: tool-tip axis index (0 = X, 1 = Y, 2 = Z) -> model direction.
    s_grid
        Path distances [m] of the design points.
    names
        Controllers the tables are for (checked first).
    s_start, s_end
        Path distances [m] of the ``constant-start`` / ``constant-end`` designs (default the
        first grid point).
    period_s, delay_s
        Command period and the delay the designs account for [s].
    lqg_r
        Control weight R of the LQG design; None: chosen like the robust design, on the loop
        with the Kalman filter.
    robust_r_grid
        Candidate R values of the robust design (default ``logspace(-2, 3, 11)``).
    force_model_true_delays_s
        True delays [s] the force-model weight's worst case is taken over (default the nominal
        delay and ± 8 ms, :func:`~robovib.control.force_model.force_model_r`).

    Returns
    -------
    PathTables

    Raises
    ------
    ValueError
        Unknown names.
    """
    names = check_controller_names(names)
    need = set().union(*(DESIGNS[n].tables for n in names)) if names else set()
    grid = np.asarray(s_grid, float)
    r_grid = np.logspace(-2, 3, 11) if robust_r_grid is None else np.asarray(robust_r_grid)
    modes = {a: [path_mode(model, si, d) for si in grid] for a, d in axes.items()}
    tab = PathTables(grid, dict(axes), modes, float(period_s), float(delay_s))
    if {"robust", "plants"} & need or ("lqg" in need and lqg_r is None):
        tab.plants = {a: [_model_set(model, si, d) for si in grid] for a, d in axes.items()}
    if "schedule" in need:
        tab.schedule = {a: _schedule(model, d, grid) for a, d in axes.items()}
        for name, s_at in (("constant-start", s_start), ("constant-end", s_end)):
            s_at = grid[0] if s_at is None else s_at
            tab.constant[name] = {a: s.gains_at(s_at) for a, s in tab.schedule.items()}
    if "lqg" in need:
        for a in axes:
            if lqg_r is None:  # R picked like the robust design, on the loop with the filter
                rows = [_robust_r(p, m, period_s, delay_s, r_grid, "kalman")[1]
                        for p, m in zip(tab.plants[a], modes[a], strict=True)]  # fmt: skip
                tab.checks.setdefault("lqg_worst_spectral_radius", {})[a] = [
                    _robust_r(p, m, period_s, delay_s, r_grid, "kalman")[0]
                    for p, m in zip(tab.plants[a], modes[a], strict=True)]  # fmt: skip
            else:
                rows = [design_delay_aware_lqr(m, period_s, delay_s, r=[[lqg_r]]).gains
                        for m in modes[a]]  # fmt: skip
            tab.lqg[a] = np.array(rows)
    if "robust" in need:
        for a in axes:
            best = [_robust_r(p, m, period_s, delay_s, r_grid)
                    for p, m in zip(tab.plants[a], modes[a], strict=True)]  # fmt: skip
            tab.robust[a] = np.array([b[1] for b in best])
            tab.checks.setdefault("robust_worst_spectral_radius", {})[a] = [b[0] for b in best]
    if "force_model_r" in need:
        fm = {a: _force_model_design(model, float(np.median(grid)), d, period_s, delay_s,
                                     force_model_true_delays_s) for a, d in axes.items()}  # fmt: skip
        tab.force_model_r = {a: v[0] for a, v in fm.items()}
        tab.checks["force_model_worst_rms_ratio"] = {a: v[1] for a, v in fm.items()}
    return tab


_NEEDS_EXCITATION = {
    "feedforward": "feedforward controllers need excitation_period_s [s]",
    "feedforward+robust": "feedforward controllers need excitation_period_s [s]",
    "tuned": "the tuned controller needs excitation_period_s [s]",
    "repetitive": "the repetitive controller needs excitation_period_s [s]",
    "adaptive": "the adaptive controllers need the nominal excitation_period_s [s]",
}

#: Default period-tracker settings (:class:`~robovib.control.adaptive.PeriodTracker`).
TRACKER_DEFAULTS = {"rel_range": 0.1, "window_periods": 2.0, "update_periods": 1.0,
                    "smoothing": 0.5, "lag_periods": 1}  # fmt: skip
#: Tracker settings a newly designed controller file carries over the defaults (a file written
#: before they existed loads with the defaults, i.e. as it ran then): the period estimated
#: over two periods at once (half the phase wander of the learners in non-periodic force).
TRACKER_DESIGN = {"lag_periods": 2}
#: Default fade-out guard settings (:class:`~robovib.control.guard.FadeGuard`).
GUARD_DEFAULTS = {"min_periodicity": 0.5, "max_ratio": 1.0, "z_score": 1.0, "window_s": 0.5,
                  "check_s": 0.1, "fade_time_s": 0.2, "warmup_s": 0.5}  # fmt: skip


def assemble_controller(
    name: str,
    tab: PathTables,
    *,
    excitation_period_s: float | None = None,
    teeth: int = 1,
    tracker: dict | None = None,
    guard: dict | None = None,
    learner: dict | None = None,
    model=None,
):
    """A fresh run-time controller ``name`` from the design tables.

    Parameters
    ----------
    name
        A name of :data:`DESIGNS`.
    tab
        The tables (:func:`design_tables`).
    excitation_period_s
        Nominal period of the disturbing force [s] (the controllers that need it).
    teeth
        The cutter's teeth; above 1 ``adaptive+force`` also learns the runout lines.
    tracker, guard
        Period-tracker and guard settings (default :data:`TRACKER_DEFAULTS`,
        :data:`GUARD_DEFAULTS`).
    learner
        Options of the tracking repetitive learners
        (:class:`~robovib.control.adaptive.TrackingRepetitive`, e.g. ``divergence_test``).
    model
        The pose model: only ``tuned`` needs it (its design depends on the excitation).

    Returns
    -------
    object
        A controller with ``reset`` / ``command`` (:class:`~robovib.control.protocol.Controller`).

    Raises
    ------
    ValueError
        Unknown name, or a controller that needs ``excitation_period_s`` without it.
    """
    check_controller_names([name])
    if DESIGNS[name].needs_excitation and excitation_period_s is None:
        raise ValueError(_NEEDS_EXCITATION.get(name, _NEEDS_EXCITATION["adaptive"]))
    grid, axes, delay_s = tab.grid, tab.axes, tab.delay_s
    tracker_opts = {**TRACKER_DEFAULTS, **(tracker or {})}
    guard_opts = {**GUARD_DEFAULTS, **(guard or {})}
    if name == "thesis":
        return StateFeedback({a: ScheduledTable(grid, np.column_stack([s.w1, s.w2]))
                              for a, s in tab.schedule.items()})  # fmt: skip
    if name in ("constant-start", "constant-end"):
        return StateFeedback(dict(tab.constant[name]))
    if name == "lqg":
        gains = {a: ScheduledTable(grid, tab.lqg[a]) for a in axes}
        kal = {a: (grid, [design_kalman(m) for m in tab.modes[a]]) for a in axes}
        return DelayAwareFeedback(gains, kal, delay_samples=round(delay_s * 1000.0))
    robust = {a: ScheduledTable(grid, tab.robust[a]) for a in tab.robust}
    if name == "robust":
        return DelayAwareFeedback(robust)
    stiff = {a: tab.stiffness(a) for a in axes}
    if name == "feedforward":
        return ForceFeedforward(stiff, excitation_period_s, delay_s)
    if name == "feedforward+robust":
        return Combined(ForceFeedforward(stiff, excitation_period_s, delay_s),
                        DelayAwareFeedback(robust))  # fmt: skip
    if name == "tuned":
        if model is None:
            raise ValueError("the tuned controller is designed per excitation: it needs the model")
        return _tuned(tab, excitation_period_s)
    fz = {a: tab.fz(a) for a in axes}
    learner = dict(learner or {})
    if learner.get("n_harmonics") == "auto":
        # every tooth harmonic the learner may use (below max_harmonic_ratio x the highest fn)
        ratio = learner.get("max_harmonic_ratio", 1.6)
        fn_max = max(float(np.max(t.values[:, 0])) for t in fz.values())
        learner["n_harmonics"] = max(1, math.floor(ratio * fn_max * excitation_period_s))
    if name == "repetitive":
        return RepetitiveFeedback(fz, excitation_period_s, delay_s)
    tracker_obj = PeriodTracker(excitation_period_s, **tracker_opts)
    if name == "adaptive-feedforward":
        parts = [TrackingFeedforward(stiff, tracker_obj, delay_s)]
    else:
        parts = [TrackingRepetitive(fz, tracker_obj, delay_s, **learner)]
    if name == "adaptive+force" and teeth > 1:
        # The once-per-revolution lines of runout (spindle harmonics that are not tooth
        # harmonics), learnt over a revolution, slowly against that window.
        runout = {k: v for k, v in learner.items() if k not in ("n_harmonics", "learning_time_s")}
        parts.append(TrackingRepetitive(fz, tracker_obj, delay_s, **runout, period_multiple=teeth,
                                        n_harmonics=2 * teeth,
                                        learning_time_s=RUNOUT_LEARNING_REVS * teeth * excitation_period_s))  # fmt: skip
    if name == "adaptive+force" and tab.force_model_r:
        # the axes whose force model was kept (a controller file leaves out an axis whose
        # force model amplifies somewhere in the checked band)
        fzk = {a: ScheduledTable(grid, np.column_stack([fz[a].values, stiff[a].values]))
               for a in axes if a in tab.force_model_r}  # fmt: skip
        parts.append(ForceModelFeedforward(fzk, delay_s, r=dict(tab.force_model_r)))
    elif name != "adaptive":
        parts.append(DelayAwareFeedback(robust))
    if name == "adaptive+force" and tab.feedback:
        # a controller file's band-stable delay-aware feedback on the other axes
        parts.append(DelayAwareFeedback({a: ScheduledTable(grid, g)
                                         for a, g in tab.feedback.items()}))  # fmt: skip
    return FadeGuard(Combined(*parts), tracker_obj, fz, delay_s, **guard_opts)


def band_stable_feedback(plant_sets, nominals, period_s: float, delay_s: float,
                         true_delays_s, r_grid=None, actuator_gains=(1.0,)):  # fmt: skip
    """The most aggressive delay-aware LQR gains stable on every plant of the band.

    For each ``R`` of ``r_grid`` from the largest (gentlest) down, the gains of
    :func:`~robovib.control.lqr.design_delay_aware_lqr` on the nominal mode of each design
    point are checked on every plant of that point's set (band corners, second modes) with
    every true delay of ``true_delays_s`` and every actuator gain of ``actuator_gains``
    (:func:`implemented_loop_matrix` with ``plant_delay_steps`` and ``actuator_gain``); the
    smallest ``R`` before the first that fails at some point is
    used. (The robust design instead picks the ``R`` of the fastest worst-case decay, which
    for a 32-40 ms delay on a 15-22 Hz mode is a gain too small to reduce the vibration.)

    Parameters
    ----------
    plant_sets
        Per design point, the plants (lists of :class:`ModalParameters`).
    nominals
        Per design point, the nominal mode.
    period_s, delay_s
        Command period and the delay the gains assume [s].
    true_delays_s
        The true delays the gains must be stable with [s].
    r_grid
        The ``R`` tried (default ``logspace(-2, 3, 11)``).
    actuator_gains
        The ratios applied / commanded correction the gains must be stable with (1: none).

    Returns
    -------
    tuple
        ``(r, gains (n, 2 + d), worst spectral radius per design point)``, or ``None`` when
        not even the largest ``R`` is stable everywhere.
    """
    grid = np.logspace(-2, 3, 11) if r_grid is None else np.asarray(r_grid, float)
    d = round(delay_s / period_s)
    steps = sorted({round(t / period_s) for t in true_delays_s})
    act = [float(k) for k in actuator_gains]
    if not act or not all(np.isfinite(k) and k > 0 for k in act):
        raise ValueError(f"actuator_gains must be finite and > 0, got {actuator_gains!r}")
    best = None
    for r in sorted(grid, reverse=True):
        gains, worst = [], []
        for plants, nominal in zip(plant_sets, nominals, strict=True):
            g = design_delay_aware_lqr(nominal, period_s, delay_s, r=[[float(r)]]).gains
            w = max(spectral_radius(implemented_loop_matrix(p, g, period_s, d,
                                                            plant_delay_steps=D,
                                                            actuator_gain=k))
                    for p in plants for D in steps for k in act)  # fmt: skip
            gains.append(g)
            worst.append(w)
        if max(worst) >= 1.0:
            break
        best = (float(r), np.array(gains), worst)
    return best


def _tuned(tab: PathTables, excitation_period_s: float) -> StateFeedback:
    out = {}
    for a in tab.axes:
        rows = []
        for plants in tab.plants[a]:
            key = ("tuned", tuple(tuple(p) for p in plants), excitation_period_s, tab.period_s,
                   tab.delay_s)  # fmt: skip
            if key not in _DESIGN_CACHE:
                _DESIGN_CACHE[key] = design_tuned_state_feedback(
                    plants, plants[0][0], 1.0 / excitation_period_s,
                    period_s=tab.period_s, delay_s=tab.delay_s)[0]  # fmt: skip
            rows.append(_DESIGN_CACHE[key])
        out[a] = ScheduledTable(tab.grid, np.array(rows))
    return StateFeedback(out)


def build_controllers(
    model: PoseModalModel,
    axes: dict[int, str],
    s_grid,
    *,
    names=CONTROLLERS,
    excitation_period_s: float | None = None,
    s_start: float | None = None,
    s_end: float | None = None,
    period_s: float = 0.004,
    delay_s: float = 0.032,
    lqg_r: float | None = None,
    robust_r_grid=None,
    teeth: int = 1,
) -> dict[str, object]:
    """Controllers designed from the pose model only, scheduled over ``s_grid`` [m].

    ``constant-start`` / ``constant-end`` use the pose-dependent design at ``s_start`` /
    ``s_end``. The feedforward, tuned, repetitive and adaptive controllers need
    ``excitation_period_s`` (the force's period). The names are checked before any design
    runs; the modes along the path are computed once (:func:`design_tables`) and every
    controller is assembled from those tables (:func:`assemble_controller`). Designs are cached
    per process (keyed by their inputs); the returned controllers are fresh objects.

    Parameters
    ----------
    model
        A path model over ``input_names=("s_m",)`` (e.g. from
        :func:`robovib.sim.path_modal_model`).
    axes
        Controlled axes: tool-tip axis index (0 = X, 1 = Y, 2 = Z) -> model direction.
    s_grid
        Path distances [m] at which the gains are designed and tabulated.
    names
        Controllers to build, from :data:`CONTROLLERS`.
    excitation_period_s
        Period of the disturbing force (spindle or tooth-passing period) [s].
    s_start, s_end
        Path distances [m] of the ``constant-start`` / ``constant-end`` designs (default the
        first grid point).
    period_s
        Command period of the controller [s] (250 Hz: 0.004 s).
    delay_s
        Command delay the designs account for [s].
    lqg_r
        Control weight R of the LQG design; None: chosen like the robust design, on the loop
        with the Kalman filter.
    robust_r_grid
        Candidate R values of the robust design (default ``logspace(-2, 3, 11)``).
    teeth
        The cutter's teeth; above 1 ``adaptive+force`` also learns the once-per-revolution
        (runout) lines.

    Returns
    -------
    dict
        Controller name -> controller object.

    Raises
    ------
    ValueError
        Unknown names, or a controller that needs ``excitation_period_s`` without it.
    """
    names = check_controller_names(names)
    for n in names:
        if DESIGNS[n].needs_excitation and excitation_period_s is None:
            assemble_controller(n, PathTables(np.zeros(0), {}, {}, period_s, delay_s))  # raises
    tab = design_tables(model, axes, s_grid, names=names, s_start=s_start, s_end=s_end,
                        period_s=period_s, delay_s=delay_s, lqg_r=lqg_r,
                        robust_r_grid=robust_r_grid)  # fmt: skip
    # the order of the result rows since the studies began (tuned after the feedforwards)
    build_order = ("thesis", "constant-start", "constant-end", "lqg", "robust", "feedforward",
                   "feedforward+robust", "tuned", "repetitive", "adaptive", "adaptive+robust",
                   "adaptive-feedforward", "adaptive+force")  # fmt: skip
    order = [n for n in build_order if n in names]
    return {n: assemble_controller(n, tab, excitation_period_s=excitation_period_s, teeth=teeth,
                                   model=model) for n in order}  # fmt: skip


#: The thesis' printed constant gains (w1, w2) at the start of the Table 7 path (extended end).
THESIS_PRINTED_START_GAINS = (0.11, 0.0065)
#: The thesis' printed constant gains (w1, w2) at the end of the Table 7 path (near the base).
THESIS_PRINTED_END_GAINS = (0.06, 0.005)


def thesis_printed_gains(s_m, s_start_m: float) -> np.ndarray:
    """The thesis' printed gain schedule (Eq. 28-29) at path distances ``s_m``.

    The thesis gives ``w1`` and ``w2`` as polynomials of ``d``, the distance from the start of
    the path in millimetres: ``w1 = -4.3e-5 d + 0.12`` and
    ``w2 = -3e-14 d^4 + 7e-11 d^3 - 6e-8 d^2 + 1e-5 d + 0.006``.

    Parameters
    ----------
    s_m
        Path distances [m] (scalar or array).
    s_start_m
        Path distance [m] where the move starts (``d = |s_m - s_start_m|``).

    Returns
    -------
    numpy.ndarray
        (n, 2) gains ``[w1, w2]`` per path distance.

    Examples
    --------
    >>> thesis_printed_gains([1.235], 1.235).round(4).tolist()
    [[0.12, 0.006]]
    """
    d = np.abs(np.asarray(s_m, float) - s_start_m) * 1e3
    w1 = -4.3e-5 * d + 0.12
    w2 = -3e-14 * d**4 + 7e-11 * d**3 - 6e-8 * d**2 + 1e-5 * d + 0.006
    return np.column_stack([w1, w2])
