"""Controller design from a pose model along a path (thesis ch. 4, Tables 7 and 10).

:func:`build_controllers` designs the controllers compared in the closed-loop studies
(:data:`CONTROLLERS`) from a path model only (a :class:`robovib.gp.PoseModalModel` over the
path distance ``s_m``; the virtual robot's is :func:`robovib.sim.path_modal_model`): the
thesis' Eq. 28-29 schedule, constant designs, LQG, the robust design over the GP band
(:func:`robovib.control.pose_plants.plant_set`), force feedforward, a tuned state feedback,
repetitive and adaptive controllers. The studies (:mod:`robovib.studies.control_closed_loop`)
run them on the virtual robot.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ..modal.parameters import ModalParameters
from .adaptive import FadeGuard, PeriodTracker, TrackingFeedforward, TrackingRepetitive
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
from .lqr import design_delay_aware_lqr
from .pose_plants import path_mode
from .pose_plants import plant_set as _model_set
from .schedule import GainSchedule, schedule_gains

if TYPE_CHECKING:
    from ..gp import PoseModalModel

__all__ = [
    "CONTROLLERS",
    "DEFAULT_CONTROLLER",
    "RUNOUT_LEARNING_REVS",
    "THESIS_PRINTED_END_GAINS",
    "THESIS_PRINTED_START_GAINS",
    "build_controllers",
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
    plants = _model_set(model, s_m, direction)
    nominal = path_mode(model, s_m, direction)
    key = ("force-model", nominal, tuple(tuple(p) for p in plants), period_s, delay_s)
    if key not in _DESIGN_CACHE:
        _DESIGN_CACHE[key] = force_model_r(plants, nominal, period_s=period_s, delay_s=delay_s)[0]
    return _DESIGN_CACHE[key]


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
    ``excitation_period_s`` (the force's period). Designs are cached per process (keyed by
    their inputs); the returned controllers are fresh objects.

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
    grid = np.asarray(s_grid, float)
    r_grid = np.logspace(-2, 3, 11) if robust_r_grid is None else np.asarray(robust_r_grid)
    out: dict[str, object] = {}
    need_sched = {"thesis", "constant-start", "constant-end"} & set(names)
    sched = {a: _schedule(model, d, grid) for a, d in axes.items()} if need_sched else {}
    if "thesis" in names:
        out["thesis"] = StateFeedback(
            {a: ScheduledTable(grid, np.column_stack([s.w1, s.w2])) for a, s in sched.items()}
        )
    for name, s_at in (("constant-start", s_start), ("constant-end", s_end)):
        if name in names:
            s_at = grid[0] if s_at is None else s_at
            out[name] = StateFeedback({a: s.gains_at(s_at) for a, s in sched.items()})
    if "lqg" in names:
        gains, kal = {}, {}
        for a, d in axes.items():
            modes = [path_mode(model, si, d) for si in grid]
            if lqg_r is None:  # R picked like the robust design, on the loop with the filter
                rows = [_robust_r(_model_set(model, si, d), m, period_s, delay_s, r_grid, "kalman")[1]
                        for si, m in zip(grid, modes, strict=True)]  # fmt: skip
            else:
                rows = [
                    design_delay_aware_lqr(m, period_s, delay_s, r=[[lqg_r]]).gains for m in modes
                ]
            gains[a] = ScheduledTable(grid, np.array(rows))
            kal[a] = (grid, [design_kalman(m) for m in modes])
        out["lqg"] = DelayAwareFeedback(gains, kal, delay_samples=round(delay_s * 1000.0))
    robust = None
    if "robust" in names or "feedforward+robust" in names:
        tabs = {}
        for a, d in axes.items():
            rows = [
                _robust_r(
                    _model_set(model, si, d), path_mode(model, si, d), period_s, delay_s, r_grid
                )[1]
                for si in grid
            ]
            tabs[a] = ScheduledTable(grid, np.array(rows))
        robust = tabs
        if "robust" in names:
            out["robust"] = DelayAwareFeedback(robust)
    if "feedforward" in names or "feedforward+robust" in names:
        if excitation_period_s is None:
            raise ValueError("feedforward controllers need excitation_period_s [s]")
        stiff = {
            a: ScheduledTable(grid, np.array([[path_mode(model, si, d).stiffness_n_per_m] for si in grid]))
            for a, d in axes.items()
        }  # fmt: skip
        if "feedforward" in names:
            out["feedforward"] = ForceFeedforward(stiff, excitation_period_s, delay_s)
        if "feedforward+robust" in names:
            out["feedforward+robust"] = Combined(
                ForceFeedforward(stiff, excitation_period_s, delay_s), DelayAwareFeedback(robust)
            )
    if "tuned" in names:
        if excitation_period_s is None:
            raise ValueError("the tuned controller needs excitation_period_s [s]")
        tab = {}
        for a, d in axes.items():
            rows = []
            for si in grid:
                plants = _model_set(model, si, d)
                key = (
                    "tuned",
                    tuple(tuple(p) for p in plants),
                    excitation_period_s,
                    period_s,
                    delay_s,
                )
                if key not in _DESIGN_CACHE:
                    _DESIGN_CACHE[key] = design_tuned_state_feedback(
                        plants, plants[0][0], 1.0 / excitation_period_s,
                        period_s=period_s, delay_s=delay_s)[0]  # fmt: skip
                rows.append(_DESIGN_CACHE[key])
            tab[a] = ScheduledTable(grid, np.array(rows))
        out["tuned"] = StateFeedback(tab)
    if "repetitive" in names:
        if excitation_period_s is None:
            raise ValueError("the repetitive controller needs excitation_period_s [s]")
        modes = {
            a: ScheduledTable(grid, np.array([[m.natural_frequency_hz, m.damping_ratio]
                                              for m in (path_mode(model, si, d) for si in grid)]))
            for a, d in axes.items()
        }  # fmt: skip
        out["repetitive"] = RepetitiveFeedback(modes, excitation_period_s, delay_s)
    adaptive = {"adaptive", "adaptive+robust", "adaptive-feedforward", "adaptive+force"} & set(
        names
    )
    if adaptive:
        if excitation_period_s is None:
            raise ValueError("the adaptive controllers need the nominal excitation_period_s [s]")
        fz = {
            a: ScheduledTable(grid, np.array([[m.natural_frequency_hz, m.damping_ratio]
                                              for m in (path_mode(model, si, d) for si in grid)]))
            for a, d in axes.items()
        }  # fmt: skip
        stiff = {
            a: ScheduledTable(grid, np.array([[path_mode(model, si, d).stiffness_n_per_m] for si in grid]))
            for a, d in axes.items()
        }  # fmt: skip
        if robust is None:
            robust = {
                a: ScheduledTable(grid, np.array([
                    _robust_r(_model_set(model, si, d), path_mode(model, si, d), period_s, delay_s, r_grid)[1]
                    for si in grid]))
                for a, d in axes.items()
            }  # fmt: skip
        for name in adaptive:
            tracker = PeriodTracker(excitation_period_s)
            if name == "adaptive-feedforward":
                parts = [TrackingFeedforward(stiff, tracker, delay_s)]
            else:
                parts = [TrackingRepetitive(fz, tracker, delay_s)]
            if name == "adaptive+force" and teeth > 1:
                # The once-per-revolution lines of runout (spindle harmonics that are not tooth
                # harmonics), learnt over a revolution, slowly against that window.
                parts.append(TrackingRepetitive(fz, tracker, delay_s, period_multiple=teeth,
                                                n_harmonics=2 * teeth,
                                                learning_time_s=RUNOUT_LEARNING_REVS * teeth * excitation_period_s))  # fmt: skip
            if name == "adaptive+force":
                fzk = {a: ScheduledTable(grid, np.column_stack([fz[a].values, stiff[a].values]))
                       for a in axes}  # fmt: skip
                parts.append(ForceModelFeedforward(fzk, delay_s, r={
                    a: _force_model_r(model, float(np.median(grid)), d, period_s, delay_s)
                    for a, d in axes.items()}))  # fmt: skip
            elif name != "adaptive":
                parts.append(DelayAwareFeedback(robust))
            out[name] = FadeGuard(Combined(*parts), tracker, fz, delay_s)
    unknown = set(names) - set(CONTROLLERS)
    if unknown:
        raise ValueError(f"unknown controllers {sorted(unknown)}; expected some of {CONTROLLERS}")
    return out


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
