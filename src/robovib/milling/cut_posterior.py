"""Test cuts update the stability forecast: a posterior over sampled structures (issue 39).

The forecast is a set of structures (:func:`robovib.milling.structures.sample_structures`,
each a draw of the pose model over the whole workspace with a process factor) with weights.
A test cut ``i`` at pose, speed and depth ``d_i`` with the observed result ``y_i`` (chatter or
stable) has, under structure ``s`` whose limit there is ``a_si``, the likelihood::

    P(y_i = chatter | s) = 1 - eps   if d_i >= a_si,   eps   otherwise

with ``eps`` the **label-noise rate** (a mislabelled cut, a cut at the limit that went either
way). Bayes with the prior weights ``w_s`` gives the posterior weights (importance sampling)::

    w_s' ∝ w_s prod_i P(y_i | s)

and P(stable) anywhere is the weighted fraction of structures whose limit lies above the depth.
**The process factor on a grid** (default, ``n_factors=32``): a structure's limit scales
exactly with its process factor ``q``, so instead of one drawn ``q_s`` per structure (a few cuts
that mostly learn ``q`` then leave few structures with weight) every structure is ``K`` rows
``(s, q_k)`` on the stratified grid of :mod:`robovib.milling.factor_grid`, prior weight
``w_s / K``, and the same likelihood weights the pairs (the Rao-Blackwellised posterior; the
linear limits are still computed once per structure). How far the cuts moved the forecast is
reported as the effective sample size ``1 / sum w'^2``
(S before, smaller after: how many structures still carry it), the information gained (the
Kullback-Leibler divergence of the posterior from the prior weights, nats) and the shift of
the median limit at the cuts' own poses and speeds.

**The factor split** (``local_factor=``, what ``mill plan --cuts`` uses): the structures'
0.5-1.5 factor is replaced by a common factor (+-10 %, the cutting coefficients: learnt by a
cut anywhere) times a local factor (0.55-1.3, the time-domain / linear limit ratio, which
depends on where the pose and speed sit in their lobes) drawn afresh at every cut and forecast
point. A row's likelihood is then smooth, ``P(chatter | r) = eps + (1 - 2 eps) F(log(d_i /
a_ri))`` (:mod:`robovib.milling.factor_grid`), and one cut moves the forecast elsewhere only
through the common factor and the structures' fields: a cut near the limit that the detection
labels wrongly (the forecast rule picks cuts there) can no longer carry the whole workspace
deeper. (On the virtual robot, fresh seed 11 of ``benchmarks/study_plan.py``: one such cut took
the re-plan with one common factor over 0.5-1.5 from 96.7 to 88.3 % stable segments.)

**The most informative cuts** (:func:`choose_test_cuts`): among candidate poses and speeds (e.g.
the segments of a plan), each at the depth where P(stable) is nearest 0.5 (a cut whose outcome
is least predictable), cuts are chosen greedily to maximise the entropy of the
joint outcome over the structures: the expected information of the set, not of each cut alone
(two cuts that would split the structures the same way are worth one).

**Cuts for the forecast elsewhere** (:func:`choose_forecast_cuts`): the entropy of a cut's own
outcome says how much it reweights the structures, not whether that moves the forecast where
it will be used. There the cuts are chosen greedily to minimise the expected Brier score of the
forecast at a set of evaluation points ``e`` (poses, speeds and depths: e.g. the plan's
segments at depths across their predictive limit), the expectation taken over the outcomes the
model itself predicts, label noise included. Under the posterior ``W`` after observed outcomes
``h`` a forecast ``p_e = sum_r W_r [a_re > d_e]`` has the expected Brier score ``p_e (1 - p_e)``,
so a candidate cut ``c`` (at a few depths across its own predictive limit) is scored by::

    B(c) = sum_h sum_y P(h, y) sum_e p_e(h, y) (1 - p_e(h, y)) / E,
    P(h, y) p_e(h, y) = sum_r w_r L(h | r) L(y | r, c) [a_re > d_e]

over the ``2^n`` outcome histories ``h`` of the cuts chosen so far and the two outcomes ``y``
of ``c`` (``L`` the label-noise likelihood above); the cut of least ``B`` is added. A cut at a
pose whose structures' limits are correlated with many evaluation points (and with the
process factor, common to all of them) lowers ``B`` most; ``groups`` spreads the cuts.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .forces import CuttingCoefficients, CuttingConditions, MillingTool
from .structures import StructureSamples

__all__ = [
    "CutUpdate",
    "choose_forecast_cuts",
    "choose_test_cuts",
    "p_stable",
    "update_with_cuts",
    "weighted_quantile",
]


def p_stable(limits_m, weights, depth_m) -> np.ndarray:
    """Weighted probability that the limit lies above the depth.

    Parameters
    ----------
    limits_m : array_like
        (S, ...) limits [m] of the structures.
    weights : array_like
        (S,) weights (normalised).
    depth_m : array_like
        Depths [m], broadcast against ``limits_m[0]``.

    Returns
    -------
    numpy.ndarray
        P(stable), the shape of ``limits_m[0]`` broadcast with ``depth_m``.
    """
    lim = np.asarray(limits_m, float)
    w = np.asarray(weights, float)
    stable = lim > np.asarray(depth_m, float)[None]
    return np.tensordot(w, stable.astype(float), axes=(0, 0))


def weighted_quantile(limits_m, weights, q: float) -> np.ndarray:
    """Depth below which the weighted fraction ``q`` of the limits lies (lower quantile).

    The depth allowed at ``P(stable) >= 1 - q`` is ``weighted_quantile(limits, w, q)`` (a cut
    just below it is stable for a weight of at least ``1 - q``).

    Parameters
    ----------
    limits_m : array_like
        (S, ...) limits [m].
    weights : array_like
        (S,) weights.
    q : float
        Probability in [0, 1).

    Returns
    -------
    numpy.ndarray
        The shape of ``limits_m[0]``.
    """
    lim = np.asarray(limits_m, float)
    w = np.asarray(weights, float)
    if not 0 <= q < 1:
        raise ValueError(f"q must be in [0, 1), got {q!r}")
    order = np.argsort(lim, axis=0)
    srt = np.take_along_axis(lim, order, axis=0)
    cw = np.cumsum(w[order], axis=0)
    # first structure whose cumulative weight exceeds q: everything below it weighs <= q
    idx = np.argmax(cw > q + 1e-12, axis=0)
    return np.take_along_axis(srt, idx[None], axis=0)[0]


@dataclass(frozen=True)
class CutUpdate:
    """Structures updated with test cuts, and how much the cuts moved the forecast.

    Attributes
    ----------
    structures
        The structures with posterior weights.
    prior_weights
        (S,) the weights before.
    p_stable_prior, p_stable_posterior
        (n_cuts,) P(stable) of each cut before and after.
    median_limit_prior_m, median_limit_posterior_m
        (n_cuts,) weighted median limits [m] at the cuts' poses and speeds.
    label_noise
        The label-noise rate used.
    chatter
        (n_cuts,) the observed results.
    settings
        The likelihood and the feed direction used.
    """

    structures: StructureSamples
    prior_weights: np.ndarray
    p_stable_prior: np.ndarray
    p_stable_posterior: np.ndarray
    median_limit_prior_m: np.ndarray
    median_limit_posterior_m: np.ndarray
    label_noise: float
    chatter: np.ndarray
    settings: dict = field(default_factory=dict)

    @property
    def effective_sample_size(self) -> float:
        """Kish's effective sample size of the structures (:class:`StructureSamples`)."""
        return self.structures.effective_sample_size

    @property
    def prior_effective_sample_size(self) -> float:
        """The same before the cuts."""
        return self.structures.with_weights(self.prior_weights).effective_sample_size

    @property
    def information_nats(self) -> float:
        """Kullback-Leibler divergence of the posterior from the prior weights [nats]."""
        w, w0 = self.structures.weights, self.prior_weights
        keep = w > 0
        return float(np.sum(w[keep] * np.log(w[keep] / w0[keep])))

    def to_dict(self) -> dict:
        return {
            "n_cuts": int(self.chatter.size),
            "label_noise": self.label_noise,
            "n_structures": self.structures.n_samples,
            "effective_sample_size_prior": self.prior_effective_sample_size,
            "effective_sample_size": self.effective_sample_size,
            "information_nats": self.information_nats,
            "median_limit_shift_rel": float(
                np.median(self.median_limit_posterior_m / self.median_limit_prior_m - 1)
            ),
            "cuts": [
                {"chatter": bool(c), "p_stable_prior": float(a), "p_stable_posterior": float(b),
                 "median_limit_prior_m": float(m0), "median_limit_posterior_m": float(m1)}
                for c, a, b, m0, m1 in zip(
                    self.chatter, self.p_stable_prior, self.p_stable_posterior,
                    self.median_limit_prior_m, self.median_limit_posterior_m, strict=True)
            ],
            "settings": dict(self.settings),
        }  # fmt: skip


def _cut_arrays(cuts):
    pose = getattr(cuts, "pose_mm_deg", None)
    if pose is None:
        raise ValueError(
            "the test cuts have no poses: a cuts file for updating needs x_mm, y_mm, rz_deg"
        )
    pose = np.atleast_2d(np.asarray(pose, float))
    rpm = np.asarray(cuts.spindle_rpm, float)
    depth = np.asarray(cuts.depth_m, float)
    chatter = np.asarray(cuts.chatter, bool)
    if not (pose.shape[0] == rpm.size == depth.size == chatter.size):
        raise ValueError("the cuts' poses, speeds, depths and results differ in length")
    return pose, rpm, depth, chatter


def update_with_cuts(
    structures: StructureSamples,
    cuts,
    tool: MillingTool,
    conditions: CuttingConditions,
    coefficients: CuttingCoefficients,
    *,
    feed_direction: str = "x",
    label_noise: float = 0.05,
    n_factors: int | None = 32,
    local_factor: tuple[float, float] | None = None,
    common_factor: tuple[float, float] = (0.9, 1.1),
) -> CutUpdate:
    """Posterior weights of the structures given test cuts (module docs).

    Parameters
    ----------
    structures : StructureSamples
        The prior (or an earlier posterior).
    cuts : MeasuredCuts
        Test cuts with poses (:func:`robovib.io.cuts.read_cuts_csv` of a file with ``x_mm,
        y_mm, rz_deg``), speeds, depths and results.
    tool, conditions, coefficients
        The cutter, engagement (radial depth, up/down) and material of the cuts.
    feed_direction : {"x", "y"}
        Base-frame feed direction of the cuts.
    label_noise : float
        Probability that a cut's label disagrees with its structure's limit (0 < eps < 0.5).
    n_factors : int or None
        The process factor integrated on a grid of this many points (the structures are
        weighted as (structure, factor) pairs, :meth:`StructureSamples.on_factor_grid`;
        default 32). None: each structure keeps its own drawn factor (with ``local_factor``
        the common factor is still gridded, on 32 points). Structures already on a grid (an
        earlier posterior) are updated as they are.
    local_factor : (low, high), optional
        Split the process factor (:meth:`StructureSamples.on_factor_grid`): a common factor on
        ``common_factor``, learnt from the cuts, times a local one log-uniform on
        ``local_factor`` drawn afresh at every cut and forecast point, e.g. (0.55, 1.3), the
        time-domain / linear limit range of :mod:`robovib.milling.time_domain`. A cut then
        moves the forecast elsewhere only through the common factor and the structures, and
        its likelihood is smooth (:mod:`robovib.milling.factor_grid`). Structures that already
        carry a local factor (an earlier posterior) keep theirs. None: no split.
    common_factor : (low, high)
        Range of the common factor with ``local_factor`` (the cutting coefficients, +-10 %).

    Returns
    -------
    CutUpdate
        Its ``structures`` are on the factor grid (``n_structures * n_factors`` rows) unless
        ``n_factors`` is None; ``prior_weights`` are the weights of those rows before the cuts.
    """
    if not 0 < label_noise < 0.5:
        raise ValueError(f"label_noise must be in (0, 0.5), got {label_noise!r}")
    pose, rpm, depth, chatter = _cut_arrays(cuts)
    if local_factor is not None and structures.factor_grid is None:
        structures = structures.on_factor_grid(
            32 if n_factors is None else n_factors, process_factor=common_factor,
            local_factor=local_factor,
        )  # fmt: skip
    elif local_factor is not None and structures.local_factor is None:
        raise ValueError("these structures are on a factor grid without a local factor")
    if n_factors is not None and structures.factor_grid is None:
        structures = structures.on_factor_grid(n_factors)
    loc = structures.local_factor
    # one limit per cut: each at its own pose and speed (the diagonal of poses x speeds)
    lim = np.empty((structures.n_samples, rpm.size))
    for j, speed in enumerate(np.unique(rpm)):
        at = np.flatnonzero(rpm == speed)
        lim[:, at] = structures.limits(pose[at], [speed], tool, conditions, coefficients,
                                       feed_direction=feed_direction)[:, :, 0]  # fmt: skip
        del j
    w0 = structures.weights
    if loc is None:
        predicted_chatter = depth[None, :] >= lim
        agree = predicted_chatter == chatter[None, :]
        loglik = np.where(agree, np.log1p(-label_noise), np.log(label_noise)).sum(axis=1)

        def prob(weights):
            return p_stable(lim, weights, depth)

        def median(weights):
            return weighted_quantile(lim, weights, 0.5)
    else:
        from .factor_grid import local_p_stable, local_quantile, row_p_stable

        # P(chatter | row) = eps + (1 - 2 eps) P(local factor x limit <= depth)
        p_chat = label_noise + (1 - 2 * label_noise) * (1.0 - row_p_stable(lim, depth, loc))
        loglik = np.log(np.where(chatter[None, :], p_chat, 1 - p_chat)).sum(axis=1)

        def prob(weights):
            return local_p_stable(lim, weights, depth, loc)

        def median(weights):
            return local_quantile(lim, weights, 0.5, loc)

    logw = np.log(np.maximum(w0, 1e-300)) + loglik
    w = np.exp(logw - logw.max())
    post = structures.with_weights(w)
    settings = {
        "likelihood": "label noise eps: P(observed = predicted) = 1 - eps",
        "feed_direction": feed_direction,
        "process_factor": ("per structure, drawn" if structures.factor_grid is None else
                           f"integrated on a {structures.factor_grid.size}-point grid"),
    }  # fmt: skip
    if loc is not None:
        settings["process_factor"] += (
            f" (common factor {structures.settings.get('process_factor_range')}, learnt) x a "
            f"local factor log-uniform on {list(loc)} drawn afresh at every cut and point"
        )
        settings["local_factor_range"] = list(loc)
    return CutUpdate(
        post, w0, prob(w0), prob(post.weights), median(w0), median(post.weights),
        float(label_noise), chatter, settings,
    )  # fmt: skip


def choose_test_cuts(
    limits_m,
    weights,
    n_cuts: int = 5,
    *,
    groups=None,
    local_factor: tuple[float, float] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """The most informative test cuts among candidates (module docs).

    Parameters
    ----------
    limits_m : array_like
        (S, C) limits [m] of the structures at the C candidate poses and speeds.
    weights : array_like
        (S,) current weights.
    n_cuts : int
        Cuts to choose.
    groups : array_like, optional
        (C,) labels of the candidates (e.g. the pose's x, y or the plan's segment): at most one
        cut per label, to spread the cuts over the workspace. Default: no constraint.
    local_factor : (low, high), optional
        The rows' local factor (:attr:`StructureSamples.local_factor`, structures updated with
        the factor split): a row's outcome is then uncertain, ``P(chatter | r) = F(log(d /
        a_r))`` (:func:`~robovib.milling.factor_grid.row_p_stable`), each candidate is cut at
        the depth where P(chatter) is one half (:func:`~robovib.milling.factor_grid.
        local_quantile`), and the cuts maximise the mutual information of their joint outcome
        with the rows, ``H(y) - sum_r w_r H(y | r)`` (the entropy alone would favour cuts whose
        outcome is pure local noise). At most 10 cuts (the outcome histories double with each).

    Returns
    -------
    index : numpy.ndarray
        (n_cuts,) chosen candidates, in the order chosen.
    depth_m : numpy.ndarray
        (n_cuts,) their depths [m]: the structure limit there at which P(chatter) is nearest
        one half (with ``local_factor``: the depth of P(chatter) = 0.5).
    """
    lim = np.asarray(limits_m, float)
    w = np.asarray(weights, float)
    if lim.ndim != 2 or lim.shape[0] != w.size:
        raise ValueError(f"limits_m must be (S={w.size}, C), got {lim.shape}")
    n = int(n_cuts)
    if groups is not None:
        groups = np.asarray(groups)
        if groups.shape != (lim.shape[1],):
            raise ValueError(
                f"groups must be ({lim.shape[1]},) like the candidates, got {groups.shape}"
            )
    if not 1 <= n <= lim.shape[1]:
        raise ValueError(f"n_cuts must be in 1..{lim.shape[1]} candidates, got {n_cuts}")
    if local_factor is not None:
        return _choose_test_cuts_local(lim, w, n, groups, local_factor)
    # each candidate's depth: the structure limit at which the weight predicting chatter
    # (depth >= limit) is nearest one half
    p_chat = _weight_at_or_below(lim, w)
    k = np.argmin(np.where(np.isfinite(lim), np.abs(p_chat - 0.5), np.inf), axis=0)
    depth = lim[k, np.arange(lim.shape[1])]
    # a candidate without a finite limit (no lobe: stable at any depth) tells nothing
    finite = np.isfinite(depth)
    outcome = lim <= depth[None, :]  # chatter under each structure
    if n > 62:
        raise ValueError(f"at most 62 cuts are chosen at once, got {n_cuts}")
    code = np.zeros(w.size, dtype=np.int64)
    chosen: list[int] = []
    for _ in range(n):
        best, best_h = -1, -1.0
        for c in np.flatnonzero(finite):
            if c in chosen or (groups is not None and any(groups[c] == groups[i] for i in chosen)):
                continue
            h = _pattern_entropy(code * 2 + outcome[:, c].astype(int), w)
            if h > best_h + 1e-12:
                best, best_h = int(c), h
        if best < 0:
            raise ValueError("fewer informative candidates than n_cuts (no finite limits)")
        chosen.append(best)
        code = code * 2 + outcome[:, best].astype(int)
    idx = np.array(chosen)
    return idx, depth[idx]


def _weight_at_or_below(lim: np.ndarray, w: np.ndarray) -> np.ndarray:
    """(S, C) ``sum_s' w_s' [a_s'c <= a_sc]`` by one sort per column (memory S C, not S^2 C)."""
    order = np.argsort(lim, axis=0, kind="stable")
    a = np.take_along_axis(lim, order, axis=0)
    cw = np.cumsum(w[order], axis=0)
    # ties share the cumulative weight at the end of their run
    rows = np.arange(a.shape[0])[:, None]
    end = np.ones(a.shape, bool)
    end[:-1] = a[1:] != a[:-1]
    last = np.minimum.accumulate(np.where(end, rows, a.shape[0])[::-1], axis=0)[::-1]
    out = np.empty(lim.shape)
    np.put_along_axis(out, order, np.take_along_axis(cw, last, axis=0), axis=0)
    return out


def _choose_test_cuts_local(lim, w, n, groups, local_factor) -> tuple[np.ndarray, np.ndarray]:
    """:func:`choose_test_cuts` with a local factor: greedy mutual information (its docs)."""
    from .factor_grid import local_quantile, row_p_stable

    if np.any(~np.isfinite(w)) or np.any(w < 0) or w.sum() <= 0:
        raise ValueError("weights must be finite, >= 0 and not all zero")
    if n > 10:
        raise ValueError(f"at most 10 cuts are chosen at once with a local factor, got {n}")
    w = w / w.sum()
    depth = local_quantile(lim, w, 0.5, local_factor)  # (C,) P(chatter) = 1/2
    usable = np.isfinite(depth) & (depth > 0)
    p_chat = np.zeros(lim.shape)  # P(chatter | row) at each candidate's depth
    p_chat[:, usable] = 1.0 - row_p_stable(lim[:, usable], depth[usable], local_factor)

    def plogp(p):
        return np.where(p > 0, p * np.log(np.where(p > 0, p, 1.0)), 0.0)

    # H(y_c | r) of each candidate alone: the outcomes are independent given the row
    cond = -(w @ (plogp(p_chat) + plogp(1.0 - p_chat)))  # (C,)
    hist = np.ones((1, w.size))  # (H, R): P(outcome history | row)
    chosen: list[int] = []
    for _ in range(n):
        allowed = usable.copy()
        for i in chosen:
            allowed[i] = False
            if groups is not None:
                allowed &= groups != groups[i]
        if not allowed.any():
            raise ValueError("fewer informative candidates than n_cuts (no finite limits)")
        # H(history, y_c) - H(y_c | r): the terms common to every candidate dropped
        joint_c = (hist * w) @ p_chat  # (H, C) P(history, chatter at c)
        joint_s = (hist * w) @ (1.0 - p_chat)
        gain = -(plogp(joint_c) + plogp(joint_s)).sum(axis=0) - cond
        best = int(np.argmax(np.where(allowed, gain, -np.inf)))
        chosen.append(best)
        hist = np.concatenate([hist * p_chat[:, best], hist * (1.0 - p_chat[:, best])])
    idx = np.array(chosen)
    return idx, depth[idx]


def _pattern_entropy(code: np.ndarray, w: np.ndarray) -> float:
    _, inv = np.unique(code, return_inverse=True)
    p = np.bincount(inv, weights=w)
    p = p[p > 0]
    return float(-np.sum(p * np.log(p)))


def choose_forecast_cuts(
    limits_m,
    weights,
    eval_limits_m,
    eval_depth_m,
    n_cuts: int = 5,
    *,
    groups=None,
    label_noise: float = 0.1,
    depth_quantiles=(0.3, 0.5, 0.7),
    local_factor: tuple[float, float] | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Test cuts that most lower the expected Brier score of the forecast elsewhere (module docs).

    Parameters
    ----------
    limits_m : array_like
        (R, C) limits [m] of the weighted rows (structures, or structure x factor pairs of
        :meth:`~robovib.milling.structures.StructureSamples.on_factor_grid`) at the C candidate
        poses and speeds.
    weights : array_like
        (R,) their weights.
    eval_limits_m : array_like
        (R, E) the rows' limits [m] at the E evaluation points.
    eval_depth_m : array_like
        (E,) the evaluation depths [m].
    n_cuts : int
        Cuts to choose (1 to 10: the outcome histories double with each).
    groups : array_like, optional
        (C,) labels of the candidates: at most one cut per label.
    label_noise : float
        Probability that a cut's label is wrong, 0 < eps < 0.5.
    depth_quantiles : sequence of float
        Each candidate is tried at these quantiles of its weighted limit (in (0, 1)).
    local_factor : (low, high), optional
        The rows' local factor (:attr:`StructureSamples.local_factor`), drawn afresh at every
        cut and evaluation point: a row's chatter at a cut and its stability at an evaluation
        point are then probabilities (:func:`~robovib.milling.factor_grid.row_p_stable`), the
        depths quantiles of :func:`~robovib.milling.factor_grid.local_quantile`; the expected
        Brier score keeps its form ``p_e (1 - p_e)``, the outcomes at the cuts and the
        evaluation points being independent given the row.

    Returns
    -------
    index : numpy.ndarray
        (n_cuts,) chosen candidates, in the order chosen.
    depth_m : numpy.ndarray
        (n_cuts,) their depths [m].
    expected_brier : numpy.ndarray
        (n_cuts + 1,) the expected Brier score at the evaluation points before any cut and
        after each chosen one.
    """
    lim = np.asarray(limits_m, float)
    w = np.asarray(weights, float)
    ev = np.asarray(eval_limits_m, float)
    ed = np.asarray(eval_depth_m, float)
    if lim.ndim != 2 or lim.shape[0] != w.size:
        raise ValueError(f"limits_m must be (R={w.size}, C), got {lim.shape}")
    if ev.ndim != 2 or ev.shape[0] != w.size or ed.shape != (ev.shape[1],):
        raise ValueError(
            f"eval_limits_m must be (R={w.size}, E) and eval_depth_m (E,), got {ev.shape} and "
            f"{ed.shape}"
        )
    if np.any(~np.isfinite(w)) or np.any(w < 0) or w.sum() <= 0:
        raise ValueError("weights must be finite, >= 0 and not all zero")
    if np.any(np.isnan(lim)) or np.any(np.isnan(ev)) or not np.all(np.isfinite(ed)):
        raise ValueError("limits and evaluation depths must not contain NaN")
    if not 0 < label_noise < 0.5:
        raise ValueError(f"label_noise must be in (0, 0.5), got {label_noise!r}")
    qs = np.asarray(depth_quantiles, float)
    if qs.ndim != 1 or qs.size < 1 or np.any((qs <= 0) | (qs >= 1)):
        raise ValueError(f"depth_quantiles must be in (0, 1), got {depth_quantiles!r}")
    n = int(n_cuts)
    n_c = lim.shape[1]
    if not 1 <= n <= min(10, n_c):
        raise ValueError(f"n_cuts must be in 1..{min(10, n_c)}, got {n_cuts!r}")
    if groups is not None:
        groups = np.asarray(groups)
        if groups.shape != (n_c,):
            raise ValueError(f"groups must be ({n_c},) like the candidates, got {groups.shape}")
    w = w / w.sum()
    # every candidate at a few depths across its own predictive limit
    if local_factor is None:
        depth = np.stack([weighted_quantile(lim, w, q) for q in qs])  # (Q, C)
    else:
        from .factor_grid import local_quantile, row_p_stable

        depth = np.stack([local_quantile(lim, w, q, local_factor) for q in qs])
    cand = np.tile(np.arange(n_c), qs.size)
    depth = depth.ravel()
    ok = np.isfinite(depth) & (depth > 0)
    cand, depth = cand[ok], depth[ok]
    if local_factor is None:
        chat = (lim[:, cand] <= depth[None, :]).astype(float)  # (R, Q C) chatter under each row
        stable_ev = (ev > ed[None, :]).astype(float)  # (R, E)
    else:  # each row's probabilities, the local factor drawn afresh at every point
        chat = 1.0 - row_p_stable(lim[:, cand], depth, local_factor)
        stable_ev = row_p_stable(ev, ed, local_factor)
    like = {True: label_noise + (1 - 2 * label_noise) * chat,  # P(observed chatter | row)
            False: 1 - label_noise - (1 - 2 * label_noise) * chat}  # fmt: skip
    n_e = stable_ev.shape[1]
    hist = w[None, :]  # (H, R): prior x likelihood of each outcome history
    chosen: list[int] = []
    chosen_depth: list[float] = []

    def expected_brier(v):  # v (H, R) -> sum over histories of sum_e N (Z - N) / Z
        z = v.sum(axis=1)
        nn = v @ stable_ev
        with np.errstate(invalid="ignore", divide="ignore"):
            b = np.where(z[:, None] > 0, nn * (z[:, None] - nn) / z[:, None], 0.0)
        return float(b.sum()) / n_e

    scores = [expected_brier(hist)]
    for _ in range(n):
        total = np.zeros(cand.size)
        for v in hist:
            for y in (True, False):
                m = v[:, None] * like[y]  # (R, K)
                z = m.sum(axis=0)  # (K,)
                nn = m.T @ stable_ev  # (K, E)
                with np.errstate(invalid="ignore", divide="ignore"):
                    total += np.where(z > 0, (nn * (z[:, None] - nn)).sum(axis=1) / z, 0.0)
        total /= n_e
        allowed = np.ones(cand.size, bool)
        for i in chosen:
            allowed &= cand != i
            if groups is not None:
                allowed &= groups[cand] != groups[i]
        if not allowed.any():
            raise ValueError("fewer allowed candidates than n_cuts (groups or no finite limit)")
        k = int(np.argmin(np.where(allowed, total, np.inf)))
        chosen.append(int(cand[k]))
        chosen_depth.append(float(depth[k]))
        scores.append(float(total[k]))
        hist = np.concatenate([hist * like[True][:, k][None], hist * like[False][:, k][None]])
    return np.array(chosen), np.array(chosen_depth), np.array(scores)
