"""How sure is a lobe? Probability of a stable cut from the pose model's predictive distribution.

The pose model predicts, per direction, the dominant mode's natural frequency, stiffness and
damping coefficient with a calibrated predictive distribution of the *latent* modal parameters
(:meth:`robovib.gp.PoseModalModel.predictive`: Student-t bands calibrated by grouped CV, and
where a mode switch is modelled the mixture of both modes, the mode drawn once per direction so
that fn, k and c of a draw belong to one mode). Samples are drawn from it (draws with
fn, k, c <= 0 or zeta >= 1 are redrawn), a stability envelope is computed for every sample
(semi-discretization or zero-order method) and at each (speed, depth) the probability of a
stable cut is the fraction of samples whose envelope lies above that depth. A
:class:`ModeDistribution` given by hand (mean and std) is sampled as independent normals.

**Every mode** (issue 29): a direction may carry a list of :class:`ModeDistribution` — e.g.
:func:`mode_distributions_at_pose` of a multi-mode pose model
(:func:`robovib.campaign.fit_multimode_pose_model`, directions ``x1, x2, ..., y1, ...``). A
sample then holds one draw of every mode; when all modes carry joint draws of one predictive
distribution the same draw row is used for all of them (their correlations are kept); a mode
seen at only a fraction of the campaign's recordings is kept in a sample with that probability
(``presence``). The lobes of a sample are those of all its modes (SDM / ZOA on the multi-mode
structure). The chapter-3 default stays one (dominant) mode per direction.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from ..modal.parameters import ModalParameters
from .forces import CuttingCoefficients, CuttingConditions, MillingTool
from .lobes import LobeEnvelope, zoa_envelope
from .sdm import sdm_lobes
from .stability import stability_lobes

__all__ = [
    "ModeDistribution",
    "StabilityProbability",
    "mode_distribution_at_pose",
    "mode_distributions_at_pose",
    "plot_stability_probability",
    "stability_probability",
]


@dataclass(frozen=True)
class ModeDistribution:
    """Normal predictive distribution of one direction's dominant mode (SI units).

    Attributes
    ----------
    fn_hz, stiffness_n_per_m, damping_ns_per_m
        Means of fn [Hz], k [N/m], c [N·s/m].
    fn_std_hz, stiffness_std_n_per_m, damping_std_ns_per_m
        Their standard deviations.
    draws
        Optional (m, 3) joint draws of (fn, k, c) used instead of the normal.
    presence
        Probability that the mode is there at all (fraction of recordings where it was seen).
    name
        Name of the mode (e.g. ``"x2"``), for reports.
    """

    fn_hz: float
    stiffness_n_per_m: float
    damping_ns_per_m: float
    fn_std_hz: float = 0.0
    stiffness_std_n_per_m: float = 0.0
    damping_std_ns_per_m: float = 0.0
    #: Optional (m, 3) joint draws of (fn_hz, stiffness_n_per_m, damping_ns_per_m) from a pose
    #: model's calibrated predictive distribution; sampled instead of the normals when given.
    draws: np.ndarray | None = field(default=None, compare=False, repr=False)
    #: Probability that the mode is there at all (fraction of recordings where it was seen).
    presence: float = 1.0
    #: Name of the mode (e.g. ``"x2"``), for reports.
    name: str = ""

    def __post_init__(self) -> None:
        if not (np.isfinite(self.presence) and 0 < self.presence <= 1):
            raise ValueError(f"presence must be in (0, 1], got {self.presence!r}")
        for name in ("fn_std_hz", "stiffness_std_n_per_m", "damping_std_ns_per_m"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v >= 0):
                raise ValueError(f"{name} must be finite and >= 0, got {v!r}")

    @property
    def mean(self) -> ModalParameters:
        return ModalParameters.from_fn_k_c(
            self.fn_hz, self.stiffness_n_per_m, self.damping_ns_per_m
        )

    def sample(self, n: int, rng) -> list[ModalParameters]:
        """``n`` physical draws (rejection of fn, k, c <= 0 and zeta >= 1).

        Parameters
        ----------
        n : int
            Number of draws.
        rng : int or numpy.random.Generator
            Seed.

        Returns
        -------
        list of ModalParameters
            The draws.
        """
        gen = np.random.default_rng(rng)
        mu = np.array([self.fn_hz, self.stiffness_n_per_m, self.damping_ns_per_m])
        sd = np.array([self.fn_std_hz, self.stiffness_std_n_per_m, self.damping_std_ns_per_m])
        out: list[ModalParameters] = []
        tries = 0
        order = None if self.draws is None else gen.permutation(len(self.draws))
        while len(out) < n:
            tries += 1
            if tries > 50 * n + 100 or (order is not None and tries > len(order)):
                raise ValueError(
                    "the predictive distribution is mostly non-physical (fn, k, c <= 0)"
                )
            s = gen.normal(mu, sd) if order is None else self.draws[order[tries - 1]]
            if np.any(s <= 0):
                continue
            m = ModalParameters.from_fn_k_c(*s)
            if m.damping_ratio < 1:
                out.append(m)
        return out


def mode_distribution_at_pose(
    model, pose, *, n_draws: int = 4000, rng=0
) -> dict[str, ModeDistribution]:
    """Predictive distribution per direction at one pose from a pose model.

    Parameters
    ----------
    model
        A fitted :class:`robovib.gp.PoseModalModel` (``modes(X)`` with ``PoseMode`` std fields,
        SI). Models without ``modes`` are refused: their output units cannot be told apart
        (a thesis-unit and an SI regressor both have 9 outputs).
    pose
        One input row in the units of ``model.input_names``.
    n_draws
        Joint draws kept from the model's calibrated latent predictive distribution
        (``model.predictive``: Student-t bands, mode mixture); 0: normals from the std fields.
    rng
        Seed of those draws.

    Returns
    -------
    dict direction -> ModeDistribution
        Mean of the more probable mode, its calibrated latent std and the joint draws.

    Raises
    ------
    TypeError
        The model has no ``modes``/``output_names_`` (not a pose model).
    ValueError
        More than one pose.
    """
    x = np.atleast_2d(np.asarray(pose, float))
    if x.shape[0] != 1:
        raise ValueError(f"one pose expected, got {x.shape[0]}")
    if hasattr(model, "modes") and hasattr(model, "output_names_"):
        row = model.modes(x)[0]
        draws = None
        if n_draws and hasattr(model, "predictive"):
            draws = model.predictive(x).sample(int(n_draws), rng, kind="latent")[:, 0, :]
        out = {}
        for i, (d, pm) in enumerate(row.items()):
            p = pm.parameters
            out[d] = ModeDistribution(
                p.natural_frequency_hz, p.stiffness_n_per_m, p.damping_ns_per_m,
                float(pm.fn_std_hz), float(pm.stiffness_std_n_per_m),
                float(pm.damping_std_ns_per_m),
                draws=None if draws is None else draws[:, 3 * i : 3 * i + 3],
            )  # fmt: skip
        return out
    raise TypeError(
        f"{type(model).__name__} is not a pose model: mode_distribution_at_pose needs "
        "modes(X) in SI (a robovib.gp.PoseModalModel); output units are never guessed"
    )


def mode_distributions_at_pose(
    model, pose, *, n_draws: int = 4000, rng=0
) -> dict[str, list[ModeDistribution]]:
    """Every modelled mode per physical direction at one pose (multi-mode pose model).

    Parameters
    ----------
    model
        A fitted :class:`robovib.gp.PoseModalModel` whose directions are mode ids (``x1``,
        ``x2``, ``y1``: :func:`robovib.campaign.fit_multimode_pose_model`); a dominant-mode
        model (directions ``x``, ``y``, ``z``) gives one mode per direction.
    pose, n_draws, rng
        As for :func:`mode_distribution_at_pose` (the draws of all modes are joint).

    Returns
    -------
    dict direction -> list of ModeDistribution
        Sorted by mode id; ``presence`` from the model's provenance ``mode_presence``
        (1 where it does not say).
    """
    import json

    per_id = mode_distribution_at_pose(model, pose, n_draws=n_draws, rng=rng)
    prov = getattr(model, "provenance_", None) or {}
    presence = json.loads(prov["mode_presence"]) if "mode_presence" in prov else {}
    out: dict[str, list[ModeDistribution]] = {}
    for k, dist in per_id.items():
        d = k.rstrip("0123456789") or k  # "x2" -> "x"; "x" stays
        frac = float(presence.get(k, {}).get("presence", 1.0))
        out.setdefault(d, []).append(replace(dist, presence=frac, name=k))
    return out


def _as_list(dist) -> list[ModeDistribution]:
    return [dist] if isinstance(dist, ModeDistribution) else list(dist)


def _kept(params: list, keep: np.ndarray, modes: list[ModeDistribution]) -> list:
    """The kept modes of one direction; never none (then the most often seen one stays)."""
    out = [p for p, k in zip(params, keep, strict=True) if k]
    return out or [params[int(np.argmax([m.presence for m in modes]))]]


def _sample_all(feed: list[ModeDistribution], norm: list[ModeDistribution], n: int, gen):
    """``n`` samples of every mode of both directions (joint draw rows where all have them)."""
    modes = feed + norm
    joint = all(m.draws is not None for m in modes) and len({len(m.draws) for m in modes}) == 1
    if joint:
        out = []
        for r in gen.permutation(len(modes[0].draws)):
            s = [m.draws[r] for m in modes]
            if any(np.any(v <= 0) for v in s):
                continue
            ps = [ModalParameters.from_fn_k_c(*v) for v in s]
            if all(p.damping_ratio < 1 for p in ps):
                out.append(ps)
            if len(out) == n:
                break
        if len(out) < n:
            raise ValueError("the predictive distribution is mostly non-physical (fn, k, c <= 0)")
    else:
        cols = [m.sample(n, gen) for m in modes]
        out = [list(v) for v in zip(*cols, strict=True)]
    keep = np.column_stack([gen.uniform(size=n) < m.presence for m in modes])
    nf = len(feed)
    feed_s = [_kept(s[:nf], k[:nf], feed) for s, k in zip(out, keep, strict=True)]
    norm_s = [_kept(s[nf:], k[nf:], norm) for s, k in zip(out, keep, strict=True)]
    return feed_s, norm_s


@dataclass(frozen=True)
class StabilityProbability:
    """``p_stable`` (n_speeds, n_depths) over ``spindle_rpm`` [rpm] × ``depth_m`` [m].

    ``a_lim_samples_m`` (n_samples, n_speeds) the sampled envelopes, ``minimum_depth_samples_m``
    (n_samples,) their minima, ``mean`` the envelope of the mean modes.

    Attributes
    ----------
    spindle_rpm, depth_m
        The grid [rpm], [m].
    p_stable
        (n_speeds, n_depths) probability of a stable cut.
    a_lim_samples_m
        (n_samples, n_speeds) sampled envelopes [m].
    minimum_depth_samples_m
        (n_samples,) their minima [m].
    mean
        Envelope of the mean modes.
    settings
        Settings of the computation.
    """

    spindle_rpm: np.ndarray
    depth_m: np.ndarray
    p_stable: np.ndarray
    a_lim_samples_m: np.ndarray
    minimum_depth_samples_m: np.ndarray
    mean: LobeEnvelope
    settings: dict = field(default_factory=dict)

    def p_unconditionally_stable(self, depth_m) -> np.ndarray:
        """Probability that the depth [m] is stable at every speed (below every sample's minimum).

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
        return np.mean(self.minimum_depth_samples_m[:, None] > d[None, :], axis=0)

    def p_stable_at(self, spindle_rpm: float, depth_m: float) -> float:
        """Probability that one cut (speed [rpm], depth [m]) is stable.

        The fraction of samples whose envelope, interpolated linearly between the chart's
        speeds, lies above the depth.

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

        Raises
        ------
        ValueError
            The speed lies outside the chart's range, or the depth is negative or not finite.
        """
        rpm = np.asarray(self.spindle_rpm, float)
        s, d = float(spindle_rpm), float(depth_m)
        if not rpm.min() <= s <= rpm.max():
            raise ValueError(f"{s:g} rpm is outside the chart's {rpm.min():g}-{rpm.max():g} rpm")
        if not (np.isfinite(d) and d >= 0):
            raise ValueError(f"depth_m must be finite and >= 0, got {depth_m!r}")
        j = int(np.clip(np.searchsorted(rpm, s), 1, rpm.size - 1))
        w = (s - rpm[j - 1]) / (rpm[j] - rpm[j - 1])
        lo, hi = self.a_lim_samples_m[:, j - 1], self.a_lim_samples_m[:, j]
        with np.errstate(invalid="ignore"):
            a = np.where(np.isinf(lo) | np.isinf(hi), np.minimum(lo, hi), (1 - w) * lo + w * hi)
        return float(np.mean(a > d))

    def depth_quantile_m(self, q: float) -> np.ndarray:
        """Depth [m] at each speed that is stable with probability ``1 - q`` (e.g. q = 0.05).

        Parameters
        ----------
        q : float
            Probability of chatter allowed.

        Returns
        -------
        numpy.ndarray
            (n_speeds,) depths [m].
        """
        return np.quantile(self.a_lim_samples_m, q, axis=0, method="nearest")  # inf-safe


def _envelope(mx, my, tool, cond, coef, rpm, method, solver="numpy", **kw):
    if method == "sdm" and solver == "compiled":
        from .sdm_kernel import sdm_envelopes

        env = sdm_envelopes([(mx, my)], tool, cond, coef, rpm, **kw)[0]
        return env, env.minimum_depth_m
    if method == "sdm":
        env = sdm_lobes(mx, my, tool, cond, coef, rpm, **kw)
        return env, env.minimum_depth_m
    if method == "zoa":
        lobes = stability_lobes(mx, my, tool, cond, coef, n_lobes=kw.get("n_lobes", 20))
        return zoa_envelope(lobes, rpm), lobes.minimum_depth_m
    raise ValueError(f"method must be 'sdm' or 'zoa', got {method!r}")


def _mode_arrays(feed_s, norm_s, mean_f, mean_n):
    """(n, M) fn [Hz], k [N/m], zeta of every sample, the in-feed mask (M,) and the means.

    Samples that dropped a mode (``presence``) keep a placeholder with a vanishing compliance.
    """
    nf = max(len(s) for s in feed_s)
    nn = max(len(s) for s in norm_s)
    n = len(feed_s)
    m = nf + nn
    fn, k, z = np.empty((n, m)), np.full((n, m), 1e300), np.full((n, m), 0.05)
    means = list(mean_f) + [mean_f[0]] * (nf - len(mean_f)) + list(mean_n)
    means += [mean_n[0]] * (m - len(means))
    fn[:] = [p.natural_frequency_hz for p in means]
    for i, (sf, sn) in enumerate(zip(feed_s, norm_s, strict=True)):
        for j, p in list(enumerate(sf)) + [(nf + j, p) for j, p in enumerate(sn)]:
            fn[i, j], k[i, j], z[i, j] = (
                p.natural_frequency_hz,
                p.stiffness_n_per_m,
                p.damping_ratio,
            )
    in_feed = np.arange(m) < nf
    mean_modes = list(mean_f) + list(mean_n)
    mfn = np.array([p.natural_frequency_hz for p in mean_modes])
    mk = np.array([p.stiffness_n_per_m for p in mean_modes])
    mz = np.array([p.damping_ratio for p in mean_modes])
    mfeed = np.arange(len(mean_modes)) < len(mean_f)
    return fn, k, z, in_feed, (mfn, mk, mz, mfeed)


def _fast_sdm_samples(
    feed_s, norm_s, mean_f, mean_n, mean_env, tool, cond, coef, rpm, quantiles, band,
    max_rounds, lobe_options, estimator="coarse-sdm", compiled=False,
):  # fmt: skip
    """Every sample's SDM envelope, estimated cheaply and solved exactly near the quantile ranks.

    1. ``estimator="coarse-sdm"``: every sample's SDM envelope at 10 steps per period and
       ``rtol`` 1 % (about 2.5x cheaper than the 40-step chart), multiplied per speed by the
       mean modes' fine / coarse ratio. ``"zoa"``: the zero-order limits of all samples in one
       batch (:func:`~robovib.milling.structures.zoa_limits`), multiplied by the SDM /
       zero-order ratio of the mean modes, read at the speed scaled by the mean's over the
       sample's natural frequency of the most flexible mode (the lobes move with fn); poor
       where the zero-order method is (heavily damped modes at low speed: everything re-solved
       there).
    2. :func:`_refine_at_ranks`: exact SDM of the samples near the 5/50/95 % order statistics,
       in a band that grows with the estimate's own measured error at each speed.

    ``compiled``: the coarse estimate and the exact solves by the compiled kernel
    (:func:`robovib.milling.sdm_kernel.sdm_limits`, only the wanted pairs), else by
    :func:`~robovib.milling.sdm.sdm_lobes` one sample at a time.

    Returns the (n, n_speeds) limits, the (n, n_speeds) exact mask, the relative error of the
    estimates on the solved pairs and a dict of counts (rounds, pairs solved per round,
    monodromy evaluations).
    """
    from .structures import zoa_limits

    if estimator == "coarse-sdm":
        coarse = {**lobe_options, "steps_per_period": 10, "steps_per_vibration": 4.0,
                  "rtol": 1e-2}  # fmt: skip
        coarse["scan_from_m"] = _scan_start(rpm, mean_env.a_lim_m)
        structs = list(zip(feed_s, norm_s, strict=True))
        if compiled:
            from .sdm_kernel import sdm_limits

            opts = {k: v for k, v in coarse.items() if k != "scan_from_m"}
            mean_c = sdm_limits([(mean_f, mean_n)], tool, cond, coef, rpm,
                                start_m=coarse["scan_from_m"], **opts)[0][0]  # fmt: skip
            raw = sdm_limits(structs, tool, cond, coef, rpm, start_m=coarse["scan_from_m"],
                             **opts)[0]  # fmt: skip
        else:
            mean_c = sdm_lobes(mean_f, mean_n, tool, cond, coef, rpm, **coarse).a_lim_m
            raw = np.array([sdm_lobes(f, m, tool, cond, coef, rpm, **coarse).a_lim_m
                            for f, m in structs])  # fmt: skip
        with np.errstate(invalid="ignore", divide="ignore"):
            corr = np.where(np.isfinite(mean_c) & np.isfinite(mean_env.a_lim_m),
                            mean_env.a_lim_m / mean_c, 1.0)  # fmt: skip
        est = raw * corr
        # A sample's lobes sit a little off the mean's: where the correction changes by more
        # than half the band from one speed to the next (a cusp, a flank) it does not carry
        # over, and every sample is solved exactly there.
        log_c = np.log(corr)
        jump = np.abs(np.diff(log_c))
        rough = np.zeros(rpm.size)
        if rpm.size > 1:
            rough = np.maximum(np.r_[jump, 0.0], np.r_[0.0, jump])
        return _refine_at_ranks(est, feed_s, norm_s, tool, cond, coef, rpm, quantiles, band,
                                max_rounds, lobe_options, rough > 0.5 * band,
                                compiled)  # fmt: skip
    if estimator != "zoa":
        raise ValueError(f"estimator must be 'coarse-sdm' or 'zoa', got {estimator!r}")
    fn, k, z, in_feed, (mfn, mk, mz, mfeed) = _mode_arrays(feed_s, norm_s, mean_f, mean_n)
    zkw = {"points_per_decade": 1000.0}
    est = zoa_limits(fn, k, z, in_feed, rpm, tool, cond, coef, **zkw)
    zoa_mean = zoa_limits(mfn[None], mk[None], mz[None], mfeed, rpm, tool, cond, coef, **zkw)[0]
    sdm_mean = mean_env.a_lim_m
    with np.errstate(invalid="ignore", divide="ignore"):
        ratio = sdm_mean / zoa_mean
    good = np.isfinite(ratio) & (ratio > 0)
    if good.sum() >= 2:
        dom = int(np.argmin(mk * mz))  # most flexible mean mode (lowest k zeta)
        shift = fn[:, dom] / mfn[dom]  # lobes of a sample sit at shift x the mean's speeds
        log_r = np.interp(np.log(rpm[None, :] / shift[:, None]), np.log(rpm[good]),
                          np.log(ratio[good]))  # fmt: skip
        est = est * np.exp(log_r)
    return _refine_at_ranks(est, feed_s, norm_s, tool, cond, coef, rpm, quantiles, band,
                            max_rounds, lobe_options, np.zeros(rpm.size, bool),
                            compiled)  # fmt: skip


#: An estimate whose measured error at a speed (or a neighbour) exceeds this is not used
#: there: every sample is solved exactly at that speed (the fast route's fallback). Errors this
#: large are lobes or unstable windows that the estimate places differently, and they come in
#: clusters that a band does not bound: on the 5-mode stand-in (10-step estimate, 200 x 100,
#: 2026-11-27) a limit of 12.5 % left one 95 % quantile 10 % off, 5 % none.
FAST_MAX_ESTIMATE_ERROR = 0.05


def _refine_at_ranks(est, feed_s, norm_s, tool, cond, coef, rpm, quantiles, band, max_rounds,
                     lobe_options, solve_all, compiled=False):  # fmt: skip
    """Step 2 of :func:`_fast_sdm_samples`: exact SDM near the quantile ranks, with fallback.

    At every speed the samples whose current value (estimate, or exact once solved) lies within
    the speed's band of the order statistics at the ranks of ``quantiles``, and all beyond a
    tail rank (below the 5 %, above the 95 %), are solved exactly; repeated until no new sample
    enters a band (``max_rounds`` at most). An unsolved sample then lies farther than the band
    from every rank; as long as its estimate errs by less than the band its true value is on
    the same side of the rank, so the order statistic at the rank is the exact one.

    The band is the estimate's own error put into it: at each speed ``max(band, 2 e)`` with
    ``e`` the largest relative error of the estimate among the samples solved so far at that
    speed and its two neighbours (a lobe that the estimate misplaces spans neighbouring
    speeds). Where ``e`` exceeds :data:`FAST_MAX_ESTIMATE_ERROR` (a lobe or an unstable window
    the estimate missed), where ``solve_all`` (n_speeds,) says so, or where an estimate is
    infinite, every sample is solved (the fallback).

    Each exact solve scans from 0.9 x the estimate, or lower where the mean's nearby lobes
    start lower (``scan_from_m`` of ``lobe_options``: an unstable window the estimate missed
    lies below a stable pocket); a pair unstable at its start is scanned again from lower down.
    ``compiled``: all pairs of a round in one call of the compiled kernel, else
    :func:`~robovib.milling.sdm.sdm_lobes` sample by sample.
    """
    n, nj = est.shape
    mean_start = np.broadcast_to(np.asarray(lobe_options.get("scan_from_m", np.nan), float), (nj,))
    a = est.copy()
    exact = np.zeros((n, nj), bool)
    ranks = sorted({int(np.clip(np.round(q * (n - 1)), 0, n - 1)) for q in quantiles})
    errs = []
    counts = {"rounds": 0, "pairs_per_round": [], "evaluations": 0}
    seen_err = np.zeros(nj)  # largest estimate error met per speed among the solved samples
    structs = list(zip(feed_s, norm_s, strict=True))
    opts = {k: v for k, v in lobe_options.items() if k != "scan_from_m"}
    for _ in range(int(max_rounds)):
        order = np.sort(a, axis=0)
        near = seen_err.copy()
        near[1:] = np.maximum(near[1:], seen_err[:-1])
        near[:-1] = np.maximum(near[:-1], seen_err[1:])
        width = np.maximum(band, 2 * near)
        fallback = solve_all | (near > FAST_MAX_ESTIMATE_ERROR)
        want = ~np.isfinite(est) | fallback[None]
        for r in ranks:
            # A tail rank: every sample beyond it too (a gross error, e.g. an unstable window
            # the estimate missed, moves a sample across it from the tail's side).
            lo_v = np.full(nj, -np.inf) if r < 0.25 * (n - 1) else order[r]
            hi_v = np.full(nj, np.inf) if r > 0.75 * (n - 1) else order[r]
            with np.errstate(invalid="ignore"):
                want |= (a >= lo_v[None] * (1 - width[None])) & (
                    a <= hi_v[None] * (1 + width[None])
                )
        want &= ~exact
        if not want.any():
            break
        counts["rounds"] += 1
        counts["pairs_per_round"].append(int(want.sum()))
        # From 10 % below the estimate, or lower where the mean's nearby lobes start lower.
        start = np.fmin(0.9 * est, mean_start[None, :])
        start = np.where(np.isfinite(start), start, np.nan)
        if compiled:
            from .sdm_kernel import sdm_limits

            a_all, _, n_ev = sdm_limits(structs, tool, cond, coef, rpm, start_m=start,
                                        solve=want, **opts)  # fmt: skip
            counts["evaluations"] += int(n_ev.sum())
            rows = [(i, np.flatnonzero(want[i]), a_all[i]) for i in np.flatnonzero(want.any(1))]
            rows = [(i, js, a_i[js]) for i, js, a_i in rows]
        else:
            rows = []
            for i in np.flatnonzero(want.any(axis=1)):
                js = np.flatnonzero(want[i])
                o = {**opts, "scan_from_m": start[i, js]}
                rows.append((i, js, sdm_lobes(feed_s[i], norm_s[i], tool, cond, coef, rpm[js],
                                              **o).a_lim_m))  # fmt: skip
        for i, js, a_ex in rows:
            with np.errstate(invalid="ignore", divide="ignore"):
                e = np.abs(est[i, js] / a_ex - 1)
            e = np.where(np.isfinite(e), e, 0.5)  # one of the two infinite: a large error
            seen_err[js] = np.maximum(seen_err[js], np.minimum(e, 0.5))
            errs.append(e)
            a[i, js] = a_ex
            exact[i, js] = True
    err = np.concatenate(errs) if errs else np.zeros(0)
    return a, exact, err, counts


def _compiled_samples(structs, mean_f, mean_n, mean_env, tool, cond, coef, rpm, options,
                      coarse_tolerance, progress):  # fmt: skip
    """Every sample's SDM envelope by the compiled kernel, on fewer steps where that is exact.

    Semi-discretization converges at second order in the step (``a(h) = a_0 + c h^2``), and at
    most speeds of a chart a quarter or half of the reference steps already gives the
    reference limit to a fraction of a per cent. At every speed the mean modes are solved at
    ``m / 4`` and ``m / 2`` steps (``m`` the reference count there, only counts >= 10); the
    coarsest count whose relative difference to the mean's reference limit is at most
    ``coarse_tolerance`` at that speed and its two neighbours is used for every sample there,
    and each sample's limit is multiplied by the mean's reference / coarse ratio at that speed
    (the sample's own discretization error differs from the mean's only by the samples'
    spread, a small fraction of an error that is itself below the tolerance). Elsewhere the
    samples get their own reference steps. Returns the (n, n_speeds) limits, their minima and
    a settings dict (share of coarse pairs, the mean's coarse errors).
    """
    from .forces import engagement_angles
    from .sdm_kernel import sdm_limits, step_counts

    nj = rpm.size
    opts = dict(options)
    start = opts.pop("scan_from_m", None)
    search_opts = {k: opts[k] for k in ("depth_range_m", "rtol", "max_iter", "scan_ratio")
                   if k in opts}  # fmt: skip
    use = np.zeros(nj, int)  # 0: each sample's own (reference) step count
    ratio = np.ones(nj)
    err_used = np.zeros(nj)
    a_ref = mean_env.a_lim_m
    if coarse_tolerance is not None:
        phi_st, phi_ex = engagement_angles(tool, cond)
        cut_fraction = min(1.0, (phi_ex - phi_st) / (2 * np.pi / tool.n_flutes))
        m_ref = step_counts(list(mean_f) + list(mean_n), 60.0 / (tool.n_flutes * rpm),
                            cut_fraction, opts.get("steps_per_period", 40),
                            opts.get("steps_per_vibration", 12.0),
                            opts.get("max_steps", 200)).astype(int)  # fmt: skip
        finite = np.isfinite(a_ref)
        for f in (4, 2):
            m_c = m_ref // f
            try_here = finite & (m_c >= 10) & (use == 0)
            if not try_here.any():
                continue
            a_c = sdm_limits([(mean_f, mean_n)], tool, cond, coef, rpm,
                             steps=np.where(try_here, m_c, 0),
                             start_m=np.where(finite, 0.7 * a_ref, np.nan),
                             **search_opts)[0][0]  # fmt: skip
            with np.errstate(invalid="ignore", divide="ignore"):
                err = np.where(np.isfinite(a_c) & finite, np.abs(a_c / a_ref - 1), np.inf)
            worst = err.copy()
            worst[1:] = np.maximum(worst[1:], err[:-1])
            worst[:-1] = np.maximum(worst[:-1], err[1:])
            good = try_here & (worst <= float(coarse_tolerance))
            use[good] = m_c[good]
            ratio[good] = a_ref[good] / a_c[good]
            err_used[good] = err[good]
    n = len(structs)
    a_s = np.empty((n, nj))
    for c0 in range(0, n, 16):
        a, _, _ = sdm_limits(structs[c0 : c0 + 16], tool, cond, coef, rpm, start_m=start,
                             steps=use, **opts)  # fmt: skip
        a_s[c0 : c0 + 16] = a * ratio[None, :]
        if progress is not None:
            progress(min(c0 + 16, n), n)
    info = {"coarse_speeds": float(np.mean(use > 0)),
            "coarse_mean_error_max": float(err_used.max()),
            "coarse_tolerance": None if coarse_tolerance is None else float(coarse_tolerance)}  # fmt: skip
    return a_s, np.min(a_s, axis=1), info


#: Documented relative bias floor of the dominant-mode fit's stiffness (closing notes of stops
#: 32-33: k +0.8 to +1.8 % before the upper-residual term, +0.2 % after on a clean campaign;
#: the larger figure is kept as the floor while multi-mode fits are not measured).
FIT_STIFFNESS_BIAS = 0.018
#: Factors of the linear limit above 1 simulated by the time-domain margin where the cut at the
#: linear limit is stable (issue 36: the time-domain limit of a structure with several modes
#: per direction reached 1.3 times its zero-order limit on the virtual robot).
MARGIN_ABOVE = (1.05, 1.1, 1.15, 1.2, 1.3, 1.45)


def _scan_start(rpm: np.ndarray, a_mean: np.ndarray) -> np.ndarray:
    """Per speed: 0.7 x the mean's lowest limit within +-15 % of the speed (NaN: scan all).

    The neighbouring speeds of the chart always count as near: on a coarse speed grid the
    +-15 % hold no other speed, and a sample whose lobes sit a little off the mean's has its
    unstable window (a flip lens, the next lobe) at a speed where the mean's starts only at the
    next speed (issue 37: a 20-speed chart put a sample's limit at 7.6 mm instead of 1.8 mm).
    """
    near = np.abs(np.log(rpm[:, None] / rpm[None, :])) <= np.log(1.15)
    rank = np.empty(rpm.size, int)
    rank[np.argsort(rpm, kind="stable")] = np.arange(rpm.size)
    near |= np.abs(rank[:, None] - rank[None, :]) <= 1
    low = np.min(np.where(near, a_mean[None, :], np.inf), axis=1)
    return np.where(np.isfinite(low), 0.7 * low, np.nan)


def _method_error(mean_env, mean_f, mean_n, tool, cond, coef, rpm, method, options) -> np.ndarray:
    """Relative numerical error of the envelope per speed, estimated on the mean modes."""
    steps = int(options.get("steps_per_period", 40))
    rtol = float(options.get("rtol", 1e-3))
    coarse_opts = {k: v for k, v in options.items() if k != "n_lobes"}
    if method == "sdm":
        coarse_opts["steps_per_period"] = max(steps // 2, 2)
        coarse_opts.setdefault("scan_from_m", _scan_start(rpm, mean_env.a_lim_m))
        coarse = sdm_lobes(mean_f, mean_n, tool, cond, coef, rpm, **coarse_opts).a_lim_m
        fine = mean_env.a_lim_m
        with np.errstate(invalid="ignore", divide="ignore"):
            err = np.abs(coarse - fine) / 3 / fine + rtol
    else:
        coarse_opts.update(steps_per_period=20)
        ref = sdm_lobes(mean_f, mean_n, tool, cond, coef, rpm, **coarse_opts).a_lim_m
        with np.errstate(invalid="ignore", divide="ignore"):
            err = np.abs(mean_env.a_lim_m - ref) / ref
    # Where either chart is stable to the top of its range the error is unknown: none added.
    return np.where(np.isfinite(err), np.minimum(err, 0.9), 0.0)


def stability_probability(
    distribution: dict[str, ModeDistribution],
    tool: MillingTool,
    conditions: CuttingConditions,
    coefficients: CuttingCoefficients,
    spindle_rpm,
    depth_m=None,
    *,
    n_samples: int = 40,
    method: str = "sdm",
    feed_direction: str = "x",
    rng=0,
    time_domain_margin: bool = False,
    entry_tooth_periods: int = 0,
    margin_samples: int = 20,
    margin_above: tuple[float, ...] = MARGIN_ABOVE,
    method_error: bool = True,
    fit_bias: float = FIT_STIFFNESS_BIAS,
    progress=None,
    warm_from_mean: bool = True,
    exact: bool = True,
    quantile_band: float = 0.01,
    fast_estimator: str = "coarse-sdm",
    solver: str = "compiled",
    coarse_tolerance: float | None = None,
    **lobe_options,
) -> StabilityProbability:
    """Probability of a stable cut over speeds × depths from sampled modes (module docs).

    Parameters
    ----------
    distribution : dict direction -> ModeDistribution or list of ModeDistribution
        E.g. :func:`mode_distribution_at_pose` (dominant mode) or
        :func:`mode_distributions_at_pose` (every mode); ``x`` and ``y`` are used.
    tool, conditions, coefficients
        As for :func:`robovib.milling.sdm.sdm_lobes`.
    spindle_rpm : array_like (n_speeds,)
        Speeds [rpm].
    depth_m : array_like (n_depths,), optional
        Depth grid [m] (default 0 to 3x the mean envelope's minimum, 120 points).
    n_samples : int
        Monte-Carlo samples.
    method : {"sdm", "zoa"}
    feed_direction : {"x", "y"}
        Base-frame direction of the feed (the other horizontal one is the normal).
    rng : seed or Generator
    **lobe_options
        Passed to :func:`robovib.milling.sdm.sdm_lobes` (``method="sdm"``); ``n_lobes`` for
        ``"zoa"``.
    time_domain_margin : bool
        Scale every sampled envelope, per speed, by its own ratio of the time-domain limit to
        the linear one (:func:`robovib.milling.time_domain.time_domain_limit_ratios`): linear
        theory assumes the flutes never leave the cut, but a cut that enters at full depth can
        be thrown into the chatter that coexists with the stable cut 5-30 % below the linear
        limit (with edge forces). That margin differs from one structure to the next (where
        the speed sits on its lobe, and whether the entry transient reaches the coexisting
        chatter), so it is simulated for ``margin_samples`` of the samples at their own linear
        limits, all in one batch; each other sample takes the bracket of the simulated sample
        with the nearest linear envelope, and every ratio is drawn uniformly inside its
        bracket. The ratio of the mean modes is in ``settings["time_domain_ratio"]``.
    margin_samples : int
        Samples whose margin is simulated (about 0.2 ms per sample and speed); 0: the mean
        modes' margin for every sample (the form before per-sample margins).
    margin_above : tuple of float
        Factors of the linear limit above 1 simulated where the cut at the linear limit is
        stable (``above`` of :func:`~robovib.milling.time_domain.time_domain_limit_ratios`):
        with several modes per direction the time-domain limit often lies above the linear one
        (up to 1.3 times the zero-order limit on the virtual robot), and a margin capped at 1
        made P(stable) too low there (issue 36). ``()``: capped at 1.
    entry_tooth_periods : int
        Entry ramp of that simulation (0: the cut starts at full depth, the conservative case).
    method_error : bool
        Put the numerical error of the method into the band (issue 36 item 5). Per speed, its
        size ``e(n)`` is estimated on the mean modes: for ``"sdm"`` from a second chart at half
        the steps (first-order SDM converges at second order in the step, so the error of the
        chart is ``|a(h) - a(2h)| / 3``), plus the depth search's ``rtol``; for ``"zoa"`` the
        zero-order truncation, ``|a_zoa - a_sdm| / a_sdm`` against a semi-discretization of the
        mean modes at 20 steps. Every sample's limit is then multiplied by ``1 + u e(n)`` with
        one ``u`` uniform in [-1, 1] per sample (the error is systematic along the speeds).
    fit_bias : float
        Documented relative bias floor of the modal fit on the stiffness (and so on the limit,
        which scales with it): the dominant-mode fit returned k up to 1.8 % high (closing notes
        of stops 32-33; 0.2 % with the upper-residual fit on a clean campaign, more where a
        secondary mode is close). Every sample's limit is multiplied by ``1 + v fit_bias`` with
        ``v`` uniform in [-1, 1] per sample (the sign is unknown for a user's robot). 0: none.
        Both factors widen the band by these floors where the pose model's own spread is
        smaller (a clean campaign); where it is larger they add in quadrature and barely
        show. The mean envelope is not changed.
    progress : callable, optional
        ``progress(done, total)`` after each sampled envelope (the library never prints; the
        CLI renders it).
    warm_from_mean : bool
        ``"sdm"``: each sample's depth search starts at 0.7 times the lowest limit of the mean
        modes within ±15 % of the speed (where a sample's lobes can lie), not at the bottom of
        the range; a sample already unstable there is scanned again from lower down, so its
        result is still its lowest unstable depth unless a window of the sample lies wholly
        below the start while the sample is stable at the start. ``False``: every sample scanned like
        the mean (:func:`robovib.milling.sdm.critical_depths`).
    exact : bool
        ``"sdm"``: every sample's whole envelope by its own semi-discretization (default, the
        reference; about 0.05 s per 2-DOF sample at 200 speeds with ``solver="compiled"``,
        0.3 s with ``"numpy"``). ``False``: the quantile-targeted route (issue 37, opt-in): a
        cheap estimate of every sample's envelope (``fast_estimator``), then at every speed the
        samples within a band of the 5, 50 and 95 % order statistics (and all beyond the 5 and
        95 % ones) solved exactly by SDM (on the compiled kernel with ``solver="compiled"``,
        only those pairs, each scan from 0.9 x the estimate or lower where the mean's nearby
        lobes start lower) until no new sample enters a band. The band at a speed is
        ``max(quantile_band, 2 e)``, ``e`` the estimate's own largest error measured on the
        samples solved there and at the neighbouring speeds; where ``e`` exceeds
        :data:`FAST_MAX_ESTIMATE_ERROR` (or an estimate is infinite) every sample is solved
        there. Those quantiles are then exact SDM values wherever the unsolved estimates err
        by less than the band; samples far from the ranks keep their estimates (P(stable) away
        from them carries the estimate's error: ``settings["route"]``,
        ``settings["estimate_error"]`` with the share of pairs solved, the rounds and the
        evaluations per solved pair). Barely faster than the default on the benchmark charts,
        so not the default (``benchmarks/bench_stability_probability.py``, 200 x 100,
        2026-11-27): 1.06x on the chapter-3 2-DOF chart, 1.1-1.2x on the 5-mode stand-in,
        quantiles equal to the exact route's. The 10-step estimate alone costs ~40 % of the
        exact chart and 36-57 % of the pairs still need the exact solve (at a 1 % band even a
        perfect free estimate leaves 42 % of the 2-DOF chart's pairs, 23 % of the 5-mode's);
        the zero-order estimate's 95th-percentile error is 17 % (2-DOF) to 37 % (5 modes), so
        the fallback solves 99-100 % of the pairs.
    quantile_band : float
        Smallest relative band of the fast route (above).
    solver : {"compiled", "numpy"}
        ``"sdm"`` (both routes): the mean's and every sample's envelope by the compiled
        semi-discretization (:func:`robovib.milling.sdm_kernel.sdm_envelopes`: the same steps,
        scan and refinement as :func:`~robovib.milling.sdm.sdm_lobes`, one (sample, speed)
        pair a loop in numba, about 20x faster; tested against the NumPy path and against
        per-sample dense SDM), or by ``sdm_lobes`` itself (``"numpy"``, the reference). Options
        the compiled kernel lacks (``eigensolver``, ``n_scan``) select ``"numpy"``.
    coarse_tolerance : float or None
        ``solver="compiled"``: at speeds where the mean modes' limit with a quarter (or half)
        of the steps is within this relative difference of their reference limit (there and
        at both neighbouring speeds), every sample is solved with those steps and multiplied
        by the mean's reference / coarse ratio (second-order convergence of SDM; see
        ``_compiled_samples``). ``None`` (default): every sample at its own reference steps.
        Opt-in, and *not* accurate enough for issue 37's 1 % quantile target: on the
        chapter-3 chart (2e-3, 200 speeds x 100 samples) it was 1.9x faster than the compiled
        default but one speed's 95 % quantile was 2.6 % off (a low-speed lobe the coarse steps
        place differently for some samples); on the 5-mode stand-in (100 x 30) 1.6x faster,
        quantiles within 0.6 %. P(stable) carries the same errors.
        ``settings["coarse"]`` says how many speeds were coarse.
    fast_estimator : {"coarse-sdm", "zoa"}
        Cheap estimate of the fast route: every sample's 10-step SDM chart corrected by the
        mean's 40-step / 10-step ratio, or the batched zero-order limits corrected by the
        mean's SDM / zero-order ratio shifted with the sample's natural frequency.

    Returns
    -------
    StabilityProbability
    """
    if feed_direction not in ("x", "y"):
        raise ValueError(f"feed_direction must be 'x' or 'y', got {feed_direction!r}")
    normal = "y" if feed_direction == "x" else "x"
    for d in (feed_direction, normal):
        if d not in distribution:
            raise ValueError(f"the distribution has no {d!r} direction")
    if int(n_samples) < 2:
        raise ValueError(f"n_samples must be >= 2, got {n_samples}")
    rpm = np.atleast_1d(np.asarray(spindle_rpm, float))
    gen = np.random.default_rng(rng)
    n = int(n_samples)
    multi = not all(isinstance(distribution[d], ModeDistribution) for d in (feed_direction, normal))
    if multi:
        feed_l, norm_l = _as_list(distribution[feed_direction]), _as_list(distribution[normal])
        if not feed_l or not norm_l:
            raise ValueError("every direction needs at least one mode")
        feed_s, norm_s = _sample_all(feed_l, norm_l, n, gen)
        mean_f, mean_n = [m.mean for m in feed_l], [m.mean for m in norm_l]
    else:
        feed_s = [[m] for m in distribution[feed_direction].sample(n, gen)]
        norm_s = [[m] for m in distribution[normal].sample(n, gen)]
        mean_f, mean_n = [distribution[feed_direction].mean], [distribution[normal].mean]
    if solver not in ("compiled", "numpy"):
        raise ValueError(f"solver must be 'compiled' or 'numpy', got {solver!r}")
    from .sdm_kernel import AVAILABLE, COMPILED_OPTIONS

    # Without numba (or under NUMBA_DISABLE_JIT=1) the same SDM runs on the NumPy path.
    compiled = (
        AVAILABLE
        and method == "sdm"
        and solver == "compiled"
        and set(lobe_options) <= COMPILED_OPTIONS
    )
    mean_env, _ = _envelope(
        mean_f, mean_n, tool, conditions, coefficients, rpm, method,
        solver="compiled" if compiled else "numpy", **lobe_options,
    )  # fmt: skip
    if not (np.isfinite(fit_bias) and 0 <= fit_bias < 0.5):
        raise ValueError(f"fit_bias must be a relative error in [0, 0.5), got {fit_bias!r}")
    a_s = np.empty((n, rpm.size))
    mins = np.empty(n)
    sample_options = dict(lobe_options)
    if method == "sdm" and warm_from_mean and "scan_from_m" not in lobe_options:
        sample_options["scan_from_m"] = _scan_start(rpm, mean_env.a_lim_m)
    fast = method == "sdm" and not exact
    route = "per-sample" if method == "zoa" else ("fast" if fast else "exact")
    est_err = None
    if fast:
        if not (np.isfinite(quantile_band) and 0 < quantile_band < 1):
            raise ValueError(f"quantile_band must be in (0, 1), got {quantile_band!r}")
        a_s, exact_mask, e, counts = _fast_sdm_samples(
            feed_s, norm_s, mean_f, mean_n, mean_env, tool, conditions, coefficients, rpm,
            (0.05, 0.5, 0.95), float(quantile_band), 8, sample_options, fast_estimator,
            compiled,
        )  # fmt: skip
        mins = np.min(a_s, axis=1)
        e = e[np.isfinite(e)]
        est_err = {
            "solved_exactly": float(exact_mask.mean()),
            "speeds_all_exact": float(exact_mask.all(axis=0).mean()),
            "p50": float(np.median(e)) if e.size else None,
            "p95": float(np.quantile(e, 0.95)) if e.size else None,
            "max": float(e.max()) if e.size else None,
            "rounds": counts["rounds"],
            "pairs_per_round": counts["pairs_per_round"],
            "evaluations_per_solved_pair": (
                counts["evaluations"] / max(int(exact_mask.sum()), 1) if compiled else None
            ),
        }
        if progress is not None:
            progress(n, n)
    coarse_info = None
    if compiled and not fast:
        if coarse_tolerance is not None and not (
            np.isfinite(coarse_tolerance) and 0 < coarse_tolerance < 0.1
        ):
            raise ValueError(
                f"coarse_tolerance must be in (0, 0.1) or None, got {coarse_tolerance!r}"
            )
        a_s, mins, coarse_info = _compiled_samples(
            list(zip(feed_s, norm_s, strict=True)), mean_f, mean_n, mean_env, tool, conditions,
            coefficients, rpm, sample_options, coarse_tolerance, progress,
        )  # fmt: skip
    for i, (mf, mn) in enumerate(zip(feed_s, norm_s, strict=True)):
        if fast or compiled:
            break
        env, mins[i] = _envelope(
            mf, mn, tool, conditions, coefficients, rpm, method, **sample_options
        )
        a_s[i] = env.a_lim_m
        if progress is not None:
            progress(i + 1, n)
    err = np.zeros(rpm.size)
    if method_error:
        err = _method_error(mean_env, mean_f, mean_n, tool, conditions, coefficients, rpm,
                            method, lobe_options)  # fmt: skip
    floor = np.ones((n, rpm.size))
    if method_error or fit_bias > 0:
        u, v = gen.uniform(-1, 1, n), gen.uniform(-1, 1, n)
        floor = (1 + u[:, None] * err[None, :]) * (1 + v[:, None] * float(fit_bias))
        a_s = a_s * floor
        mins = mins * floor.min(axis=1)
    ratio = np.ones(rpm.size)
    if time_domain_margin:
        from .time_domain import time_domain_limit_ratios

        if int(margin_samples) < 0:
            raise ValueError(f"margin_samples must be >= 0, got {margin_samples}")
        # The mean modes first (their ratio is reported), then the first margin_samples samples
        # with a finite envelope (the samples are in random order), each at its own linear limit.
        finite = np.all(np.isfinite(a_s) & (a_s > 0), axis=1)
        sim = np.flatnonzero(finite)[: int(margin_samples)]
        if int(margin_samples) > 0 and sim.size == 0:
            raise ValueError("no sample has a finite linear limit at every speed")
        sets = [(mean_f, mean_n)] + [(feed_s[i], norm_s[i]) for i in sim]
        low, high = time_domain_limit_ratios(
            sets, tool, conditions, coefficients, rpm,
            np.vstack([mean_env.a_lim_m[None, :], a_s[sim]]),
            entry_tooth_periods=int(entry_tooth_periods), above=tuple(margin_above),
        )  # fmt: skip
        ratio = 0.5 * (low[0] + high[0])
        if sim.size:
            low_s, high_s = low[1:], high[1:]
            # A sample not simulated takes the bracket of the simulated sample whose linear
            # envelope is nearest (log depth over the speeds: the same place on the lobes).
            log_a = np.log(np.where(finite[:, None], a_s, 1.0))
            near = np.argmin(np.sum((log_a[:, None, :] - log_a[None, sim, :]) ** 2, axis=2), axis=1)
            near[sim] = np.arange(sim.size)
        else:  # margin_samples=0: the mean modes' bracket for every sample
            low_s, high_s, near = low[:1], high[:1], np.zeros(n, int)
        # The simulated limit is known to its bracket: each sample's ratio is drawn inside it.
        a_s = a_s * gen.uniform(low_s[near], high_s[near])
        mins = mins * low_s[near].min(axis=1)
    if depth_m is None:
        depth = np.linspace(0, 3 * mean_env.minimum_depth_m, 121)[1:]
    else:
        depth = np.atleast_1d(np.asarray(depth_m, float))
        if np.any(~np.isfinite(depth)) or np.any(depth < 0):
            raise ValueError("depth_m must be finite depths >= 0 m")
    p = np.mean(a_s[:, :, None] > depth[None, None, :], axis=0)
    return StabilityProbability(
        rpm, depth, p, a_s, mins, mean_env,
        {"n_samples": int(n_samples), "method": method, "feed_direction": feed_direction,
         "time_domain_ratio": ratio.tolist() if time_domain_margin else None,
         "entry_tooth_periods": int(entry_tooth_periods) if time_domain_margin else None,
         "margin_samples": int(sim.size) if time_domain_margin else None,
         "method_error": err.tolist() if method_error else None,
         "fit_bias": float(fit_bias),
         "route": route, "solver": "compiled" if compiled else "numpy",
         "quantile_band": float(quantile_band) if fast else None,
         "fast_estimator": fast_estimator if fast else None,
         "estimate_error": est_err,
         "coarse": coarse_info,
         "sampling": (
             "joint draws of the pose model's calibrated latent predictive distribution "
             "(Student-t bands, mode mixture)"
             if _as_list(distribution[feed_direction])[0].draws is not None
             else "independent normals on fn_hz, stiffness_n_per_m, damping_ns_per_m"),
         "modes": {d: [m.name or f"{d}{j + 1}" for j, m in enumerate(_as_list(distribution[d]))]
                   for d in (feed_direction, normal)}},
    )  # fmt: skip


def plot_stability_probability(
    result: StabilityProbability,
    ax=None,
    *,
    title: str | None = None,
    operating_point: tuple[float, float] | None = None,
    cuts=None,
):
    """Shaded lobes: probability of a stable cut, mean envelope, 5 % / 95 % depth quantiles.

    Parameters
    ----------
    result : StabilityProbability
        The probability map.
    ax : matplotlib.axes.Axes, optional
        Axes to draw on (default: a new figure).
    title : str, optional
        Chart title.
    operating_point : (rpm, depth [m]), optional
        Marked on the chart.
    cuts : MeasuredCuts, optional
        Test cuts to mark.

    Returns
    -------
    matplotlib.figure.Figure
    """
    import matplotlib.pyplot as plt

    from .lobes import plot_lobes

    if ax is None:
        _, ax = plt.subplots(figsize=(8, 4.5))
    plot_lobes(result.mean, ax=ax, probability=result, depth_max_m=float(result.depth_m.max()),
               operating_point=operating_point, cuts=cuts,
               title=title or f"probability of a stable cut ({result.settings['n_samples']} samples)")  # fmt: skip
    for q, ls in ((0.05, ":"), (0.95, "--")):
        ax.plot(result.spindle_rpm, result.depth_quantile_m(q) * 1e3, color="0.2", ls=ls, lw=1,
                label=f"{int(q * 100)} % quantile of the limit")  # fmt: skip
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.22, 1.0), borderaxespad=0.0)
    ax.figure.tight_layout()
    return ax.figure
