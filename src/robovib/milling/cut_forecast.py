"""Test cuts move the forecast of a stability chart or map (issue 39: ``--cuts`` of ``mill lobes``
and ``mill map``).

The posterior is the one of :mod:`robovib.milling.cut_posterior` (the same functions, no second
one): the pose model's sampled structures (:func:`robovib.milling.structures.sample_structures`)
are weighted by each test cut's likelihood with a label-noise rate ``eps``::

    w_s' ∝ w_s prod_i P(y_i | s)

Here the structures' zero-order limits ``a_s(pose, n)`` are computed at the chart's pose (or
the map's poses) and speeds, and the forecast there is, before (uniform ``w``) and after
(``w'``) the cuts::

    P(stable | depth d) = sum_s w_s [a_s > d],   q-quantile: min { a : sum_s w_s [a_s <= a] > q }

(:func:`~robovib.milling.cut_posterior.p_stable`, :func:`~robovib.milling.cut_posterior.
weighted_quantile`). How far the cuts moved it is reported as the effective sample size, the
information gained, the shift of the median limit at the cuts and at the forecast's own poses.
Cuts from a file without pose columns are taken at the chart's pose.

With ``local_factor`` (the factor split of the re-plan, :mod:`robovib.milling.factor_grid`; the
default of ``mill lobes --cuts`` and ``mill map --cuts``, as of ``mill plan --cuts``) each
weighted row is a structure x common-factor pair and a local factor ``rho`` log-uniform on
``local_factor`` is drawn afresh at every point: P(stable) is the smooth per-row form
``sum_r w_r (1 - F(log(d / a_r)))`` (:func:`~robovib.milling.factor_grid.local_p_stable`) and
the quantiles its inverse (:func:`~robovib.milling.factor_grid.local_quantile`).
A point that coincides with test cuts (same pose and speed within
:class:`~robovib.milling.same_point.SamePointTolerance`) shares their local factor instead,
conditioned on their labels (:mod:`robovib.milling.same_point`): after a chattering cut there,
P(stable) at its depth falls to about the label-noise rate.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from .cut_posterior import CutUpdate, p_stable, update_with_cuts, weighted_quantile
from .factor_grid import local_p_stable, local_quantile
from .forces import CuttingCoefficients, CuttingConditions, MillingTool
from .same_point import (
    DEFAULT_SAME_POINT,
    SamePointTolerance,
    matching_cuts,
    same_pose,
    shared_local_p_stable,
    shared_local_quantile,
)
from .uncertainty import StabilityProbability

__all__ = [
    "CutForecast",
    "WeightedStabilityProbability",
    "add_cut_forecast",
    "cuts_at_pose",
    "forecast_with_cuts",
]


def cuts_at_pose(cuts, pose=None):
    """Test cuts with poses: a file without pose columns is taken at ``pose``.

    Parameters
    ----------
    cuts : MeasuredCuts
        The cuts (:func:`robovib.io.cuts.read_cuts_csv`).
    pose : (x_mm, y_mm, rz_deg), optional
        The chart's pose, for cuts without pose columns.

    Returns
    -------
    MeasuredCuts
        The cuts, each with a pose.

    Raises
    ------
    ValueError
        The cuts have no poses and no pose is given.
    """
    if cuts.pose_mm_deg is not None:
        return cuts
    if pose is None:
        raise ValueError(
            "the test cuts have no poses: give the columns x_mm, y_mm, rz_deg in the cuts file"
        )
    p = np.asarray(pose, float)
    if p.shape != (3,) or not np.all(np.isfinite(p)):
        raise ValueError(f"pose must be finite (x_mm, y_mm, rz_deg), got {pose!r}")
    return replace(cuts, pose_mm_deg=np.tile(p, (np.asarray(cuts.spindle_rpm).size, 1)))


@dataclass(frozen=True)
class CutForecast:
    """The structures' limits at poses and speeds, with prior and posterior weights.

    Attributes
    ----------
    poses_mm_deg
        (P, 3) poses of the forecast (x [mm], y [mm], Rz [deg]).
    spindle_rpm
        (J,) speeds [rpm].
    limits_m
        (S, P, J) zero-order limits [m] of the structures (inf: no lobe).
    update
        The posterior (:class:`~robovib.milling.cut_posterior.CutUpdate`).
    cuts
        The cuts used, each with its pose.
    cut_limits_m
        (S, n_cuts) the rows' limits [m] at the cuts' own poses and speeds (with the factor
        split), or None.
    same_point
        With the factor split: when a point is a cut's own point and shares its local factor
        (:mod:`robovib.milling.same_point`); None: every point draws it afresh.
    """

    poses_mm_deg: np.ndarray
    spindle_rpm: np.ndarray
    limits_m: np.ndarray = field(repr=False)
    update: CutUpdate = field(repr=False)
    cuts: object = field(repr=False)
    cut_limits_m: np.ndarray | None = field(default=None, repr=False)
    same_point: SamePointTolerance | None = None

    def _matches(self, posterior: bool = True) -> np.ndarray | None:
        """(P, J, n_cuts) bool: the cuts each point shares its local factor with (None: before
        the cuts, or no sharing)."""
        if (not posterior or self.same_point is None or self.local_factor is None
                or self.cut_limits_m is None):  # fmt: skip
            return None
        return matching_cuts(self.poses_mm_deg, self.spindle_rpm, self.cuts.pose_mm_deg,
                             self.cuts.spindle_rpm, self.same_point)  # fmt: skip

    def _cut_args(self, at) -> tuple:
        """The cuts' limits, depths and results of the cuts ``at`` (bool mask)."""
        return (self.cut_limits_m[:, at], np.asarray(self.cuts.depth_m, float)[at],
                np.asarray(self.cuts.chatter, bool)[at])  # fmt: skip

    def weights(self, posterior: bool = True) -> np.ndarray:
        """The structures' weights after or before the cuts.

        Parameters
        ----------
        posterior : bool
            After (True) or before the cuts.

        Returns
        -------
        numpy.ndarray
            (S,) normalised weights.
        """
        return self.update.structures.weights if posterior else self.update.prior_weights

    @property
    def local_factor(self) -> tuple[float, float] | None:
        """The local factor's range (the factor split), or None (one factor per row)."""
        return self.update.structures.local_factor

    def p_stable(self, depth_m, posterior: bool = True) -> np.ndarray:
        """Weighted P(stable) at the depth (module docs).

        Parameters
        ----------
        depth_m : float or array_like
            Depth [m], broadcast against (P, J).
        posterior : bool
            After (True) or before the cuts.

        Returns
        -------
        numpy.ndarray
            (P, J) probabilities.
        """
        w = self.weights(posterior)
        out = _p_stable(self.limits_m, w, depth_m, self.local_factor)
        match = self._matches(posterior)
        if match is None or not np.any(match):
            return out
        out = np.array(out, float)
        d = np.broadcast_to(np.asarray(depth_m, float), out.shape)
        eps = self.update.label_noise
        for p, j in zip(*np.nonzero(match.any(axis=2)), strict=True):
            at = match[p, j]
            dd = d[..., p, j]
            out[..., p, j] = shared_local_p_stable(
                self.limits_m[:, p, j], w, dd.ravel(), *self._cut_args(at), self.local_factor,
                eps).reshape(dd.shape)  # fmt: skip
        return out

    def quantile_m(self, q: float, posterior: bool = True) -> np.ndarray:
        """Weighted ``q``-quantile of the limit (module docs).

        Parameters
        ----------
        q : float
            Probability in [0, 1).
        posterior : bool
            After (True) or before the cuts.

        Returns
        -------
        numpy.ndarray
            (P, J) depths [m] (inf: no lobe).
        """
        w = self.weights(posterior)
        out = _quantile(self.limits_m, w, q, self.local_factor)
        match = self._matches(posterior)
        if match is None or not np.any(match):
            return out
        out = np.array(out, float)
        for p, j in zip(*np.nonzero(match.any(axis=2)), strict=True):
            out[p, j] = shared_local_quantile(self.limits_m[:, p, j], w, q,
                                              *self._cut_args(match[p, j]), self.local_factor,
                                              self.update.label_noise)  # fmt: skip
        return out

    def median_shift_rel(self) -> float:
        """How far the cuts moved the median limit at the forecast's poses and speeds.

        Returns
        -------
        float
            Median over poses and speeds of posterior / prior median limit - 1 (NaN: no
            finite limit).
        """
        a0, a1 = self.quantile_m(0.5, False), self.quantile_m(0.5, True)
        ok = np.isfinite(a0) & np.isfinite(a1) & (a0 > 0)
        return float(np.median(a1[ok] / a0[ok] - 1)) if np.any(ok) else float("nan")

    def to_dict(self) -> dict:
        """The update (:meth:`CutUpdate.to_dict`) and the shift at the forecast's poses.

        Returns
        -------
        dict
            Plain JSON types, units in the keys.
        """
        doc = self.update.to_dict()
        doc["effective_sample_size_prior"] = self.update.prior_effective_sample_size
        doc["median_limit_shift_rel_at_forecast"] = self.median_shift_rel()
        doc["cut_poses_mm_deg"] = np.asarray(self.cuts.pose_mm_deg, float).tolist()
        doc["limits"] = ("zero-order limits of the pose model's sampled structures "
                         "(robovib.milling.structures), process factor included")  # fmt: skip
        if self.local_factor is not None:  # the factor split (absent without it, as before)
            doc["local_factor_range"] = list(self.local_factor)
            doc["common_factor_range"] = self.update.structures.settings.get("process_factor_range")
        if self.same_point is not None and self.local_factor is not None:
            doc["same_point_tolerance"] = self.same_point.to_dict()
            doc["settings"]["same_point_tolerance"] = self.same_point.to_dict()
        return doc

    def stability_probability(
        self, mean_envelope, *, pose_index: int = 0, posterior: bool = True, n_depths: int = 120
    ) -> WeightedStabilityProbability:
        """The forecast at one pose as a chart's P(stable) (speeds × depths), weights kept.

        Parameters
        ----------
        mean_envelope : LobeEnvelope
            The envelope of the mean modes drawn with it (over the same speeds).
        pose_index : int
            Which of the forecast's poses.
        posterior : bool
            The weights after (True) or before the cuts.
        n_depths : int
            Depths of the grid, from 0 to 1.5 x the largest finite 95 % quantile.

        Returns
        -------
        WeightedStabilityProbability
        """
        lim = self.limits_m[:, pose_index, :]
        w = self.weights(posterior)
        loc = self.local_factor
        top = _quantile(lim, w, 0.95, loc)
        top = top[np.isfinite(top)]
        d_max = 1.5 * float(top.max()) if top.size else 0.02
        depth = np.linspace(0.0, d_max, int(n_depths))
        grid = _p_stable(lim[:, :, None], w, depth[None, :], loc)  # (J, D)
        shared = None
        match = self._matches(posterior)
        if match is not None:
            at = same_pose(self.poses_mm_deg[pose_index], self.cuts.pose_mm_deg,
                           self.same_point)[0]  # the cuts at this pose  # fmt: skip
            if np.any(at):
                shared = SharedCuts(np.asarray(self.cuts.spindle_rpm, float)[at],
                                    *self._cut_args(at), self.update.label_noise,
                                    self.same_point)  # fmt: skip
                for j in np.flatnonzero(match[pose_index].any(axis=1)):
                    grid[j] = shared.p_stable(lim[:, j], w, depth, self.spindle_rpm[j], loc)
        finite = np.where(np.isfinite(lim), lim, np.inf)
        return WeightedStabilityProbability(
            self.spindle_rpm, depth, grid, finite, finite.min(axis=1), mean_envelope,
            {"n_samples": self.update.structures.n_structures, "n_weighted_rows": int(w.size),
             "method": "zoa",
             "sampling": ("weighted structures of the pose model "
                          + ("after" if posterior else "before") + " the test cuts "
                          "(robovib.milling.cut_forecast)"),
             "effective_sample_size": self.update.structures.with_weights(w)
             .effective_sample_size,
             **({} if loc is None else {
                 "local_factor_range": list(loc),
                 "common_factor_range": self.update.structures.settings.get(
                     "process_factor_range")})},
            weights=w, local_factor=loc, shared_cuts=shared,
        )  # fmt: skip


def _p_stable(limits_m, weights, depth_m, local_factor) -> np.ndarray:
    """P(stable) of weighted rows: the step form, or the smooth one with a local factor."""
    if local_factor is None:
        return p_stable(limits_m, weights, depth_m)
    return local_p_stable(limits_m, weights, depth_m, local_factor)


def _quantile(limits_m, weights, q, local_factor) -> np.ndarray:
    """The ``q``-quantile of the limit of weighted rows (with a local factor: its inverse)."""
    if local_factor is None:
        return weighted_quantile(limits_m, weights, q)
    return local_quantile(limits_m, weights, q, local_factor)


@dataclass(frozen=True)
class SharedCuts:
    """Test cuts at a chart's pose, whose local factor the chart shares at their speeds.

    Attributes
    ----------
    spindle_rpm
        (m,) the cuts' speeds [rpm].
    limits_m
        (R, m) the rows' limits [m] at the cuts.
    depth_m, chatter
        (m,) the cuts' depths [m] and results.
    label_noise
        The update's label-noise rate.
    tolerance
        When a speed is a cut's (:class:`~robovib.milling.same_point.SamePointTolerance`).
    """

    spindle_rpm: np.ndarray
    limits_m: np.ndarray = field(repr=False)
    depth_m: np.ndarray
    chatter: np.ndarray
    label_noise: float
    tolerance: SamePointTolerance

    def at(self, spindle_rpm: float) -> np.ndarray:
        """(m,) bool: the cuts whose speed is ``spindle_rpm`` within the tolerance."""
        return np.abs(float(spindle_rpm) - self.spindle_rpm) <= (
            self.tolerance.speed_rel * self.spindle_rpm
        )

    def p_stable(self, limits_m, weights, depth_m, spindle_rpm, local_factor) -> np.ndarray:
        """P(stable) at the speed (the cuts there shared; none there: the fresh local factor).

        Parameters
        ----------
        limits_m : array_like
            (R,) the rows' limits [m] at the speed.
        weights : array_like
            (R,) weights.
        depth_m : array_like
            (N,) depths [m].
        spindle_rpm : float
            The speed [rpm].
        local_factor : (low, high)
            The local factor's range.

        Returns
        -------
        numpy.ndarray
            (N,) probabilities.
        """
        at = self.at(spindle_rpm)
        d = np.atleast_1d(np.asarray(depth_m, float))
        if not np.any(at):
            return local_p_stable(np.asarray(limits_m, float)[:, None], weights, d, local_factor)
        return shared_local_p_stable(limits_m, weights, d, self.limits_m[:, at], self.depth_m[at],
                                     self.chatter[at], local_factor, self.label_noise)  # fmt: skip

    def quantile_m(self, limits_m, weights, q, spindle_rpm, local_factor) -> float:
        """The ``q``-quantile of the limit at the speed (the inverse of :meth:`p_stable`)."""
        at = self.at(spindle_rpm)
        if not np.any(at):
            return float(local_quantile(limits_m, weights, q, local_factor))
        return shared_local_quantile(limits_m, weights, q, self.limits_m[:, at], self.depth_m[at],
                                     self.chatter[at], local_factor, self.label_noise)  # fmt: skip


@dataclass(frozen=True)
class WeightedStabilityProbability(StabilityProbability):
    """:class:`~robovib.milling.uncertainty.StabilityProbability` of weighted samples.

    Attributes
    ----------
    spindle_rpm, depth_m
        The grid [rpm], [m].
    p_stable
        (n_speeds, n_depths) weighted probability of a stable cut.
    a_lim_samples_m
        (n_samples, n_speeds) sampled envelopes [m].
    minimum_depth_samples_m
        (n_samples,) their minima [m].
    mean
        Envelope of the mean modes.
    settings
        Settings of the computation.
    weights
        (n_samples,) normalised weights of ``a_lim_samples_m``.
    local_factor
        Range of the local factor drawn afresh at every point (the factor split), or None:
        P(stable) and the quantiles are then the smooth per-row forms
        (:func:`~robovib.milling.factor_grid.local_p_stable`).
    shared_cuts
        Test cuts at the chart's pose whose local factor is shared at their speeds
        (:class:`SharedCuts`), or None.
    """

    weights: np.ndarray | None = None
    local_factor: tuple[float, float] | None = None
    shared_cuts: SharedCuts | None = None

    def p_unconditionally_stable(self, depth_m) -> np.ndarray:
        """Weighted probability that the depth is stable at every speed.

        With ``local_factor`` one local factor is drawn on each row's minimum over the speeds
        (the factor of the speed that limits it).

        Parameters
        ----------
        depth_m : array_like
            Depths [m].

        Returns
        -------
        numpy.ndarray
            Probabilities.
        """
        d = np.atleast_1d(np.asarray(depth_m, float))
        return _p_stable(self.minimum_depth_samples_m[:, None], self.weights, d, self.local_factor)

    def p_stable_at(self, spindle_rpm: float, depth_m: float) -> float:
        """Weighted probability that one cut is stable (speeds interpolated linearly).

        Parameters
        ----------
        spindle_rpm : float
            Speed [rpm], inside the chart's speed range.
        depth_m : float
            Axial depth [m].

        Returns
        -------
        float
            P(stable) in [0, 1].
        """
        rpm = np.asarray(self.spindle_rpm, float)
        s, d = float(spindle_rpm), float(depth_m)
        if not rpm.min() <= s <= rpm.max():
            raise ValueError(f"{s:g} rpm is outside the chart's {rpm.min():g}-{rpm.max():g} rpm")
        if not (np.isfinite(d) and d >= 0):
            raise ValueError(f"depth_m must be finite and >= 0, got {depth_m!r}")
        j = int(np.clip(np.searchsorted(rpm, s), 1, rpm.size - 1))
        f = (s - rpm[j - 1]) / (rpm[j] - rpm[j - 1])
        lo, hi = self.a_lim_samples_m[:, j - 1], self.a_lim_samples_m[:, j]
        with np.errstate(invalid="ignore"):
            a = np.where(np.isinf(lo) | np.isinf(hi), np.minimum(lo, hi), (1 - f) * lo + f * hi)
        if self.shared_cuts is not None and self.local_factor is not None:
            return float(self.shared_cuts.p_stable(a, self.weights, d, s, self.local_factor)[0])
        return float(_p_stable(a, self.weights, d, self.local_factor))

    def depth_quantile_m(self, q: float) -> np.ndarray:
        """Weighted ``q``-quantile of the limit at each speed.

        Parameters
        ----------
        q : float
            Probability of chatter allowed.

        Returns
        -------
        numpy.ndarray
            (n_speeds,) depths [m].
        """
        out = _quantile(self.a_lim_samples_m, self.weights, q, self.local_factor)
        sc = self.shared_cuts
        if sc is None or self.local_factor is None:
            return out
        out = np.array(out, float)
        for j, n in enumerate(self.spindle_rpm):
            if np.any(sc.at(n)):
                out[j] = sc.quantile_m(self.a_lim_samples_m[:, j], self.weights, q, n,
                                       self.local_factor)  # fmt: skip
        return out


def forecast_with_cuts(
    model,
    poses,
    spindle_rpm,
    cuts,
    tool: MillingTool,
    conditions: CuttingConditions,
    coefficients: CuttingCoefficients,
    *,
    feed_direction: str = "x",
    n_samples: int = 64,
    label_noise: float = 0.05,
    rng=0,
    structures=None,
    n_factors: int | None = 32,
    local_factor: tuple[float, float] | None = None,
    common_factor: tuple[float, float] = (0.9, 1.1),
    same_point: SamePointTolerance | None = DEFAULT_SAME_POINT,
) -> CutForecast:
    """Forecast at poses and speeds before and after test cuts (module docs).

    Parameters
    ----------
    model
        The pose model (inputs x_mm, y_mm, rz_deg); unused when ``structures`` is given.
    poses : array_like
        (P, 3) poses of the forecast.
    spindle_rpm : array_like
        (J,) speeds [rpm].
    cuts : MeasuredCuts
        Test cuts with poses (:func:`cuts_at_pose`).
    tool, conditions, coefficients
        Cutter, engagement and material of the cuts and the forecast.
    feed_direction : {"x", "y"}
        Base-frame feed direction.
    n_samples : int
        Structures drawn (:func:`~robovib.milling.structures.sample_structures`).
    label_noise : float
        Probability that a cut's label is wrong (0 < eps < 0.5).
    rng : int or numpy.random.Generator
        Seed of the structures.
    structures : StructureSamples, optional
        Structures to use instead of drawing them (the prior: their weights).
    n_factors : int or None
        Process factor integrated on this many grid points (:func:`~robovib.milling.
        cut_posterior.update_with_cuts`); None: one drawn factor per structure.
    local_factor : (low, high), optional
        The factor split (:func:`~robovib.milling.cut_posterior.update_with_cuts`): a local
        factor log-uniform on this range drawn afresh at every cut and forecast point, the cuts
        learning only the common factor; P(stable) and the quantiles are then smooth (module
        docs). None: one factor per row over the whole range.
    common_factor : (low, high)
        Range of the common factor with ``local_factor``.
    same_point : SamePointTolerance or None
        With ``local_factor``: a forecast point this close to test cuts shares their local
        factor (:mod:`robovib.milling.same_point`); None: drawn afresh there too.

    Returns
    -------
    CutForecast
    """
    x = np.atleast_2d(np.asarray(poses, float))
    if x.ndim != 2 or x.shape[1] != 3 or not np.all(np.isfinite(x)):
        raise ValueError(f"poses must be finite (n, 3) x_mm, y_mm, rz_deg; got {x.shape}")
    rpm = np.atleast_1d(np.asarray(spindle_rpm, float))
    if structures is None:
        from .structures import sample_structures

        structures = sample_structures(model, n_samples, rng=rng)
    update = update_with_cuts(structures, cuts, tool, conditions, coefficients,
                              feed_direction=feed_direction, label_noise=label_noise,
                              n_factors=n_factors, local_factor=local_factor,
                              common_factor=common_factor)  # fmt: skip
    # the rows of the update (on the factor grid: structure x factor pairs)
    lim = update.structures.limits(x, rpm, tool, conditions, coefficients,
                                   feed_direction=feed_direction)  # fmt: skip
    cut_lim = None
    if update.structures.local_factor is not None and same_point is not None:
        if not isinstance(same_point, SamePointTolerance):
            raise TypeError(f"same_point must be a SamePointTolerance or None, got {same_point!r}")
        c_pose = np.atleast_2d(np.asarray(cuts.pose_mm_deg, float))
        c_rpm = np.asarray(cuts.spindle_rpm, float)
        cut_lim = np.empty((update.structures.n_samples, c_rpm.size))
        for speed in np.unique(c_rpm):  # each cut at its own pose and speed
            at = np.flatnonzero(c_rpm == speed)
            cut_lim[:, at] = update.structures.limits(
                c_pose[at], [speed], tool, conditions, coefficients,
                feed_direction=feed_direction)[:, :, 0]  # fmt: skip
    else:
        same_point = None
    return CutForecast(x, rpm, np.asarray(lim, float), update, cuts, cut_lim, same_point)


def add_cut_forecast(
    ds,
    model,
    cuts,
    tool: MillingTool,
    conditions: CuttingConditions,
    coefficients: CuttingCoefficients,
    *,
    n_samples: int = 64,
    depth_m: float | None = None,
    label_noise: float = 0.05,
    rng=0,
    local_factor: tuple[float, float] | None = None,
    common_factor: tuple[float, float] = (0.9, 1.1),
):
    """A workspace map with the forecast after test cuts (``mill map --cuts``).

    Parameters
    ----------
    ds : xarray.Dataset
        Map of :func:`robovib.milling.maps.workspace_lobe_map` (its grid, speeds and feed
        direction are used).
    model
        The pose model of the map.
    cuts : MeasuredCuts
        Test cuts with poses.
    tool, conditions, coefficients
        Cutter, engagement and material of the map.
    n_samples : int
        Structures drawn.
    depth_m : float, optional
        Depth [m] whose P(stable) is mapped.
    label_noise : float
        Probability that a cut's label is wrong.
    rng : int
        Seed of the structures.
    local_factor, common_factor
        The factor split (:func:`forecast_with_cuts`); None: no split.

    Returns
    -------
    ds : xarray.Dataset
        A copy with ``a_lim_p05_m``, ``a_lim_p50_m``, ``a_lim_p95_m`` (and ``p_stable``) after
        the cuts, ``a_lim_p50_before_cuts_m`` (and ``p_stable_before_cuts``), and the
        attribute ``test_cuts`` (JSON of :meth:`CutForecast.to_dict`).
    forecast : CutForecast
    """
    import json

    if cuts.pose_mm_deg is None:
        raise ValueError("a map's test cuts need their poses: give the columns x_mm, y_mm, rz_deg")
    if depth_m is not None and not (np.isfinite(depth_m) and depth_m > 0):
        raise ValueError(f"depth_m must be a finite depth > 0 m, got {depth_m!r}")
    settings = json.loads(ds.attrs["settings"])
    xs, ys, rzs = (ds[k].values for k in ("x_mm", "y_mm", "rz_deg"))
    rpm = ds["spindle_rpm"].values
    grid = np.stack(np.meshgrid(xs, ys, rzs, indexing="ij"), axis=-1).reshape(-1, 3)
    fc = forecast_with_cuts(
        model, grid, rpm, cuts, tool, conditions, coefficients,
        feed_direction=settings["feed_direction"], n_samples=n_samples,
        label_noise=label_noise, rng=rng, local_factor=local_factor,
        common_factor=common_factor,
    )  # fmt: skip
    dims = ("x_mm", "y_mm", "rz_deg", "spindle_rpm")
    shape = (xs.size, ys.size, rzs.size, rpm.size)
    out = ds.copy()
    n = fc.update.structures.n_structures
    for q in (5, 50, 95):
        out[f"a_lim_p{q:02d}_m"] = (dims, fc.quantile_m(q / 100).reshape(shape), {
            "units": "m", "long_name": f"{q} % quantile of the critical depth over {n} sampled "
            "structures weighted by the test cuts"})  # fmt: skip
    out["a_lim_p50_before_cuts_m"] = (dims, fc.quantile_m(0.5, False).reshape(shape), {
        "units": "m", "long_name": "median critical depth before the test cuts"})  # fmt: skip
    if depth_m is not None:
        for name, post in (("p_stable", True), ("p_stable_before_cuts", False)):
            out[name] = (dims, fc.p_stable(depth_m, post).reshape(shape), {
                "units": "1", "depth_m": float(depth_m),
                "long_name": f"probability of a stable cut at {depth_m * 1e3:g} mm "
                + ("after" if post else "before") + " the test cuts"})  # fmt: skip
    settings.update(n_samples=int(n), seed=int(rng), label_noise=float(label_noise),
                    **({} if depth_m is None else {"depth_m": float(depth_m)}))  # fmt: skip
    if fc.local_factor is not None:
        settings.update(local_factor_range=list(fc.local_factor),
                        common_factor_range=list(common_factor))  # fmt: skip
        if fc.same_point is not None:
            settings["same_point_tolerance"] = fc.same_point.to_dict()
    out.attrs["settings"] = json.dumps(settings)
    out.attrs["test_cuts"] = json.dumps(fc.to_dict())
    return out, fc
