"""A point that coincides with a test cut shares the cut's local factor (issue 39).

With the factor split (:mod:`robovib.milling.factor_grid`) each weighted row ``r`` (a structure
x common factor) has the limit ``a_r`` before the local factor ``l``, log-uniform on
``(lo, hi)``, drawn afresh at every cut and every point. The local factor is the time-domain /
linear limit ratio: it depends on where the pose and speed sit in their lobes, so it is *not*
fresh at the cut's own point. A point within :class:`SamePointTolerance` of test cuts ``c``
(same pose and speed) shares their local factor. Per row, with ``u = log l`` uniform on
``(log lo, log hi)`` and the cut's threshold ``t_c = log(d_c / a_rc)`` (the cut chatters when
``u <= t_c``), the labels ``y_c`` give ``u`` the posterior density (the likelihood of
:func:`robovib.milling.cut_posterior.update_with_cuts`, label-noise rate ``eps``)::

    p(u | r, y) ∝ prod_c [eps + (1 - 2 eps) [u <= t_c]]     (y_c = chatter)
                         [1 - eps - (1 - 2 eps) [u <= t_c]]  (y_c = stable)

piecewise constant between the sorted ``t_c``, and the point at depth ``d`` is stable when
``u > log(d / a_r)``::

    P(stable at d | r, y) = int_{u > log(d / a_r)} p(u | r, y) du

(exact: the integral of a step function; used by ``mill lobes|map --cuts``,
:mod:`robovib.milling.cut_forecast`, and ``mill plan --cuts``,
:func:`robovib.milling.planning.plan_path`). The forecast is ``sum_r w_r P(stable at d | r, y)``
with the rows' posterior weights ``w_r`` of the update. After a chattering cut at depth
``d_c`` the point at ``d >= d_c`` (same limit) keeps P(stable) at about the label-noise level.

The row weights are those of :func:`~robovib.milling.cut_posterior.update_with_cuts`, which
draws each cut's local factor afresh: with one cut at a point they are exact; several cuts at
the same point are each conditioned on here, but their joint weight on the rows still treats
their local factors as independent (an approximation, stated).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .factor_grid import _checked_local, row_p_stable

__all__ = [
    "DEFAULT_SAME_POINT",
    "SamePointTolerance",
    "matching_cuts",
    "same_pose",
    "shared_local_p_stable",
    "shared_local_quantile",
    "shared_local_row_p_stable",
]


@dataclass(frozen=True)
class SamePointTolerance:
    """When a point is a test cut's own point (module docs).

    The local factor changes with speed on the scale of a lobe: a lobe spans ``dn / n ~ 1 / k``
    (``k`` the lobe number), so 0.5 % stays within a tenth of a lobe up to ``k ~ 20``. With pose
    it changes as the modes do (over tens to hundreds of mm, several degrees of Rz): a few mm
    and 1 degree are the same point for the robot (its repeatability and a typed pose).

    Attributes
    ----------
    position_mm
        Largest ``|dx|`` and ``|dy|`` [mm].
    rz_deg
        Largest ``|dRz|`` [deg] (wrapped to +-180).
    speed_rel
        Largest ``|dn| / n_cut``.
    """

    position_mm: float = 5.0
    rz_deg: float = 1.0
    speed_rel: float = 0.005

    def __post_init__(self):
        for name in ("position_mm", "rz_deg", "speed_rel"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v >= 0):
                raise ValueError(f"{name} must be finite and >= 0, got {v!r}")

    def to_dict(self) -> dict:
        """The tolerance as JSON.

        Returns
        -------
        dict
            ``position_mm``, ``rz_deg``, ``speed_rel`` (units in the keys).
        """
        return {"position_mm": float(self.position_mm), "rz_deg": float(self.rz_deg),
                "speed_rel": float(self.speed_rel)}  # fmt: skip


#: the tolerance of ``mill lobes|map --cuts`` (5 mm, 1 deg, 0.5 %)
DEFAULT_SAME_POINT = SamePointTolerance()


def same_pose(poses_mm_deg, cut_poses_mm_deg, tol: SamePointTolerance) -> np.ndarray:
    """Which cuts each point's pose is (x, y and Rz within ``tol``).

    Parameters
    ----------
    poses_mm_deg : array_like
        (P, 3) points' poses (x [mm], y [mm], Rz [deg]).
    cut_poses_mm_deg : array_like
        (n_cuts, 3) the cuts' poses.
    tol : SamePointTolerance
        The tolerance.

    Returns
    -------
    numpy.ndarray
        (P, n_cuts) bool.
    """
    p = np.atleast_2d(np.asarray(poses_mm_deg, float))[:, None, :]
    c = np.atleast_2d(np.asarray(cut_poses_mm_deg, float))[None, :, :]
    drz = (p[..., 2] - c[..., 2] + 180.0) % 360.0 - 180.0
    return (
        (np.abs(p[..., 0] - c[..., 0]) <= tol.position_mm)
        & (np.abs(p[..., 1] - c[..., 1]) <= tol.position_mm)
        & (np.abs(drz) <= tol.rz_deg)
    )


def _speed_match(spindle_rpm, cut_rpm, tol: SamePointTolerance) -> np.ndarray:
    """(J, n_cuts) bool: the speed is the cut's."""
    n = np.atleast_1d(np.asarray(spindle_rpm, float))[:, None]
    c = np.atleast_1d(np.asarray(cut_rpm, float))[None, :]
    return np.abs(n - c) <= tol.speed_rel * c


def matching_cuts(poses_mm_deg, spindle_rpm, cut_poses_mm_deg, cut_rpm,
                  tol: SamePointTolerance) -> np.ndarray:  # fmt: skip
    """(P, J, n_cuts) bool: which cuts each pose x speed point coincides with.

    Parameters
    ----------
    poses_mm_deg : array_like
        (P, 3) points' poses (x [mm], y [mm], Rz [deg]).
    spindle_rpm : array_like
        (J,) speeds [rpm].
    cut_poses_mm_deg, cut_rpm : array_like
        (n_cuts, 3) and (n_cuts,) the cuts' poses and speeds.
    tol : SamePointTolerance
        The tolerance.

    Returns
    -------
    numpy.ndarray
    """
    return (same_pose(poses_mm_deg, cut_poses_mm_deg, tol)[:, None, :]
            & _speed_match(spindle_rpm, cut_rpm, tol)[None, :, :])  # fmt: skip


def shared_local_row_p_stable(limits_m, depth_m, cut_limits_m, cut_depth_m, cut_chatter,
                              local_factor, label_noise: float) -> np.ndarray:  # fmt: skip
    """Each row's P(stable) at a point sharing the local factor of the cuts there (module docs).

    Parameters
    ----------
    limits_m : array_like
        (R,) the rows' limits [m] at the point, before the local factor (inf: no lobe).
    depth_m : array_like
        (N,) depths [m] at the point.
    cut_limits_m : array_like
        (R, m) the rows' limits [m] at the cuts' own poses and speeds.
    cut_depth_m, cut_chatter : array_like
        (m,) the cuts' depths [m] and results (bool).
    local_factor : (low, high)
        Range of the log-uniform local factor.
    label_noise : float
        The label-noise rate ``eps`` of the update (0 < eps < 0.5).

    Returns
    -------
    numpy.ndarray
        (R, N) probabilities.
    """
    lo, hi = (np.log(v) for v in _checked_local(local_factor))
    a = np.asarray(limits_m, float)
    d = np.atleast_1d(np.asarray(depth_m, float))
    ac = np.asarray(cut_limits_m, float)
    dc = np.asarray(cut_depth_m, float)
    y = np.asarray(cut_chatter, bool)
    if a.ndim != 1 or d.ndim != 1 or ac.shape != (a.size, dc.size) or y.shape != dc.shape:
        raise ValueError(
            f"shapes: limits (R,), depths (N,), cut limits (R, m), cut depths and results (m,); "
            f"got {a.shape}, {d.shape}, {ac.shape}, {dc.shape}, {y.shape}"
        )
    if not 0 < label_noise < 0.5:
        raise ValueError(f"label_noise must be in (0, 0.5), got {label_noise!r}")
    if np.any(np.isnan(ac)) or np.any(ac <= 0) or not np.all(np.isfinite(dc) & (dc > 0)):
        raise ValueError("cut limits must be positive (inf: no lobe), cut depths positive")
    if hi == lo or dc.size == 0:  # a fixed local factor: the labels cannot move it
        return row_p_stable(a[:, None], d[None, :], local_factor)
    row_p_stable(a[:, None], d[None, :], local_factor)  # the checks of limits and depths
    with np.errstate(divide="ignore"):
        t = np.clip(np.log(dc[None, :] / ac), lo, hi)  # (R, m); inf limit: never chatters
        s = np.log(d[None, :] / a[:, None])  # (R, N); -inf: d = 0 or no lobe
    r = a.size
    knots = np.sort(np.concatenate([np.full((r, 1), lo), t, np.full((r, 1), hi)], axis=1), axis=1)
    mid = 0.5 * (knots[:, :-1] + knots[:, 1:])  # (R, m + 1)
    below = mid[:, :, None] <= t[:, None, :]  # (R, m + 1, m): cut c chatters there
    eps = float(label_noise)
    p_chat = eps + (1 - 2 * eps) * below
    density = np.where(y[None, None, :], p_chat, 1 - p_chat).prod(axis=2)  # (R, m + 1)
    mass = density * np.diff(knots, axis=1)
    left = np.maximum(knots[:, None, :-1], s[:, :, None])  # (R, N, m + 1)
    above = np.clip(knots[:, None, 1:] - left, 0.0, None)
    return (density[:, None, :] * above).sum(axis=2) / mass.sum(axis=1)[:, None]


def shared_local_p_stable(limits_m, weights, depth_m, cut_limits_m, cut_depth_m, cut_chatter,
                          local_factor, label_noise: float) -> np.ndarray:  # fmt: skip
    """Weighted P(stable) at a point sharing the cuts' local factor, ``sum_r w_r P_r``.

    Parameters
    ----------
    limits_m, depth_m, cut_limits_m, cut_depth_m, cut_chatter, local_factor, label_noise
        As :func:`shared_local_row_p_stable`.
    weights : array_like
        (R,) the rows' weights.

    Returns
    -------
    numpy.ndarray
        (N,) probabilities.
    """
    w = np.asarray(weights, float)
    if np.any(~np.isfinite(w)) or np.any(w < 0) or w.sum() <= 0:
        raise ValueError("weights must be finite, >= 0 and not all zero")
    rows = shared_local_row_p_stable(limits_m, depth_m, cut_limits_m, cut_depth_m, cut_chatter,
                                     local_factor, label_noise)  # fmt: skip
    return (w / w.sum()) @ rows


def shared_local_quantile(limits_m, weights, q: float, cut_limits_m, cut_depth_m, cut_chatter,
                          local_factor, label_noise: float) -> float:  # fmt: skip
    """Depth [m] at which :func:`shared_local_p_stable` falls to ``1 - q`` (bisection in log d).

    Parameters
    ----------
    limits_m, weights, cut_limits_m, cut_depth_m, cut_chatter, local_factor, label_noise
        As :func:`shared_local_p_stable`.
    q : float
        Probability of chatter in [0, 1).

    Returns
    -------
    float
        Depth [m] (inf where the rows without a lobe weigh more than ``1 - q``).
    """
    if not 0 <= q < 1:
        raise ValueError(f"q must be in [0, 1), got {q!r}")
    lo, hi = _checked_local(local_factor)
    a = np.asarray(limits_m, float)
    finite = a[np.isfinite(a)]
    if finite.size == 0:
        return float("inf")

    def p(log_d):
        return float(shared_local_p_stable(a, weights, [np.exp(log_d)], cut_limits_m,
                                           cut_depth_m, cut_chatter, local_factor,
                                           label_noise)[0])  # fmt: skip

    # P(stable) is 1 below lo min(a) and the no-lobe rows' weight above hi max(a)
    t0, t1 = np.log(lo * finite.min()) - 1e-9, np.log(hi * finite.max()) + 1e-9
    if p(t1) > 1 - q:
        return float("inf")
    if p(t0) <= 1 - q:
        return float(np.exp(t0))
    for _ in range(60):
        tm = 0.5 * (t0 + t1)
        if p(tm) > 1 - q:
            t0 = tm
        else:
            t1 = tm
    return float(np.exp(0.5 * (t0 + t1)))
