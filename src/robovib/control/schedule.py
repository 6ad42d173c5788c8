"""Gain scheduling along a tool path (thesis §4.3.3, Eq. 28-29).

Gains are designed at N points along the path from the pose model's predicted modes; in the
control cycle they are looked up by path distance either from (a) the thesis' polynomial fits
(degree 1 for w1, 4 for w2, Eq. 28-29) or (b) linear interpolation of the designed points
(default). Both lookups cost a few microseconds (see ``benchmarks/bench_control.py``).
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np

from ..modal.parameters import ModalParameters
from .lqr import THESIS_Q, LQRDesign, delay_analysis, design_lqr, tune_r_for_delay

__all__ = ["GainSchedule", "ModelSchedule", "schedule_along_line", "schedule_gains"]


@dataclass(frozen=True)
class GainSchedule:
    """Gains w1, w2 at path distances ``s_m`` with polynomial fits (coefficients high->low).

    Attributes
    ----------
    s_m
        (n,) path distances [m].
    w1, w2
        (n,) gains at those points.
    r
        (n,) the R used at each point.
    stable_with_delay
        (n,) bool: the loop is stable with the transport delay.
    w1_poly, w2_poly
        Polynomial fits of the gains over ``s_m`` (coefficients high -> low).
    """

    s_m: np.ndarray
    w1: np.ndarray
    w2: np.ndarray
    r: np.ndarray  #: the R used at each point
    stable_with_delay: np.ndarray  #: bool per point
    w1_poly: np.ndarray
    w2_poly: np.ndarray

    def gains_at(
        self,
        s_m: float,
        method: Literal["interp", "poly"] = "interp",
        *,
        outside: Literal["raise", "hold"] = "raise",
    ) -> tuple[float, float]:
        """Gains (w1 [m/m], w2 [s]) at path distance ``s_m`` [m].

        Parameters
        ----------
        s_m : float
            Path distance [m].
        method : {"interp", "poly"}
            Linear interpolation of the designed points, or the thesis' polynomial fits
            (Eq. 28-29).
        outside : {"raise", "hold"}
            Outside the designed range ``[s_m[0], s_m[-1]]``: raise (default; the gains there
            were never checked for stability) or hold the end gains.

        Returns
        -------
        tuple of float
            ``(w1, w2)``.

        Raises
        ------
        ValueError
            ``s_m`` not finite, outside the designed range with ``outside="raise"``, or an
            unknown ``method`` / ``outside``.
        """
        if method not in ("interp", "poly"):
            raise ValueError(f"unknown method {method!r}; expected 'interp' or 'poly'")
        if outside not in ("raise", "hold"):
            raise ValueError(f"unknown outside {outside!r}; expected 'raise' or 'hold'")
        s = float(s_m)
        lo, hi = float(self.s_m[0]), float(self.s_m[-1])
        if not np.isfinite(s):
            raise ValueError(f"path distance s_m must be finite [m], got {s_m!r}")
        tol = 1e-9 * max(1.0, abs(hi - lo))
        if outside == "raise" and not (lo - tol <= s <= hi + tol):
            raise ValueError(
                f"path distance {s:g} m lies outside the designed range [{lo:g}, {hi:g}] m; "
                "design the schedule over the whole path or pass outside='hold'"
            )
        s = min(max(s, lo), hi)
        if method == "interp":
            return float(np.interp(s, self.s_m, self.w1)), float(np.interp(s, self.s_m, self.w2))
        return float(np.polyval(self.w1_poly, s)), float(np.polyval(self.w2_poly, s))

    def plot(self, ax=None):
        """Designed gains w1, w2 along the path with their polynomial fits (thesis Fig. 23).

        Parameters
        ----------
        ax : sequence of two matplotlib.axes.Axes, optional
            Axes for w1 [m/m] and w2 [s]; a new figure when omitted.

        Returns
        -------
        matplotlib.figure.Figure
            The figure (saving is the caller's: ``robovib.io.save_figure``).
        """
        import matplotlib.pyplot as plt

        if ax is None:
            fig, axes = plt.subplots(1, 2, figsize=(9, 3.5))
        else:
            axes = list(ax)
            if len(axes) != 2:
                raise ValueError(f"ax must be two Axes (w1, w2), got {len(axes)}")
            fig = axes[0].figure
        dense = np.linspace(self.s_m.min(), self.s_m.max(), 200)
        for ax, w, poly, name in (
            (axes[0], self.w1, self.w1_poly, "w1 [m/m]"),
            (axes[1], self.w2, self.w2_poly, "w2 [s]"),
        ):
            ax.plot(self.s_m, w, "o", label="designed")
            ax.plot(dense, np.polyval(poly, dense), "-", label="polynomial fit (Eq. 28-29 form)")
            ax.set_xlabel("distance along the path s [m]")
            ax.set_ylabel(name)
            ax.legend(fontsize=8)
        fig.tight_layout()
        return fig


def schedule_gains(
    s_m: Sequence[float],
    modes: Sequence[ModalParameters],
    *,
    period_s: float = 0.004,
    delay_s: float = 0.032,
    q=THESIS_Q,
    r: float | None = None,
    warn: Callable[[str], None] | None = None,
) -> GainSchedule:
    """Gains along a path from the modes predicted at the path distances ``s_m`` (Eq. 28-29).

    See ``docs/methods.md`` section 6 (pose-dependent vibration control).

    Parameters
    ----------
    s_m : sequence of float, shape (n,)
        Path coordinates [m], strictly increasing, at least 5.
    modes : sequence of ModalParameters, shape (n,)
        The mode at each path coordinate.
    period_s : float
        Command period [s].
    delay_s : float
        Loop delay [s] the gains must stay stable with.
    q : array_like, shape (2, 2)
        State weight of the LQR.
    r : float, optional
        ``None``: R tuned per point for stability with the delay (:func:`tune_r_for_delay`);
        a number: that R everywhere (points whose delayed loop is unstable are flagged).
    warn : callable(str), optional
        Receives a message for each flagged point (default: :func:`warnings.warn`).

    Returns
    -------
    GainSchedule
        ``s_m``, gains ``w1`` [m/m] and ``w2`` [s], ``r``, ``stable_with_delay`` and the
        polynomial fits ``w1_poly``, ``w2_poly`` (highest power first).

    Raises
    ------
    ValueError
        Lengths differ, ``s_m`` not increasing, fewer than 5 points, bad weights or delay.

    Examples
    --------
    >>> import numpy as np
    >>> from robovib.control.schedule import schedule_gains
    >>> from robovib.modal import ModalParameters
    >>> s = np.linspace(0.335, 1.235, 5)
    >>> sched = schedule_gains(s, [ModalParameters(14 + 4 * v, 2e6, 0.05) for v in s])
    >>> sched.w1.shape
    (5,)
    """
    from .._checks import check_increasing

    s = np.asarray(s_m, float)
    if s.ndim != 1 or s.size != len(modes) or s.size < 5:
        raise ValueError("need at least 5 path points with one mode each")
    # unsorted or repeated points would make the interpolated gains silently wrong
    s = check_increasing("path distances s_m", s, "m", min_size=5)
    w1, w2, rs, ok = [], [], [], []
    for si, mode in zip(s, modes, strict=True):
        if r is None:
            design, ri = tune_r_for_delay(mode, period_s, delay_s, q)
        else:
            design: LQRDesign = design_lqr(mode, period_s, q, [[r]])
            ri = float(r)
        stable = delay_analysis(design, delay_s, rounding="round", max_search_steps=0).stable
        if not stable:
            message = f"gains at s = {si:.3f} m are unstable with the {delay_s * 1e3:g} ms delay"
            if warn is None:
                warnings.warn(message, RuntimeWarning, stacklevel=2)
            else:
                warn(message)
        w1.append(design.gains[0])
        w2.append(design.gains[1])
        rs.append(ri)
        ok.append(stable)
    w1, w2 = np.array(w1), np.array(w2)
    return GainSchedule(
        s, w1, w2, np.array(rs), np.array(ok), np.polyfit(s, w1, 1), np.polyfit(s, w2, 4)
    )


@dataclass(frozen=True)
class ModelSchedule:
    """Gains along a straight line through a pose model's workspace.

    Attributes
    ----------
    schedule
        The gains along the line (``s_m``: path distance [m], see :func:`schedule_along_line`).
    poses
        (n, n_inputs) poses in the model's input units.
    input_names
        The model's input names.
    modes
        The predicted mode at each pose (SI).
    extrapolating
        (n,) bool: pose outside the model's training data.
    mode_choice
        How the one controlled mode was picked where the direction has several (a multi-mode
        model); empty otherwise.
    """

    schedule: GainSchedule
    poses: np.ndarray  #: (n, n_inputs) poses in the model's input units
    input_names: tuple[str, ...]
    modes: tuple[ModalParameters, ...]  #: the predicted mode at each pose (SI)
    extrapolating: np.ndarray  #: bool (n,): pose outside the model's training data
    mode_choice: str = ""


def schedule_along_line(
    model,
    start,
    end,
    direction: str,
    n_points: int = 20,
    **schedule_kwargs,
) -> ModelSchedule:
    """Gains along the straight line from ``start`` to ``end`` from a pose model (§4.3.3).

    The thesis designs W at 20 equally spaced points of the path from the GP's predicted modes
    and schedules them by path distance. Here the poses are interpolated linearly between
    ``start`` and ``end`` (in the model's input units, e.g. (x_mm, y_mm, rz_deg)); the path
    distance ``s`` [m] is the tool-tip travel from ``start`` in the inputs named ``x_mm``,
    ``y_mm`` (``z_mm``), or, for a path model with input ``s_m``, that input itself (then the
    design points are returned in increasing ``s_m`` whichever way the line runs).

    Parameters
    ----------
    model : PoseModalModel
        Any fitted pose model with ``modes(X)`` and ``input_names``.
    start, end : array_like, shape (n_inputs,)
        End poses of the line, in the model's input units.
    direction : str
        The direction whose dominant mode is controlled (one of the model's directions).
    n_points : int
        Design points (at least 5).
    **schedule_kwargs
        Passed to :func:`schedule_gains` (``period_s``, ``delay_s``, ``q``, ``r``, ``warn``).

    Returns
    -------
    ModelSchedule
        The :class:`GainSchedule` over ``s`` [m], the poses, the predicted modes and a flag per
        pose that is outside the model's training data (its mode is a GP extrapolation).

    Raises
    ------
    ValueError
        Wrong pose length or non-finite pose, start equal to end, an unknown direction, a
        model without position inputs, or fewer than 5 points.
    """
    names = tuple(model.input_names)
    a = np.asarray(start, float).reshape(-1)
    b = np.asarray(end, float).reshape(-1)
    if a.size != len(names) or b.size != len(names):
        raise ValueError(
            f"start and end need {len(names)} coordinates ({', '.join(names)}), "
            f"got {a.size} and {b.size}"
        )
    if not (np.all(np.isfinite(a)) and np.all(np.isfinite(b))):
        raise ValueError("start and end poses must be finite")
    if int(n_points) != n_points or n_points < 5:
        raise ValueError(f"n_points must be a whole number >= 5, got {n_points!r}")
    from ..gp.contract import physical_direction

    directions = tuple(dict.fromkeys(physical_direction(d) for d in model.directions_))
    if direction not in directions:
        raise ValueError(
            f"unknown direction {direction!r}: give one of {', '.join(directions)} (the "
            f"directions of the model's modes {', '.join(model.directions_)})"
        )
    if "s_m" in names:
        pos = [names.index("s_m")]
        to_m = 1.0
    else:
        pos = [names.index(n) for n in ("x_mm", "y_mm", "z_mm") if n in names]
        to_m = 1e-3
    if not pos:
        raise ValueError(
            f"the model's inputs ({', '.join(names)}) have no position (x_mm, y_mm, z_mm or s_m) "
            "to measure the path distance in"
        )
    travel_m = float(np.linalg.norm((b - a)[pos])) * to_m
    if not travel_m > 0:
        raise ValueError("start and end are the same position: no path to schedule along")
    frac = np.linspace(0.0, 1.0, int(n_points))
    poses = a + frac[:, None] * (b - a)
    s = frac * travel_m
    if "s_m" in names:  # the path coordinate is an input: schedule on it, increasing
        s = poses[:, pos[0]]
        if s[-1] < s[0]:
            poses, s = poses[::-1], s[::-1]
    rows = [row[direction] for row in model.mode_set(poses)]
    # one mode along the whole line: the one with the largest compliance peak at most points
    ids = [m.mode_id for m in rows[0]]
    wins = [max(r, key=lambda m: m.compliance_peak_m_per_n).mode_id for r in rows]
    chosen = max(ids, key=wins.count)
    note = ""
    if len(ids) > 1:
        note = (f"{direction}: the model has modes {', '.join(ids)}; the schedule controls "
                f"{chosen}, the largest compliance peak at {wins.count(chosen)} of "
                f"{len(rows)} points")  # fmt: skip
    picked = [next(m for m in r if m.mode_id == chosen) for r in rows]
    modes = tuple(m.parameters for m in picked)
    flags = np.array([bool(m.mode.extrapolating) for m in picked])
    sched = schedule_gains(s, list(modes), **schedule_kwargs)
    return ModelSchedule(sched, poses, names, modes, flags, note)
