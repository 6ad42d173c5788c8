"""The process factor split into a common part (learnt by test cuts) and a local part drawn
afresh at every point (issue 39's re-plan): P(stable) and its inverse against Monte-Carlo draws
of the local factor and SciPy's root finder, the update against ``factor_grid_posterior`` and
importance-weighted Monte Carlo, the plan's depth at the P(stable) it claims, bad input."""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy import optimize, stats

from robovib.milling import ALUMINIUM_7075, CuttingConditions, MillingTool
from robovib.milling.factor_grid import factor_grid_posterior, local_p_stable, local_quantile

TOOL = MillingTool()
COND = CuttingConditions(1750.0, 0.058e-3, 1e-3, 6e-3)
LOCAL = (0.55, 1.3)


def _rows(rng, n_rows=40, n_points=6):
    lim = np.exp(rng.normal(np.log(5e-3), 0.4, (n_rows, n_points)))
    w = rng.uniform(size=n_rows)
    return lim, w / w.sum()


def test_local_p_stable_against_monte_carlo_draws_of_the_local_factor():
    rng = np.random.default_rng(0)
    lim, w = _rows(rng)
    lim[:5, 1] = np.inf  # no lobe: stable at any depth
    r = stats.loguniform(*LOCAL).rvs((200_000, 1), random_state=rng)
    for depth in (1.5e-3, 3e-3, 5e-3, 8e-3):
        got = local_p_stable(lim, w, depth, LOCAL)
        for c in range(lim.shape[1]):
            # each row's own draws of the local factor, weighted
            ref = np.sum(w * np.mean(r * lim[None, :, c] > depth, axis=0))
            assert got[c] == pytest.approx(ref, abs=4e-3)
    assert local_p_stable(np.full((3, 1), np.inf), np.full(3, 1 / 3), 1.0, LOCAL) == 1.0


@pytest.mark.parametrize("q", [0.02, 0.05, 0.3, 0.5, 0.9])
def test_local_quantile_is_the_root_of_p_stable(q):
    rng = np.random.default_rng(1)
    lim, w = _rows(rng)
    lim[:10, 2] = np.inf
    d = local_quantile(lim, w, q, LOCAL, chunk=4)  # several chunks
    for c in range(lim.shape[1]):

        def chatter(x, c=c):
            return 1 - local_p_stable(lim[:, c], w, x, LOCAL) - q

        if chatter(1.0) < 0:  # the rows with no lobe weigh more than 1 - q
            assert np.isinf(d[c]) and np.sum(w[np.isinf(lim[:, c])]) >= 1 - q
            continue
        ref = optimize.brentq(chatter, 1e-6, 1.0, xtol=1e-14, rtol=1e-12)
        assert d[c] == pytest.approx(ref, rel=1e-9)
    # and against sorted Monte-Carlo draws of the whole mixture, one point
    n = 400_000
    rows = rng.choice(w.size, n, p=w)
    draws = np.sort(lim[rows, 0] * stats.loguniform(*LOCAL).rvs(n, random_state=rng))
    assert d[0] == pytest.approx(draws[int(q * n)], rel=0.02)


def test_local_quantile_edge_cases():
    w = np.array([0.5, 0.3, 0.2])
    lim = np.array([[4e-3, np.inf], [np.inf, np.inf], [np.inf, np.inf]])
    d = local_quantile(lim, w, 0.2, LOCAL)
    # column 0: only the first row can chatter; F of its local factor reaches 0.4 at the root
    ref = 4e-3 * np.exp(np.log(LOCAL[0]) + 0.4 * np.log(LOCAL[1] / LOCAL[0]))
    assert d[0] == pytest.approx(ref, rel=1e-12)
    assert np.isinf(d[1])
    assert np.isinf(local_quantile(lim, w, 0.6, LOCAL)[0])  # the rows with no lobe weigh 0.5
    # a local factor of one value: the weighted quantile of the scaled limits
    from robovib.milling.cut_posterior import weighted_quantile

    lim2 = np.array([[1e-3], [2e-3], [3e-3]])
    assert local_quantile(lim2, w, 0.6, (0.8, 0.8)) == pytest.approx(
        weighted_quantile(lim2 * 0.8, w, 0.6)
    )
    with pytest.raises(ValueError, match="q must be"):
        local_quantile(lim2, w, 1.0, LOCAL)
    with pytest.raises(ValueError, match="local_factor"):
        local_quantile(lim2, w, 0.5, (1.3, 0.55))
    with pytest.raises(ValueError, match="rows first"):
        local_quantile(lim2, w[:2], 0.5, LOCAL)
    with pytest.raises(ValueError, match="NaN"):
        local_quantile(np.array([[np.nan], [1e-3], [2e-3]]), w, 0.5, LOCAL)
    with pytest.raises(ValueError, match="weights"):
        local_quantile(lim2, -w, 0.5, LOCAL)


def _known_limits(limits_m, factor_range=(0.5, 1.5)):
    """Structures whose linear limit is known: ``a_s`` at every pose and speed."""
    from robovib.milling.structures import StructureSamples

    class _Known(StructureSamples):
        def _linear_limits(self, poses, spindle_rpm, *args):
            shape = (np.atleast_2d(poses).shape[0], np.atleast_1d(spindle_rpm).size)
            return np.asarray(limits_m, float)[:, None, None] * np.ones(shape)[None]

    n = len(limits_m)
    return _Known(None, np.full(n, 1.0 / n), np.ones(n), (1.0, 1.0, 1.0), np.zeros((1, 1, 3)),
                  np.zeros((1, 1)), np.zeros((n, 1, 1)),
                  {"process_factor_range": list(factor_range)})  # fmt: skip


def test_update_with_cuts_split_against_monte_carlo():
    """``update_with_cuts(local_factor=)``: the weights are factor_grid_posterior's, and a
    structure's posterior P(stable) elsewhere matches importance-weighted Monte Carlo over the
    common factor and one local factor per cut and per forecast point."""
    from robovib.io.cuts import MeasuredCuts
    from robovib.milling.cut_posterior import update_with_cuts

    a = np.array([3.0, 4.0, 6.0]) * 1e-3
    st = _known_limits(a)
    d = np.array([2.5e-3, 4.0e-3, 3.2e-3])
    y = np.array([False, True, False])
    pose = np.tile([2400.0, 0.0, 45.0], (3, 1))
    common, eps, k = (0.9, 1.1), 0.1, 64
    upd = update_with_cuts(st, MeasuredCuts(np.full(3, 2000.0), d, y, pose), TOOL, COND,
                           ALUMINIUM_7075, label_noise=eps, n_factors=k, local_factor=LOCAL,
                           common_factor=common)  # fmt: skip
    post = upd.structures
    assert post.local_factor == LOCAL and post.n_samples == 3 * k
    assert post.settings["process_factor_range"] == list(common)
    ref = factor_grid_posterior(np.tile(a[:, None], (1, 3)), d, y, process_factor=common,
                                n_factors=k, label_noise=eps, local_factor=LOCAL)  # fmt: skip
    np.testing.assert_allclose(post.weights, ref.weights.ravel(), rtol=1e-10)
    # Monte Carlo: a structure (uniform prior), a common factor, a local factor per cut + 1
    rng = np.random.default_rng(4)
    n = 600_000
    s = rng.integers(0, 3, n)
    c = stats.loguniform(*common).rvs(n, random_state=rng)
    r = stats.loguniform(*LOCAL).rvs((n, 4), random_state=rng)
    chat = d[None, :] >= (a[s] * c)[:, None] * r[:, :3]
    lw = np.prod(np.where(chat == y[None, :], 1 - eps, eps), axis=1)
    lim = post.limits([[2300.0, 100.0, 0.0]], [1500.0], TOOL, COND, ALUMINIUM_7075)[:, 0, 0]
    ess = lw.sum() ** 2 / np.sum(lw**2)
    for depth in (2e-3, 3e-3, 4.5e-3):
        mc = np.sum(lw * (a[s] * c * r[:, 3] > depth)) / lw.sum()
        got = float(local_p_stable(lim, post.weights, depth, LOCAL))
        assert got == pytest.approx(mc, abs=4 * 0.5 / np.sqrt(ess) + 2 / k)
    # the cuts' own P(stable) before and after, and the weighted median, from the same rows
    lim_c = np.repeat(a, k)[:, None] * post.process_factor[:, None]
    np.testing.assert_allclose(upd.p_stable_prior,
                               local_p_stable(lim_c, upd.prior_weights, d, LOCAL))  # fmt: skip
    np.testing.assert_allclose(
        upd.p_stable_posterior, local_p_stable(lim_c, post.weights, d, LOCAL)
    )
    assert "local factor" in upd.to_dict()["settings"]["process_factor"]
    # a second update keeps the split; an earlier grid without one is refused
    cut1 = MeasuredCuts(np.full(1, 2000.0), d[:1], y[:1], pose[:1])
    again = update_with_cuts(post, cut1, TOOL, COND, ALUMINIUM_7075, label_noise=eps,
                             local_factor=LOCAL)  # fmt: skip
    assert again.structures.local_factor == LOCAL
    plain = update_with_cuts(st, cut1, TOOL, COND, ALUMINIUM_7075, n_factors=8)
    with pytest.raises(ValueError, match="without a local factor"):
        update_with_cuts(plain.structures, cut1, TOOL, COND, ALUMINIUM_7075, local_factor=LOCAL)
    with pytest.raises(ValueError, match="local_factor"):
        st.on_factor_grid(4, local_factor=(1.3, 0.5))


def test_a_stable_label_moves_other_points_only_through_the_common_factor():
    """One structure: with the split, 3 stable cuts at 1.3x the prior median raise the forecast
    elsewhere by at most the common factor's range; with one common factor over 0.5-1.5 it
    raises it far more (the failure of the re-plan on study seed 11)."""
    from robovib.io.cuts import MeasuredCuts
    from robovib.milling.cut_posterior import update_with_cuts

    a = 4e-3
    st = _known_limits([a])
    cut = MeasuredCuts(np.full(3, 2000.0), np.full(3, 4.5e-3), np.zeros(3, bool),
                       np.tile([2400.0, 0.0, 45.0], (3, 1)))  # fmt: skip
    split = update_with_cuts(st, cut, TOOL, COND, ALUMINIUM_7075, label_noise=0.1,
                             local_factor=LOCAL)  # fmt: skip
    whole = update_with_cuts(st, cut, TOOL, COND, ALUMINIUM_7075, label_noise=0.1)

    def allowed(upd, loc):
        lim = upd.structures.limits([[2300.0, 100.0, 0.0]], [1500.0], TOOL, COND, ALUMINIUM_7075)[
            :, 0, 0
        ]
        w0, w1 = upd.prior_weights, upd.structures.weights
        if loc is None:
            from robovib.milling.cut_posterior import weighted_quantile

            return [float(weighted_quantile(lim, w, 0.05)) for w in (w0, w1)]
        return [float(local_quantile(lim, w, 0.05, loc)) for w in (w0, w1)]

    s0, s1 = allowed(split, LOCAL)
    w0, w1 = allowed(whole, None)
    assert 1.0 < s1 / s0 <= 1.1 / 0.9 + 1e-9
    assert w1 / w0 > 1.8


def test_plan_from_split_structures_claims_what_its_rows_give(tmp_path):
    """A plan from split structures: at each segment's depth allowed, P(stable) by Monte-Carlo
    draws of the local factor over the weighted rows is the required one; the CLI re-plan uses
    the split by default and ``--local-factor none`` restores one common factor."""
    from robovib.gp.chapter3_model import workspace_predictor
    from robovib.io.cuts import MeasuredCuts
    from robovib.milling.cut_posterior import update_with_cuts
    from robovib.milling.planning import plan_path
    from robovib.milling.structures import sample_structures

    model = workspace_predictor(None, seed=0, require_inputs=("x_mm", "y_mm", "rz_deg"))
    st = sample_structures(model, 16, rng=3)
    cuts = MeasuredCuts(np.array([2000.0, 2500.0]), np.array([2e-3, 6e-3]),
                        np.array([False, True]), np.array([[2300.0, 0.0, 40.0],
                                                           [2500.0, 200.0, 100.0]]))  # fmt: skip
    upd = update_with_cuts(st, cuts, TOOL, COND, ALUMINIUM_7075, n_factors=8, local_factor=LOCAL)
    plan = plan_path(upd.structures, [[2200, -100], [2600, 400]], TOOL, COND, ALUMINIUM_7075,
                     n_segments=4, rpm_range=(1500, 3000), n_speeds=4, rz_step_deg=60,
                     vibration_samples=0, p_required=0.9, max_depth_m=0.05)  # fmt: skip
    seg = np.arange(4)
    rz = np.asarray(plan.settings["rz_grid_deg"])
    rpm = np.asarray(plan.settings["rpm_grid"])
    ri = np.searchsorted(rz, plan.rz_deg)
    ji = np.searchsorted(rpm, plan.spindle_rpm)
    lim = plan.limits_m[:, seg, ri, ji]  # (R, 4) the rows' limits at the chosen configurations
    rng = np.random.default_rng(0)
    w = upd.structures.weights
    n = 200_000
    rows = rng.choice(w.size, n, p=w)
    r = stats.loguniform(*LOCAL).rvs(n, random_state=rng)
    for i in seg:
        mc = np.mean(lim[rows, i] * r > plan.depth_m[i])
        if plan.depth_m[i] < 0.05 * (1 - 1e-6):  # not capped by the tool
            assert mc == pytest.approx(0.9, abs=5e-3)
        assert plan.p_stable[i] == pytest.approx(mc, abs=5e-3)
        assert plan.p_stable[i] >= 0.9 - 1e-9
    assert "local factor" in plan.settings["method"]

    from typer.testing import CliRunner

    from robovib.cli import app

    f = tmp_path / "cuts.csv"
    f.write_text("x_mm,y_mm,rz_deg,spindle_rpm,depth_mm,result\n2300,0,40,2000,2,stable\n")
    args = ["mill", "plan", "--start", "2200,-100", "--end", "2600,400", "--segments", "3",
            "--samples", "8", "--rpm-range", "1500:3000:3", "--cuts", str(f), "--json"]  # fmt: skip
    run = CliRunner()
    out = run.invoke(app, args)
    assert out.exit_code == 0, out.output
    doc = json.loads(out.output)
    assert doc["result_settings"]["structures"]["local_factor_range"] == list(LOCAL)
    assert doc["result_settings"]["structures"]["process_factor_range"] == [0.9, 1.1]
    assert doc["test_cuts"]["settings"]["local_factor_range"] == list(LOCAL)
    out = run.invoke(app, [*args, "--local-factor", "none"])
    assert out.exit_code == 0, out.output
    doc = json.loads(out.output)
    assert "local_factor_range" not in doc["result_settings"]["structures"]
    assert "local factor" not in doc["result_settings"]["method"]
