"""The process factor integrated on a grid (issue 39): against direct numerical integration over
the log-uniform factor (SciPy quad), against independent Monte-Carlo draws of the factor, and
bad input refused."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import integrate, stats

from robovib.milling.factor_grid import factor_grid, factor_grid_posterior, unscaled_limits

LO, HI = 0.5, 1.5


def test_grid_points_are_the_bin_medians_of_the_log_uniform():
    q = factor_grid((LO, HI), 8)
    expected = stats.loguniform(LO, HI).ppf((np.arange(8) + 0.5) / 8)
    np.testing.assert_allclose(q, expected, rtol=1e-12)
    assert factor_grid((1.0, 1.0), 3) == pytest.approx([1.0, 1.0, 1.0])


def _reference_p_stable(limit, depths, chatter, eps, depth):
    """One structure of linear limit ``limit``: P(stable at depth | cuts) by quad over log q."""
    lo, hi = np.log(LO), np.log(HI)

    def lik(t):
        q = np.exp(t)
        pred = depths >= q * limit
        return np.prod(np.where(pred == chatter, 1 - eps, eps))

    breaks = sorted({np.log(d / limit) for d in [*depths, depth] if lo < np.log(d / limit) < hi})
    norm = integrate.quad(lik, lo, hi, points=breaks or None, limit=200)[0]
    t_d = np.log(depth / limit)  # stable where q limit > depth: t > t_d
    upper = integrate.quad(lik, max(lo, t_d), hi, points=[b for b in breaks if b > t_d] or None,
                           limit=200)[0] if t_d < hi else 0.0  # fmt: skip
    return upper / norm


@pytest.mark.parametrize(
    ("depths_mm", "chatter"),
    [([3.0, 4.5], [False, True]), ([2.0, 2.6, 3.3, 4.0], [False, True, False, True])],
)
def test_one_structure_posterior_matches_direct_integration(depths_mm, chatter):
    limit = 4e-3
    d = np.array(depths_mm) * 1e-3
    y = np.array(chatter)
    k = 4000
    post = factor_grid_posterior(np.full((1, d.size), limit), d, y, process_factor=(LO, HI),
                                 n_factors=k, label_noise=0.1)  # fmt: skip
    for depth in (2.2e-3, 3.1e-3, 3.9e-3, 5.5e-3):
        ref = _reference_p_stable(limit, d, y, 0.1, depth)
        # a stratified grid misplaces at most one bin's mass per break (cuts + the depth)
        assert post.p_stable(np.array([limit]), depth) == pytest.approx(ref, abs=(d.size + 2) / k)
    # the factor's posterior mean against quad as well
    lo, hi = np.log(LO), np.log(HI)

    def lik(t):
        return np.prod(np.where((d >= np.exp(t) * limit) == y, 0.9, 0.1))

    num = integrate.quad(lambda t: np.exp(t) * lik(t), lo, hi, limit=200)[0]
    den = integrate.quad(lik, lo, hi, limit=200)[0]
    fp = post.factor_posterior()
    assert np.sum(fp * post.factors) == pytest.approx(num / den, rel=1e-3)


def test_prior_p_stable_tends_to_monte_carlo_over_independent_factor_draws():
    gen = np.random.default_rng(3)
    s = 40
    lim = gen.uniform(1e-3, 6e-3, (s, 3))
    lim[5, 1] = np.inf  # no lobe: stable at any depth
    depth = np.array([1.5e-3, 2.5e-3, 4.0e-3])
    prior = factor_grid_posterior(lim[:, :0], depth[:0], np.zeros(0, bool),
                                  process_factor=(LO, HI), n_factors=512)  # fmt: skip
    # an independent reference: (structure, factor) pairs drawn at random
    n = 400_000
    which = gen.integers(0, s, n)
    q = stats.loguniform(LO, HI).rvs(n, random_state=gen)
    mc = np.mean(q[:, None] * lim[which] > depth[None, :], axis=0)
    p = prior.p_stable(lim, depth)
    assert p.shape == (3,)
    np.testing.assert_allclose(p, mc, atol=5 * 0.5 / np.sqrt(n) + 1 / 512)
    assert prior.effective_sample_size == pytest.approx(s * 512)


def test_posterior_matches_importance_weighting_of_many_factor_draws():
    # the grid posterior is the limit of the per-structure-draw posterior (cut_posterior)
    from robovib.milling.cut_posterior import p_stable

    gen = np.random.default_rng(4)
    lim = gen.uniform(2e-3, 5e-3, (10, 4))
    d = np.array([3e-3, 2.5e-3, 3.5e-3, 3e-3])
    y = np.array([True, False, True, False])
    post = factor_grid_posterior(lim, d, y, process_factor=(LO, HI), n_factors=1024,
                                 label_noise=0.05)  # fmt: skip
    n = 200_000
    which = gen.integers(0, 10, n)
    q = stats.loguniform(LO, HI).rvs(n, random_state=gen)
    drawn = q[:, None] * lim[which]
    w = np.prod(np.where((d[None] >= drawn) == y[None], 0.95, 0.05), axis=1)
    w /= w.sum()
    depth = np.array([2e-3, 3e-3, 4e-3, 5e-3])
    ref = p_stable(drawn, w, depth)
    ess = 1 / np.sum(w**2)
    np.testing.assert_allclose(
        post.p_stable(lim, depth), ref, atol=5 * 0.5 / np.sqrt(ess) + 4 / 1024
    )
    assert post.information_nats > 0
    assert post.effective_sample_size < post.prior_weights.size


def test_unscaled_limits_divides_out_the_drawn_factor():
    class _Structures:
        process_factor = np.array([0.5, 2.0])

        def limits(self, poses, spindle_rpm, tool, conditions, coefficients, **kw):
            return (
                np.full((2, len(poses), len(spindle_rpm)), 3e-3)
                * self.process_factor[:, None, None]
            )

    out = unscaled_limits(_Structures(), np.zeros((3, 3)), [2000.0, 3000.0], None, None, None)
    np.testing.assert_allclose(out, np.full((2, 3, 2), 3e-3))


def test_bad_input_is_refused():
    lim = np.full((3, 2), 3e-3)
    d = np.array([2e-3, 4e-3])
    y = np.array([False, True])
    with pytest.raises(ValueError, match="label_noise"):
        factor_grid_posterior(lim, d, y, label_noise=0.0)
    with pytest.raises(ValueError, match="n_factors"):
        factor_grid_posterior(lim, d, y, n_factors=0)
    with pytest.raises(ValueError, match="process_factor"):
        factor_grid((1.5, 0.5), 4)
    with pytest.raises(ValueError, match="NaN"):
        factor_grid_posterior(np.where(lim > 0, np.nan, lim), d, y)
    with pytest.raises(ValueError, match="depth_m and chatter"):
        factor_grid_posterior(lim, d[:1], y)
    with pytest.raises(ValueError, match="bool"):
        factor_grid_posterior(lim, d, y.astype(int))
    with pytest.raises(ValueError, match="positive"):
        factor_grid_posterior(lim, -d, y)
    with pytest.raises(ValueError, match="prior_weights"):
        factor_grid_posterior(lim, d, y, prior_weights=[1.0, -1.0, 1.0])
    post = factor_grid_posterior(lim, d, y)
    with pytest.raises(ValueError, match="3 structures"):
        post.p_stable(lim[:2], 1e-3)
    with pytest.raises(ValueError, match="NaN"):
        post.p_stable(lim, np.nan)


def test_choose_test_cuts_groups_spread_the_cuts():
    from robovib.milling.cut_posterior import choose_test_cuts

    # 4 equally likely structures; candidates 0 and 1 split them independently (joint outcome
    # entropy log 4), candidate 2 together with 0 gives only 3 outcome patterns
    lim = np.array([[1, 1, 1], [2, 3, 1], [3, 2, 1], [4, 4, 4]], float) * 1e-3
    w = np.full(4, 0.25)
    idx, _ = choose_test_cuts(lim, w, 2)
    assert list(idx) == [0, 1]
    idx, depth = choose_test_cuts(lim, w, 2, groups=["a", "a", "b"])
    assert list(idx) == [0, 2]
    assert depth == pytest.approx([2e-3, 1e-3])
    with pytest.raises(ValueError, match="groups"):
        choose_test_cuts(lim, w, 2, groups=[0, 1])
    with pytest.raises(ValueError, match="fewer informative"):
        choose_test_cuts(lim, w, 3, groups=[0, 0, 1])


def _known_limits(limits_m):
    """Structures whose linear limit is known: ``a_s`` at every pose and speed."""
    from robovib.milling.structures import StructureSamples

    class _Known(StructureSamples):
        def _linear_limits(self, poses, spindle_rpm, *args):
            shape = (np.atleast_2d(poses).shape[0], np.atleast_1d(spindle_rpm).size)
            return np.asarray(limits_m, float)[:, None, None] * np.ones(shape)[None]

    n = len(limits_m)
    return _Known(None, np.full(n, 1.0 / n), np.ones(n), (1.0, 1.0, 1.0), np.zeros((1, 1, 3)),
                  np.zeros((1, 1)), np.zeros((n, 1, 1)), {"process_factor_range": [LO, HI]})  # fmt: skip


@pytest.mark.parametrize(
    ("depths_mm", "chatter"),
    [([3.0, 4.5], [False, True]), ([2.0, 2.6, 3.3, 4.0], [False, True, False, True])],
)
def test_update_with_cuts_integrates_the_factor_like_quad(depths_mm, chatter):
    """The library's update (``mill lobes|map|plan --cuts``) on the factor grid: one structure's
    posterior P(stable) against SciPy quad over the log-uniform factor."""
    from robovib.io.cuts import MeasuredCuts
    from robovib.milling import ALUMINIUM_7075, CuttingConditions, MillingTool
    from robovib.milling.cut_posterior import update_with_cuts

    limit, k = 4e-3, 2000
    d = np.array(depths_mm) * 1e-3
    y = np.array(chatter)
    st = _known_limits([limit])
    cuts = MeasuredCuts(np.full(d.size, 2000.0), d, y, np.tile([2400.0, 0.0, 45.0], (d.size, 1)))
    tool, cond = MillingTool(), CuttingConditions(1750.0, 0.058e-3, 1e-3, 6e-3)
    upd = update_with_cuts(st, cuts, tool, cond, ALUMINIUM_7075, label_noise=0.1, n_factors=k)
    post = upd.structures
    assert post.n_samples == k and post.n_structures == 1
    lim = post.limits([[2300.0, 100.0, 0.0]], [1500.0], tool, cond, ALUMINIUM_7075)[:, 0, 0]
    for depth in (2.2e-3, 3.1e-3, 3.9e-3, 5.5e-3):
        ref = _reference_p_stable(limit, d, y, 0.1, depth)
        got = float(np.sum(post.weights * (lim > depth)))
        assert got == pytest.approx(ref, abs=(d.size + 2) / k)
    # the cuts' own P(stable) before: the log-uniform's closed form
    prior = np.clip(np.log(HI / (d / limit)) / np.log(HI / LO), 0, 1)
    np.testing.assert_allclose(upd.p_stable_prior, prior, atol=1 / k)


def test_update_with_cuts_on_the_grid_equals_factor_grid_posterior():
    """Several structures: the update's pair weights are those of factor_grid_posterior (tested
    against quad and Monte Carlo above), a second update continues on the same grid, and the
    structures' effective sample size sums each structure's factors."""
    from robovib.io.cuts import MeasuredCuts
    from robovib.milling import ALUMINIUM_7075, CuttingConditions, MillingTool
    from robovib.milling.cut_posterior import update_with_cuts

    a = np.array([2.0, 3.0, 4.0, 6.0]) * 1e-3
    st = _known_limits(a)
    d = np.array([2.5e-3, 4e-3])
    y = np.array([False, True])
    pose = np.tile([2400.0, 0.0, 45.0], (2, 1))
    tool, cond = MillingTool(), CuttingConditions(1750.0, 0.058e-3, 1e-3, 6e-3)
    upd = update_with_cuts(st, MeasuredCuts(np.full(2, 2000.0), d, y, pose), tool, cond,
                           ALUMINIUM_7075, label_noise=0.1, n_factors=16)  # fmt: skip
    ref = factor_grid_posterior(np.tile(a[:, None], (1, 2)), d, y, process_factor=(LO, HI),
                                n_factors=16, label_noise=0.1)  # fmt: skip
    np.testing.assert_allclose(upd.structures.weights, ref.weights.ravel(), rtol=1e-12)
    np.testing.assert_allclose(upd.prior_weights, ref.prior_weights.ravel(), rtol=1e-12)
    marg = ref.weights.sum(axis=1)
    assert upd.effective_sample_size == pytest.approx(1 / np.sum(marg**2))
    assert upd.prior_effective_sample_size == pytest.approx(4.0)
    # one cut after the other = both at once
    one = update_with_cuts(st, MeasuredCuts(np.full(1, 2000.0), d[:1], y[:1], pose[:1]), tool,
                           cond, ALUMINIUM_7075, label_noise=0.1, n_factors=16)  # fmt: skip
    two = update_with_cuts(one.structures, MeasuredCuts(np.full(1, 2000.0), d[1:], y[1:],
                           pose[1:]), tool, cond, ALUMINIUM_7075, label_noise=0.1)  # fmt: skip
    np.testing.assert_allclose(two.structures.weights, upd.structures.weights, rtol=1e-12)
    with pytest.raises(ValueError, match="already on a process-factor grid"):
        upd.structures.on_factor_grid(4)


def _brute_expected_brier(lim, w, ev, ed, cuts, eps):
    """Expected Brier score at the evaluation points after cuts (index, depth), by enumerating
    every outcome sequence with plain Bayes (loops, no shared code)."""
    import itertools

    total = 0.0
    for ys in itertools.product([True, False], repeat=len(cuts)):
        post = np.array(w, float)
        for (c, d), y in zip(cuts, ys, strict=True):
            pred = lim[:, c] <= d
            post = post * np.where(pred == y, 1 - eps, eps)
        z = post.sum()
        if z == 0:
            continue
        p = (post[:, None] * (ev > ed[None, :])).sum(axis=0) / z
        total += z * np.mean(p * (1 - p))
    return total


def test_choose_forecast_cuts_minimises_the_expected_brier_score():
    from robovib.milling.cut_posterior import choose_forecast_cuts, weighted_quantile

    rng = np.random.default_rng(5)
    r, c, e = 40, 6, 9
    factor = np.exp(rng.uniform(np.log(0.5), np.log(1.5), r))  # shared by every point
    lim = factor[:, None] * rng.uniform(2e-3, 6e-3, c)[None] * rng.lognormal(0, 0.1, (r, c))
    ev = factor[:, None] * rng.uniform(2e-3, 6e-3, e)[None] * rng.lognormal(0, 0.1, (r, e))
    ed = np.median(ev, axis=0) * rng.uniform(0.7, 1.3, e)
    w = rng.uniform(0.5, 1.5, r)
    w /= w.sum()
    eps, qs = 0.1, (0.3, 0.5, 0.7)
    idx, depth, scores = choose_forecast_cuts(lim, w, ev, ed, 2, label_noise=eps,
                                              depth_quantiles=qs)  # fmt: skip
    assert scores[0] == pytest.approx(_brute_expected_brier(lim, w, ev, ed, [], eps))
    # the first cut is the best single one over every candidate and depth, by enumeration
    options = [(k, float(weighted_quantile(lim[:, k : k + 1], w, q)[0])) for k in range(c)
               for q in qs]  # fmt: skip
    brute = [_brute_expected_brier(lim, w, ev, ed, [o], eps) for o in options]
    assert scores[1] == pytest.approx(min(brute), rel=1e-9)
    assert (idx[0], depth[0]) == options[int(np.argmin(brute))]
    # the second, given the first (greedy), and its expected score
    second = [_brute_expected_brier(lim, w, ev, ed, [(idx[0], depth[0]), o], eps)
              for o in options if o[0] != idx[0]]  # fmt: skip
    assert scores[2] == pytest.approx(min(second), rel=1e-9)
    assert scores[2] <= scores[1] <= scores[0]
    # groups: the two cuts have different labels
    g = np.array([0, 0, 1, 1, 2, 2])
    gi, _, _ = choose_forecast_cuts(lim, w, ev, ed, 3, groups=g, label_noise=eps)
    assert len(set(g[gi])) == 3
    with pytest.raises(ValueError, match="eval_limits_m"):
        choose_forecast_cuts(lim, w, ev[:, :2], ed, 2)
    with pytest.raises(ValueError, match="label_noise"):
        choose_forecast_cuts(lim, w, ev, ed, 2, label_noise=0.5)
    with pytest.raises(ValueError, match="fewer allowed"):
        choose_forecast_cuts(lim, w, ev, ed, 4, groups=g)


def test_local_factor_against_monte_carlo():
    """A local factor drawn afresh at each cut and forecast point: the grid posterior's P(stable)
    against importance-weighted Monte-Carlo draws of (common factor, one local factor per cut,
    one at the forecast point)."""
    rng = np.random.default_rng(11)
    a, eps, local = 4e-3, 0.1, (0.6, 1.3)
    d = np.array([3.0e-3, 4.5e-3, 3.6e-3])
    y = np.array([False, True, True])
    post = factor_grid_posterior(np.full((1, 3), a), d, y, process_factor=(LO, HI),
                                 n_factors=400, label_noise=eps, local_factor=local)  # fmt: skip
    n = 400_000
    q = stats.loguniform(LO, HI).rvs(n, random_state=rng)
    r = stats.loguniform(*local).rvs((n, 4), random_state=rng)
    pred = d[None, :] >= q[:, None] * r[:, :3] * a
    w = np.prod(np.where(pred == y[None, :], 1 - eps, eps), axis=1)
    for depth in (2.0e-3, 3.0e-3, 4.0e-3, 5.5e-3):
        ref = np.sum(w * (q * r[:, 3] * a > depth)) / w.sum()
        ess = w.sum() ** 2 / np.sum(w**2)
        got = float(post.p_stable(np.array([a]), depth))
        assert got == pytest.approx(ref, abs=4 * 0.5 / np.sqrt(ess) + 4 / 400)
    # the prior (no cuts) and an infinite limit (no lobe: stable at any depth)
    prior = factor_grid_posterior(np.full((1, 0), a), d[:0], y[:0], process_factor=(LO, HI),
                                  n_factors=400, local_factor=local)  # fmt: skip
    ref0 = np.mean(q * r[:, 3] * a > 3.5e-3)
    assert float(prior.p_stable(np.array([a]), 3.5e-3)) == pytest.approx(ref0, abs=0.01)
    assert float(prior.p_stable(np.array([np.inf]), 3.5e-3)) == pytest.approx(1.0, abs=1e-12)
    with pytest.raises(ValueError, match="local_factor"):
        factor_grid_posterior(np.full((1, 3), a), d, y, local_factor=(1.3, 0.6))
