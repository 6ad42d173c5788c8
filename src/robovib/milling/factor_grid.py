"""Test cuts with the process factor integrated on a grid (Rao-Blackwellised posterior, issue 39).

Each sampled structure ``s`` (:func:`robovib.milling.structures.sample_structures`) has a
linear limit ``a_s`` at a pose and speed, and the limit used is ``q a_s`` with the process
factor ``q`` log-uniform on ``(low, high)``. :func:`robovib.milling.cut_posterior.update_with_cuts`
draws one ``q_s`` per structure, so a few cuts that mostly learn ``q`` leave few structures
with weight. Since the limit scales exactly with ``q``, the factor is integrated here on ``K``
stratified quantiles instead (the midpoints of ``K`` equally probable bins of the
log-uniform)::

    q_k = low (high / low)^((k + 1/2) / K),   k = 0 .. K-1,   prior weight 1 / (S K)

A test cut ``i`` at depth ``d_i`` with result ``y_i`` has under ``(s, k)`` the likelihood of
:mod:`robovib.milling.cut_posterior` (label-noise rate ``eps``)::

    P(y_i = chatter | s, k) = 1 - eps   if d_i >= q_k a_si,   eps   otherwise

    W_sk ∝ W0_sk prod_i P(y_i | s, k)

and P(stable) at depth ``d`` is ``sum_sk W_sk [q_k a_s > d]``. The linear limits are computed
once per structure (``StructureSamples.limits / process_factor``); the grid costs only the
products with the ``K`` factors. As ``K`` grows the prior P(stable) tends to the Monte-Carlo
average over independent factor draws (the stratified grid's error is at most ``1 / K`` per
structure).

**A local factor** (``local_factor=(lo_l, hi_l)``): part of what separates the linear limit
from the cut's is not common to the workspace. The time-domain limit of a full-depth entry
lies 5-45 % below the linear one, or up to 1.3x above with several modes per direction
(:func:`robovib.milling.time_domain.time_domain_limit_ratios`), depending on where the pose
and speed sit in their lobes: a cut at one speed says nothing about it at another. With a
local factor ``r`` log-uniform on ``(lo_l, hi_l)``, drawn afresh for every cut and every
forecast point, the limit is ``r q_k a_s`` and::

    P(stable at d | s, k) = P(r > d / (q_k a_s)) = 1 - F(log(d / (q_k a_s)))
    P(y_i = chatter | s, k) = eps + (1 - 2 eps) F(log(d_i / (q_k a_si)))

with ``F`` the (linear) CDF of ``log r`` on ``(log lo_l, log hi_l)``: the cuts learn only the
common ``q`` (e.g. the cutting coefficients, some +-10 %), and a chattering cut at a low speed
no longer drags the forecast at every other speed down with it.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = [
    "FactorGridPosterior",
    "factor_grid",
    "factor_grid_posterior",
    "local_p_stable",
    "local_quantile",
    "row_p_stable",
    "unscaled_limits",
]


def factor_grid(
    process_factor: tuple[float, float] = (0.5, 1.5), n_factors: int = 32
) -> np.ndarray:
    """Stratified quantiles of the log-uniform process factor (module docs).

    Parameters
    ----------
    process_factor : (low, high)
        Range of the log-uniform factor, ``0 < low <= high``.
    n_factors : int
        Grid points ``K >= 1`` (equally probable bins, one point at each bin's median).

    Returns
    -------
    numpy.ndarray
        (K,) factors, increasing.
    """
    lo, hi = (float(v) for v in process_factor)
    if not (np.isfinite(lo) and np.isfinite(hi) and 0 < lo <= hi):
        raise ValueError(f"process_factor must be 0 < low <= high, got {process_factor}")
    k = int(n_factors)
    if k < 1 or k != n_factors:
        raise ValueError(f"n_factors must be an integer >= 1, got {n_factors!r}")
    u = (np.arange(k) + 0.5) / k
    return np.exp(np.log(lo) + u * (np.log(hi) - np.log(lo)))


def unscaled_limits(structures, poses, spindle_rpm, tool, conditions, coefficients,
                    **kwargs) -> np.ndarray:  # fmt: skip
    """(S, P, J) linear limits [m] of the structures, without their own process factor.

    Parameters
    ----------
    structures : StructureSamples
        The structures.
    poses, spindle_rpm, tool, conditions, coefficients, **kwargs
        As :meth:`robovib.milling.structures.StructureSamples.limits`.

    Returns
    -------
    numpy.ndarray
        The limits divided by each structure's drawn factor.
    """
    lim = structures.limits(poses, spindle_rpm, tool, conditions, coefficients, **kwargs)
    return lim / np.asarray(structures.process_factor, float)[:, None, None]


@dataclass(frozen=True)
class FactorGridPosterior:
    """Weights over structures x process factors (module docs).

    Attributes
    ----------
    factors
        (K,) the factor grid.
    weights
        (S, K) normalised weights.
    prior_weights
        (S, K) the weights before the cuts.
    label_noise
        The label-noise rate used.
    settings
        How the grid and the likelihood were set.
    local_factor
        Range of the local factor drawn afresh at every cut and forecast point (None: none).
    """

    factors: np.ndarray
    weights: np.ndarray
    prior_weights: np.ndarray
    label_noise: float
    settings: dict = field(default_factory=dict)
    #: (lo_l, hi_l) of the local log-uniform factor (module docs), or None
    local_factor: tuple[float, float] | None = None

    @property
    def effective_sample_size(self) -> float:
        """Kish's effective sample size over (structure, factor) pairs, ``1 / sum W^2``."""
        return float(1.0 / np.sum(self.weights**2))

    @property
    def structure_effective_sample_size(self) -> float:
        """Kish's effective sample size of the structures' marginal weights ``sum_k W_sk``."""
        return float(1.0 / np.sum(self.weights.sum(axis=1) ** 2))

    @property
    def information_nats(self) -> float:
        """Kullback-Leibler divergence of the posterior from the prior weights [nats]."""
        w, w0 = self.weights, self.prior_weights
        keep = w > 0
        return float(np.sum(w[keep] * np.log(w[keep] / w0[keep])))

    def factor_posterior(self) -> np.ndarray:
        """The marginal posterior of the process factor on the grid, ``sum_s W_sk``.

        Returns
        -------
        numpy.ndarray
            (K,) probabilities of the grid points ``factors``.
        """
        return self.weights.sum(axis=0)

    def p_stable(self, unscaled_limits_m, depth_m) -> np.ndarray:
        """P(stable) = ``sum_sk W_sk [q_k a_s > d]`` (with a local factor ``sum_sk W_sk (1 -
        F(log(d / (q_k a_s))))``, module docs).

        Parameters
        ----------
        unscaled_limits_m : array_like
            (S, ...) linear limits [m] without a process factor (:func:`unscaled_limits`).
        depth_m : array_like
            Depths [m], broadcast against ``unscaled_limits_m[0]``.

        Returns
        -------
        numpy.ndarray
            The shape of ``unscaled_limits_m[0]`` broadcast with ``depth_m``.
        """
        lim = _checked_limits(unscaled_limits_m, self.weights.shape[0])
        d = np.asarray(depth_m, float)
        if np.any(np.isnan(d)):
            raise ValueError("depth_m contains NaN")
        # q_k a_s > d for every grid point, weighted (as cut_posterior.p_stable, per factor)
        out = 0.0
        for k, q in enumerate(self.factors):
            if self.local_factor is None:
                stable = (q * lim > d[None]).astype(float)
            else:
                stable = 1.0 - _local_cdf(d[None] / (q * lim), self.local_factor)
            out = out + np.tensordot(self.weights[:, k], stable, axes=(0, 0))
        out = np.asarray(out, float)
        return out


def _local_cdf(ratio, local_factor) -> np.ndarray:
    """P(r <= ratio) for r log-uniform on local_factor (0 for ratio 0, i.e. an infinite limit)."""
    lo, hi = np.log(local_factor[0]), np.log(local_factor[1])
    with np.errstate(divide="ignore"):
        t = np.log(np.asarray(ratio, float))
    if hi == lo:
        return (t >= lo).astype(float)
    return np.clip((t - lo) / (hi - lo), 0.0, 1.0)


def _checked_local(local_factor) -> tuple[float, float]:
    lo, hi = (float(v) for v in local_factor)
    if not (np.isfinite(lo) and np.isfinite(hi) and 0 < lo <= hi):
        raise ValueError(f"local_factor must be 0 < low <= high, got {local_factor}")
    return lo, hi


def local_p_stable(limits_m, weights, depth_m, local_factor) -> np.ndarray:
    """P(stable) with a local factor drawn afresh at the point (module docs).

    ``sum_r w_r (1 - F(log(d / a_r)))``: each weighted row ``r`` (a structure, or a
    structure x common-factor pair) has the limit ``a_r`` before the local factor, and the
    cut at depth ``d`` is stable when ``rho a_r > d`` with ``rho`` log-uniform on
    ``local_factor`` (``F`` the CDF of ``log rho``).

    Parameters
    ----------
    limits_m : array_like
        (R, ...) the rows' limits [m] (inf: no lobe, stable at any depth).
    weights : array_like
        (R,) weights (normalised).
    depth_m : array_like
        Depths [m], broadcast against ``limits_m[0]``.
    local_factor : (low, high)
        Range of the log-uniform local factor.

    Returns
    -------
    numpy.ndarray
        P(stable), the shape of ``limits_m[0]`` broadcast with ``depth_m``.
    """
    w = np.asarray(weights, float)
    lim = np.asarray(limits_m, float)
    if lim.ndim < 1 or lim.shape[0] != w.size:
        raise ValueError(f"limits_m must have {w.size} rows first, got {lim.shape}")
    if np.any(~np.isfinite(w)) or np.any(w < 0) or w.sum() <= 0:
        raise ValueError("weights must be finite, >= 0 and not all zero")
    return np.tensordot(w, row_p_stable(lim, depth_m, local_factor), axes=(0, 0))


def row_p_stable(limits_m, depth_m, local_factor) -> np.ndarray:
    """Each row's P(stable) with the local factor, ``1 - F(log(d / a_r))`` (module docs).

    Parameters
    ----------
    limits_m : array_like
        (R, ...) the rows' limits [m] (inf: no lobe).
    depth_m : array_like
        Depths [m], broadcast against ``limits_m[0]``.
    local_factor : (low, high)
        Range of the log-uniform local factor.

    Returns
    -------
    numpy.ndarray
        (R, ...) probabilities.
    """
    loc = _checked_local(local_factor)
    lim = np.asarray(limits_m, float)
    d = np.asarray(depth_m, float)
    if np.any(np.isnan(d)) or np.any(np.isnan(lim)):
        raise ValueError("limits and depths must not contain NaN")
    if np.any(lim <= 0):
        raise ValueError("limits must be positive (inf: no lobe)")
    if np.any(~np.isfinite(d)) or np.any(d < 0):
        raise ValueError("depths must be finite and >= 0")
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(np.isinf(lim), 0.0, d[None] / np.where(np.isinf(lim), 1.0, lim))
    return 1.0 - _local_cdf(ratio, loc)


def local_quantile(limits_m, weights, q: float, local_factor, *, chunk: int = 256) -> np.ndarray:
    """Depth at which P(stable) with the local factor falls to ``1 - q`` (the inverse of
    :func:`local_p_stable`).

    With ``t = log d`` the probability of chatter ``H(t) = sum_r w_r F(t - log a_r)`` is
    continuous and piecewise linear in ``t`` (``F`` rises linearly from ``log lo`` to
    ``log hi``), with knots at ``log a_r + log lo`` (slope ``+ w_r / (log hi - log lo)``) and
    ``log a_r + log hi`` (slope back down). The knots are sorted, ``H`` is accumulated over them
    and the root of ``H(t) = q`` is interpolated exactly in its interval (one sort per point;
    a ``lo == hi`` factor is the weighted quantile of ``lo a_r``).

    Parameters
    ----------
    limits_m : array_like
        (R, ...) the rows' limits [m] (inf: no lobe).
    weights : array_like
        (R,) weights (normalised, >= 0).
    q : float
        Probability of chatter in [0, 1).
    local_factor : (low, high)
        Range of the log-uniform local factor.
    chunk : int
        Points sorted at once (memory: ``2 R chunk`` values).

    Returns
    -------
    numpy.ndarray
        Depths [m], the shape of ``limits_m[0]`` (inf where the rows without a lobe weigh
        more than ``1 - q``).
    """
    lo, hi = _checked_local(local_factor)
    lim = np.asarray(limits_m, float)
    w = np.asarray(weights, float)
    if lim.ndim < 1 or lim.shape[0] != w.size:
        raise ValueError(f"limits_m must have {w.size} rows first, got {lim.shape}")
    if np.any(np.isnan(lim)) or np.any(lim <= 0):
        raise ValueError("limits must be positive (inf: no lobe), without NaN")
    if not 0 <= q < 1:
        raise ValueError(f"q must be in [0, 1), got {q!r}")
    if np.any(~np.isfinite(w)) or np.any(w < 0) or w.sum() <= 0:
        raise ValueError("weights must be finite, >= 0 and not all zero")
    if int(chunk) != chunk or chunk < 1:
        raise ValueError(f"chunk must be an integer >= 1, got {chunk!r}")
    chunk = int(chunk)
    w = w / w.sum()
    shape = lim.shape[1:]
    flat = lim.reshape(w.size, -1)
    out = np.empty(flat.shape[1])
    if hi == lo:  # one value: the weighted (lower) quantile of lo a_r
        order = np.argsort(flat, axis=0)
        cw = np.cumsum(w[order], axis=0)
        idx = np.argmax(cw > q + 1e-12, axis=0)
        return (lo * np.take_along_axis(flat, order, axis=0)[idx, np.arange(idx.size)]).reshape(
            shape
        )
    width = np.log(hi) - np.log(lo)
    # a row without a lobe: its knots far beyond any depth (its weight stays "stable")
    big = 1e6
    keep = w > 0
    w, flat = w[keep], flat[keep]
    inc = np.concatenate([w, -w]) / width
    for c0 in range(0, flat.shape[1], chunk):
        u = np.log(np.minimum(flat[:, c0 : c0 + chunk], big))  # (R, c)
        knots = np.concatenate([u + np.log(lo), u + np.log(hi)])  # (2R, c)
        order = np.argsort(knots, axis=0, kind="stable")
        k = np.take_along_axis(knots, order, axis=0)
        slope = np.cumsum(inc[order], axis=0)  # H's slope right of each knot
        h = np.concatenate([np.zeros((1, k.shape[1])),
                            np.cumsum(slope[:-1] * np.diff(k, axis=0), axis=0)])  # fmt: skip
        j = np.argmax(h > q, axis=0)  # first knot past the root (h[-1] = 1 > q)
        j = np.where(h[j, np.arange(j.size)] > q, j, k.shape[0] - 1)
        a = np.arange(j.size)
        s = np.maximum(slope[j - 1, a], 1e-300)
        t = k[j - 1, a] + (q - h[j - 1, a]) / s
        t = np.minimum(t, k[j, a])
        d = np.exp(t)
        out[c0 : c0 + chunk] = np.where(d >= big * lo * (1 - 1e-9), np.inf, d)
    return out.reshape(shape)


def _checked_limits(limits_m, n_structures: int) -> np.ndarray:
    lim = np.asarray(limits_m, float)
    if lim.ndim < 1 or lim.shape[0] != n_structures:
        raise ValueError(f"limits must have {n_structures} structures first, got {lim.shape}")
    if np.any(np.isnan(lim)) or np.any(lim <= 0):
        raise ValueError("limits must be positive (inf: no lobe), without NaN")
    return lim


def factor_grid_posterior(
    unscaled_limits_m,
    depth_m,
    chatter,
    *,
    process_factor: tuple[float, float] = (0.5, 1.5),
    n_factors: int = 32,
    label_noise: float = 0.05,
    prior_weights=None,
    local_factor: tuple[float, float] | None = None,
) -> FactorGridPosterior:
    """Posterior over structures x factor grid given test cuts (module docs).

    Parameters
    ----------
    unscaled_limits_m : array_like
        (S, n_cuts) linear limits [m] of each structure at each cut's pose and speed, without
        a process factor (:func:`unscaled_limits`; inf: no lobe).
    depth_m : array_like
        (n_cuts,) the cuts' depths [m].
    chatter : array_like
        (n_cuts,) bool, the observed results.
    process_factor : (low, high)
        Range of the log-uniform factor (as the structures were drawn with).
    n_factors : int
        Grid points ``K``.
    label_noise : float
        Probability that a cut's label disagrees with the limit (0 < eps < 0.5).
    prior_weights : array_like, optional
        (S,) structure weights before the cuts (default uniform).
    local_factor : (low, high), optional
        Range of a log-uniform factor drawn afresh at every cut and forecast point (module
        docs); None: the limit is ``q_k a_s`` exactly.

    Returns
    -------
    FactorGridPosterior
    """
    if not 0 < label_noise < 0.5:
        raise ValueError(f"label_noise must be in (0, 0.5), got {label_noise!r}")
    q = factor_grid(process_factor, n_factors)
    lim = np.asarray(unscaled_limits_m, float)
    if lim.ndim != 2:
        raise ValueError(f"unscaled_limits_m must be (S, n_cuts), got shape {lim.shape}")
    lim = _checked_limits(lim, lim.shape[0])
    d = np.asarray(depth_m, float)
    y = np.asarray(chatter)
    if d.shape != (lim.shape[1],) or y.shape != (lim.shape[1],):
        raise ValueError(
            f"depth_m and chatter must be ({lim.shape[1]},) like the limits' cuts; got "
            f"{d.shape} and {y.shape}"
        )
    if not np.all(np.isfinite(d) & (d > 0)):
        raise ValueError("depth_m must be positive and finite")
    if y.dtype != bool:
        raise ValueError(f"chatter must be bool, got dtype {y.dtype}")
    s = lim.shape[0]
    w0s = np.full(s, 1.0 / s) if prior_weights is None else np.asarray(prior_weights, float)
    if w0s.shape != (s,) or np.any(~np.isfinite(w0s)) or np.any(w0s < 0) or w0s.sum() <= 0:
        raise ValueError(f"prior_weights must be ({s},) finite, >= 0, not all zero")
    w0 = np.outer(w0s / w0s.sum(), np.full(q.size, 1.0 / q.size))
    if local_factor is None:
        predicted = d[None, None, :] >= q[None, :, None] * lim[:, None, :]  # (S, K, n_cuts)
        agree = predicted == y[None, None, :]
        loglik = np.where(agree, np.log1p(-label_noise), np.log(label_noise)).sum(axis=2)
    else:
        lo_l, hi_l = (float(v) for v in local_factor)
        if not (np.isfinite(lo_l) and np.isfinite(hi_l) and 0 < lo_l <= hi_l):
            raise ValueError(f"local_factor must be 0 < low <= high, got {local_factor}")
        local_factor = (lo_l, hi_l)
        p_chat = label_noise + (1 - 2 * label_noise) * _local_cdf(
            d[None, None, :] / (q[None, :, None] * lim[:, None, :]), local_factor
        )  # (S, K, n_cuts)
        loglik = np.log(np.where(y[None, None, :], p_chat, 1 - p_chat)).sum(axis=2)
    with np.errstate(divide="ignore"):
        logw = np.log(w0) + loglik
    w = np.exp(logw - logw.max())
    return FactorGridPosterior(
        q, w / w.sum(), w0, float(label_noise),
        {"process_factor_range": [float(process_factor[0]), float(process_factor[1])],
         "n_factors": int(q.size),
         "grid": "stratified quantiles of the log-uniform (bin medians)",
         "likelihood": "label noise eps: P(observed = predicted) = 1 - eps",
         "local_factor_range": None if local_factor is None else list(local_factor)},
        local_factor,
    )  # fmt: skip
