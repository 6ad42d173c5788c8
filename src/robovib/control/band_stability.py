"""Stability of designed controllers over a pose model's band (thesis ch. 4).

:func:`stability_over_band` checks every feedback loop of a set of controllers on the plants
of :func:`robovib.control.pose_plants.plant_set` (the nominal mode, the 8 corners of the GP
band and, optionally, unmodelled second modes) at poses along the path.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from .controllers import (
    Combined,
    DelayAwareFeedback,
    RepetitiveFeedback,
    StateFeedback,
    design_kalman,
    implemented_loop_matrix,
    lqg_loop_matrix,
    spectral_radius,
)
from .pose_plants import path_mode
from .pose_plants import plant_set as _model_set

if TYPE_CHECKING:
    from ..gp import PoseModalModel

__all__ = ["stability_over_band"]


def _controller_gains(ctrl, axis: int, coords) -> np.ndarray | None:
    """Feedback gains (n, m) of a controller along ``coords`` (None: no feedback)."""
    if isinstance(ctrl, Combined):
        for p in ctrl.parts:
            g = _controller_gains(p, axis, coords)
            if g is not None:
                return g
        return None
    if isinstance(ctrl, StateFeedback | DelayAwareFeedback):
        return ctrl.gains[axis].at(coords)
    return None


def stability_over_band(
    model: PoseModalModel,
    controllers: dict[str, object],
    axes: dict[int, str],
    s_points,
    *,
    period_s: float = 0.004,
    delay_s: float = 0.032,
    second_modes: bool = False,
) -> dict[str, float]:
    """Worst spectral radius of each feedback loop over the GP 95 % band at every pose.

    The implemented loop (backward-difference velocity; the LQG with its 1 kHz Kalman filter,
    :func:`~robovib.control.controllers.lqg_loop_matrix`) with the nominal delay, for the
    nominal mode and the 8 band corners at each of ``s_points`` (``second_modes=True``: also
    with each :data:`~robovib.control.pose_plants.SECOND_MODE_HYPOTHESES` second mode).
    < 1: stable everywhere. NaN: no feedback.
    The repetitive controller is checked through its phasor learning loop
    (:meth:`~robovib.control.controllers.RepetitiveFeedback.loop_radius`).

    Parameters
    ----------
    model
        The path model the controllers were designed from (e.g.
        :func:`robovib.sim.path_modal_model`).
    controllers
        Name -> controller, e.g. from
        :func:`robovib.control.design.build_controllers`.
    axes
        Tool-tip axis index -> model direction, as the controllers were designed for.
    s_points
        Path distances [m] checked.
    period_s
        Command period [s].
    delay_s
        Command delay [s].
    second_modes
        Also check each plant with the second modes of
        :data:`~robovib.control.pose_plants.SECOND_MODE_HYPOTHESES`.

    Returns
    -------
    dict
        Controller name -> worst spectral radius (< 1: stable; NaN: no feedback loop).
    """
    d = round(delay_s / period_s)
    s = np.asarray(s_points, float)
    out = {}
    for name, ctrl in controllers.items():
        worst = np.nan
        if isinstance(ctrl, RepetitiveFeedback):
            for direction in axes.values():
                for si in s:
                    nominal = path_mode(model, si, direction)
                    for p in _model_set(model, si, direction, second_modes):
                        rho = ctrl.loop_radius(p, nominal, period_s)
                        worst = rho if np.isnan(worst) else max(worst, rho)
            out[name] = float(worst)
            continue
        for a, direction in axes.items():
            g = _controller_gains(ctrl, a, s)
            if g is None:
                continue
            lqg = isinstance(ctrl, DelayAwareFeedback) and ctrl.kalman is not None
            for si, gi in zip(s, g, strict=True):
                kf = design_kalman(path_mode(model, si, direction)) if lqg else None
                for p in _model_set(model, si, direction, second_modes):
                    m = (lqg_loop_matrix(p, gi, kf, period_s, 1e-3, round(delay_s * 1e3)) if lqg
                         else implemented_loop_matrix(p, gi, period_s, d))  # fmt: skip
                    rho = spectral_radius(m)
                    worst = rho if np.isnan(worst) else max(worst, rho)
        out[name] = float(worst)
    return out
