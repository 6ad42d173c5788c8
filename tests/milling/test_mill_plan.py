"""Path planning, sampled structures and test-cut updating (issue 39)."""

from __future__ import annotations

import itertools
import json

import numpy as np
import pytest

from robovib.milling import ALUMINIUM_7075, CuttingConditions, MillingTool
from robovib.milling.cut_posterior import (
    choose_test_cuts,
    p_stable,
    update_with_cuts,
    weighted_quantile,
)
from robovib.milling.structures import sample_structures, zoa_limits
from robovib.modal import ModalParameters

TOOL = MillingTool()
COND = CuttingConditions(1750.0, 0.058e-3, 1e-3, 6e-3)


@pytest.fixture(scope="module")
def model():
    from robovib.gp.chapter3_model import workspace_predictor

    return workspace_predictor(None, seed=0, require_inputs=("x_mm", "y_mm", "rz_deg"))


@pytest.mark.parametrize("n_x_modes", [1, 2])
def test_batched_zoa_matches_the_zero_order_lobes(n_x_modes):
    from robovib.milling.lobes import zoa_envelope
    from robovib.milling.stability import stability_lobes

    mx = [ModalParameters(16.0, 4e6, 0.11), ModalParameters(63.0, 5e6, 0.05)][:n_x_modes]
    my = [ModalParameters(8.0, 1.1e6, 0.18)]
    rpm = np.linspace(800, 4000, 17)
    ref = zoa_envelope(
        stability_lobes(mx, my, TOOL, COND, ALUMINIUM_7075, n_lobes=30, n_frequencies=20000), rpm
    ).a_lim_m
    ms = mx + my
    fn = np.array([m.natural_frequency_hz for m in ms])
    k = np.array([m.stiffness_n_per_m for m in ms])
    z = np.array([m.damping_ratio for m in ms])
    feed = np.arange(len(ms)) < len(mx)
    got = zoa_limits(np.stack([fn, fn]), k, z, feed, rpm, TOOL, COND, ALUMINIUM_7075)
    np.testing.assert_allclose(got[0], ref, rtol=0.015)  # the default grid's error
    np.testing.assert_array_equal(got[0], got[1])
    fine = zoa_limits(fn, k, z, feed, rpm, TOOL, COND, ALUMINIUM_7075, points_per_decade=800)
    np.testing.assert_allclose(fine, ref, rtol=0.003)  # and it converges
    with pytest.raises(ValueError, match="zeta"):
        zoa_limits(fn, k, z * 0, feed, rpm, TOOL, COND, ALUMINIUM_7075)


def test_weighted_quantile_and_p_stable_against_numpy():
    rng = np.random.default_rng(0)
    lim = rng.uniform(1, 5, (40, 3))
    w = np.full(40, 1 / 40)
    for q in (0.037, 0.49, 0.81):  # off the 1/40 grid (on it, numpy takes the lower one)
        np.testing.assert_array_equal(
            weighted_quantile(lim, w, q), np.quantile(lim, q, axis=0, method="inverted_cdf")
        )
    np.testing.assert_allclose(p_stable(lim, w, 2.5), np.mean(lim > 2.5, axis=0))
    # weights: a structure of weight 0 does not count
    w2 = np.r_[np.zeros(20), np.full(20, 1 / 20)]
    np.testing.assert_allclose(p_stable(lim, w2, 2.5), np.mean(lim[20:] > 2.5, axis=0))


def test_most_informative_cuts_split_the_structures_differently():
    # 8 structures; candidates 0 and 1 split them the same way, 2 splits them across
    lim = np.array([[1, 1, 1], [1, 1, 1], [1, 1, 3], [1, 1, 3],
                    [3, 3, 1], [3, 3, 1], [3, 3, 3], [3, 3, 3]], float)  # fmt: skip
    lim[:, 1] += 1e-3  # candidate 1: the same split, a hair apart
    idx, depth = choose_test_cuts(lim, np.full(8, 1 / 8), 2)
    assert set(idx) == {0, 2} or set(idx) == {1, 2}
    assert np.all((depth >= 1) & (depth <= 3.001))
    with pytest.raises(ValueError, match="n_cuts"):
        choose_test_cuts(lim, np.full(8, 1 / 8), 4)


def test_structures_keep_the_model_marginals_and_correlate_over_the_pose(model):
    st = sample_structures(model, 1500, rng=1, process_factor=(1.0, 1.0))
    pose = np.array([[2400.0, 0.0, 45.0]])
    fn, _, _, in_feed = st.modes(pose, "x")
    pred = model.predictive(pose)
    i = list(pred.output_names).index("x_fn_hz")
    draws = fn[:, 0, np.flatnonzero(in_feed)[0]]
    # the low component's Student-t quantiles (a few draws take the rare high mode: the mixture)
    from scipy.stats import t as student_t

    mu, scale = pred.mean[0, i, 0], pred.component_scale("latent")[0, i, 0]
    dof = pred.dof[i, 0]
    for q in (0.1, 0.5, 0.9):
        expect = mu + scale * (student_t.ppf(q, dof) if np.isfinite(dof) else student_t.ppf(q, 1e9))
        assert np.quantile(draws, q) == pytest.approx(expect, abs=0.12 * scale)
    high = np.mean(draws > 40)
    assert (
        high <= pred.high_probability[0, i] + 4 * np.sqrt(pred.high_probability[0, i] / 1500) + 1e-3
    )
    # correlation of the fields over one correlation length in X: exp(-1/2)
    z = st.fields(np.array([[2400.0, 0.0, 45.0], [2400.0 + st.correlation_length[0], 0.0, 45.0]]))
    r = np.mean([np.corrcoef(z[:, 0, c], z[:, 1, c])[0, 1] for c in range(z.shape[2])])
    assert r == pytest.approx(np.exp(-0.5), abs=0.06)


def test_test_cuts_from_one_structure_pull_the_forecast_towards_it(model):
    from robovib.io.cuts import MeasuredCuts

    st = sample_structures(model, 96, rng=2)
    rng = np.random.default_rng(3)
    poses = np.column_stack([rng.uniform(2150, 2650, 12), rng.uniform(-250, 550, 12),
                             rng.uniform(0, 180, 12)])  # fmt: skip
    rpm = 2000.0
    lim = st.limits(poses, [rpm], TOOL, COND, ALUMINIUM_7075)[:, :, 0]  # (S, 12)
    true = int(np.argmin(np.abs(st.process_factor - np.quantile(st.process_factor, 0.85))))
    # 8 cuts labelled by the "true" structure, at the prior median depth; 4 poses held out
    depth = weighted_quantile(lim, st.weights, 0.5)
    cuts = MeasuredCuts(np.full(8, rpm), depth[:8], depth[:8] >= lim[true, :8], poses[:8])
    upd = update_with_cuts(
        st, cuts, TOOL, COND, ALUMINIUM_7075, label_noise=0.05, n_factors=None
    )  # each structure its own drawn factor
    err0 = np.abs(weighted_quantile(lim[:, 8:], st.weights, 0.5) / lim[true, 8:] - 1).mean()
    err1 = np.abs(weighted_quantile(lim[:, 8:], upd.structures.weights, 0.5) / lim[true, 8:] - 1)
    assert err1.mean() < 0.6 * err0
    assert upd.effective_sample_size < st.n_samples
    assert upd.information_nats > 0
    # every cut's posterior P(stable) moved towards its label
    moved = np.where(cuts.chatter, upd.p_stable_posterior <= upd.p_stable_prior + 1e-12,
                     upd.p_stable_posterior >= upd.p_stable_prior - 1e-12)  # fmt: skip
    assert moved.all()
    with pytest.raises(ValueError, match="label_noise"):
        update_with_cuts(st, cuts, TOOL, COND, ALUMINIUM_7075, label_noise=0.7)
    with pytest.raises(ValueError, match="no poses"):
        update_with_cuts(st, MeasuredCuts(cuts.spindle_rpm, cuts.depth_m, cuts.chatter), TOOL,
                         COND, ALUMINIUM_7075)  # fmt: skip


def test_plan_is_the_best_rz_sequence_under_the_rate_limit(model):
    from robovib.milling.planning import plan_path

    st = sample_structures(model, 24, rng=4)
    pts = [[2200.0, -100.0], [2600.0, 400.0]]
    kw = dict(n_segments=4, rpm_range=(1500.0, 3000.0), n_speeds=4, vibration_samples=0)
    rz = (0.0, 60.0, 120.0)
    rate = 60.0 / 160.0  # one 60° step per segment (length 160 mm)
    plan = plan_path(st, pts, TOOL, COND, ALUMINIUM_7075, rz_range_deg=(0, 120), rz_step_deg=60,
                     max_rz_rate_deg_per_mm=rate, **kw)  # fmt: skip
    assert np.all(np.abs(np.diff(plan.rz_deg)) <= 60 + 1e-9)
    # brute force over every (Rz, speed) sequence allowed: volume / time, the allowed depths
    # from the plan's limit table by NumPy's quantile (equal weights)
    rpm = np.asarray(plan.settings["rpm_grid"])
    allowed = np.minimum(
        np.quantile(plan.limits_m, 0.05, axis=0, method="inverted_cdf") * (1 - 1e-9), 0.02
    )  # (m, r, j)
    configs = list(itertools.product(range(3), range(4)))

    def brute(score_of):
        best = -1.0
        for seq in itertools.product(configs, repeat=4):
            if all(abs(rz[b[0]] - rz[a[0]]) <= 60 for a, b in itertools.pairwise(seq)):
                best = max(best, score_of(seq))
        return best

    def per_segment(seq):
        d = np.array([allowed[i, a, b] for i, (a, b) in enumerate(seq)])
        return np.sum(d * plan.length_mm) / np.sum(plan.length_mm / rpm[[b for _, b in seq]])

    def one_depth(seq):
        d = min(allowed[i, a, b] for i, (a, b) in enumerate(seq))
        return d * np.sum(plan.length_mm) / np.sum(plan.length_mm / rpm[[b for _, b in seq]])

    k = COND.radial_depth_m * COND.feed_per_tooth_m * TOOL.n_flutes / 60.0
    assert plan.mean_mrr_m3_per_s == pytest.approx(k * brute(per_segment), rel=1e-9)
    path = plan_path(st, pts, TOOL, COND, ALUMINIUM_7075, rz_range_deg=(0, 120), rz_step_deg=60,
                     max_rz_rate_deg_per_mm=rate, depth_rule="path", **kw)  # fmt: skip
    assert np.all(path.depth_m == path.depth_m[0])
    assert np.all(path.depth_m <= path.depth_allowed_m) and np.all(path.p_stable >= 0.95)
    assert path.mean_mrr_m3_per_s == pytest.approx(k * brute(one_depth), rel=1e-9)
    # the fixed comparisons: the same rules at one (Rz, speed), brute force
    fixed_seg = max(np.mean(allowed[:, a, b]) * rpm[b] for a, b in configs)  # equal lengths
    fixed_one = max(np.min(allowed[:, a, b]) * rpm[b] for a, b in configs)
    assert plan.fixed["mean_mrr_mm3_per_s"] == pytest.approx(k * fixed_seg * 1e9, rel=1e-9)
    assert path.fixed["mean_mrr_mm3_per_s"] == pytest.approx(k * fixed_one * 1e9, rel=1e-9)
    assert plan.fixed["one_depth"] == path.fixed["one_depth"]
    assert path.mean_mrr_m3_per_s * 1e9 >= path.fixed["mean_mrr_mm3_per_s"] * (1 - 1e-9)
    assert plan.mean_mrr_m3_per_s * 1e9 >= plan.fixed["mean_mrr_mm3_per_s"] * (1 - 1e-9)
    assert np.all(plan.p_stable >= 0.95)
    # a depth asked: P(stable) there reported, infeasible segments flagged
    asked = plan_path(st, pts, TOOL, COND, ALUMINIUM_7075, depth_m=2e-3, **kw)
    assert np.all(asked.depth_m == 2e-3)
    np.testing.assert_array_equal(asked.feasible, asked.p_stable_at_asked >= 0.95)
    with pytest.raises(ValueError, match="p_required"):
        plan_path(st, pts, TOOL, COND, ALUMINIUM_7075, p_required=1.0, **kw)
    with pytest.raises(ValueError, match="depth_rule"):
        plan_path(st, pts, TOOL, COND, ALUMINIUM_7075, depth_rule="pass", **kw)
    with pytest.raises(ValueError, match="repeats a point"):
        plan_path(st, [[2200.0, 0.0], [2200.0, 0.0], [2300.0, 0.0]], TOOL, COND,
                  ALUMINIUM_7075, vibration_samples=0)  # fmt: skip


def test_cuts_file_with_poses(tmp_path):
    from robovib.io.cuts import read_cuts_csv

    p = tmp_path / "cuts.csv"
    p.write_text("x_mm,y_mm,rz_deg,spindle_rpm,depth_mm,result\n2400,0,45,1750,2.0,stable\n")
    cuts = read_cuts_csv(p)
    np.testing.assert_array_equal(cuts.pose_mm_deg, [[2400.0, 0.0, 45.0]])
    assert cuts.depth_m[0] == pytest.approx(2e-3)
    p.write_text("x_mm,y_mm,spindle_rpm,depth_mm,result\n2400,0,1750,2.0,stable\n")
    with pytest.raises(ValueError, match="give all of x_mm, y_mm, rz_deg"):
        read_cuts_csv(p)


def test_cli_plan_suggest_update_replan(tmp_path):
    from typer.testing import CliRunner

    from robovib.cli import app

    run = CliRunner()
    cuts = tmp_path / "cuts.csv"
    args = ["mill", "plan", "--start", "2200,-100", "--end", "2600,400", "--segments", "6",
            "--samples", "24", "--rpm-range", "1500:3000:4"]  # fmt: skip
    out = run.invoke(app, [*args, "--suggest-cuts", str(cuts), "--n-suggest", "2",
                           "-o", str(tmp_path / "plan.csv"), "--json"])  # fmt: skip
    assert out.exit_code == 0, out.output
    doc = json.loads(out.output)
    assert len(doc["segments"]) == 6 and doc["units"]["depth_mm"] == "mm"
    lines = cuts.read_text().splitlines()
    assert lines[0] == "x_mm,y_mm,rz_deg,spindle_rpm,depth_mm,result" and len(lines) == 3
    # the machinist fills in the results, the plan is made again with them
    cuts.write_text("\n".join([lines[0], lines[1] + "stable", lines[2] + "chatter"]) + "\n")
    out = run.invoke(app, [*args, "--cuts", str(cuts), "--json"])
    assert out.exit_code == 0, out.output
    upd = json.loads(out.output)["test_cuts"]
    assert upd["n_cuts"] == 2 and upd["effective_sample_size"] < 24
    out = run.invoke(app, ["mill", "plan", "--segments", "6"])
    assert out.exit_code == 1 and "give a tool path" in out.output


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_choose_configurations_is_the_brute_force_optimum(seed):
    """Random depth tables: the planner's choice against every (Rz, speed) sequence."""
    from robovib.milling.planning import choose_configurations, fixed_configuration

    rng = np.random.default_rng(seed)
    m, rz, rpm = 4, np.array([0.0, 30.0, 60.0]), np.array([1000.0, 1800.0, 3000.0])
    allowed = rng.uniform(0.5e-3, 5e-3, (m, rz.size, rpm.size))
    length = rng.uniform(20.0, 40.0, m)
    rate = 1.1 * 30.0 / length.min()  # one 30° step between segments, never two
    configs = list(itertools.product(range(rz.size), range(rpm.size)))
    best = {"segment": -1.0, "path": -1.0}
    for seq in itertools.product(configs, repeat=m):
        if any(abs(rz[b[0]] - rz[a[0]]) > 30 for a, b in itertools.pairwise(seq)):
            continue
        d = np.array([allowed[i, a, b] for i, (a, b) in enumerate(seq)])
        t = np.sum(length / rpm[[b for _, b in seq]])
        best["segment"] = max(best["segment"], np.sum(d * length) / t)
        best["path"] = max(best["path"], d.min() * length.sum() / t)
    for rule in ("segment", "path"):
        ch = choose_configurations(allowed, rz, rpm, length, max_rz_rate_deg_per_mm=rate,
                                   depth_rule=rule)  # fmt: skip
        assert np.all(np.abs(np.diff(rz[ch.rz_index])) <= 30)
        assert np.all(ch.depth_m <= allowed[np.arange(m), ch.rz_index, ch.speed_index])
        t = np.sum(length / rpm[ch.speed_index])
        assert np.sum(ch.depth_m * length) / t == pytest.approx(best[rule], rel=1e-12)
        assert ch.score == pytest.approx(best[rule], rel=1e-12)
        fixed = fixed_configuration(allowed, rz, rpm, length, depth_rule=rule)
        one = (allowed.min(axis=0) if rule == "path" else
               np.einsum("i,irj->rj", length, allowed) / length.sum()) * rpm  # fmt: skip
        assert fixed["score"] == pytest.approx(one.max(), rel=1e-12)
        assert ch.score >= fixed["score"] * (1 - 1e-12)
    # no Rz change allowed: every segment at one Rz
    ch = choose_configurations(allowed, rz, rpm, length, max_rz_rate_deg_per_mm=0.0)
    assert np.unique(ch.rz_index).size == 1
    with pytest.raises(ValueError, match="allowed_m"):
        choose_configurations(allowed[:, :2], rz, rpm, length, max_rz_rate_deg_per_mm=1.0)
    with pytest.raises(ValueError, match="finite"):
        choose_configurations(np.full(allowed.shape, np.inf), rz, rpm, length,
                              max_rz_rate_deg_per_mm=1.0)  # fmt: skip


def test_cli_plan_one_depth_for_the_path():
    from typer.testing import CliRunner

    from robovib.cli import app

    run = CliRunner()
    args = ["mill", "plan", "--start", "2200,-100", "--end", "2600,400", "--segments", "5",
            "--samples", "16", "--rpm-range", "1500:3000:3", "--json"]  # fmt: skip
    out = run.invoke(app, [*args, "--depth-rule", "path"])
    assert out.exit_code == 0, out.output
    doc = json.loads(out.output)
    depths = {round(s["depth_mm"], 9) for s in doc["segments"]}
    assert len(depths) == 1 and doc["settings"]["depth_rule"] == "path"
    # compared with one fixed Rz, speed and depth: the same rule
    assert doc["fixed"]["mean_mrr_mm3_per_s"] == doc["fixed"]["one_depth"]["mean_mrr_mm3_per_s"]
    assert doc["gain_over_fixed"] >= 1 - 1e-9
    out = run.invoke(app, [*args, "--depth-rule", "pass"])
    assert out.exit_code == 1 and "depth_rule" in out.output


def test_choose_configurations_at_a_depth_asked():
    """A depth asked: the feasible sequences' best MRR (brute force); a segment with nothing
    feasible takes its configuration of highest P(stable)."""
    from robovib.milling.planning import choose_configurations

    rng = np.random.default_rng(5)
    m, rz, rpm = 4, np.array([0.0, 30.0, 60.0]), np.array([1000.0, 1800.0, 3000.0])
    length = rng.uniform(20.0, 40.0, m)
    p_at = rng.uniform(0.5, 1.0, (m, rz.size, rpm.size))
    p_at[:, :, 0] = 0.99  # the slowest speed is always feasible
    allowed = np.full(p_at.shape, 5e-3)
    kw = dict(max_rz_rate_deg_per_mm=1e3, depth_m=2e-3, p_required=0.95)
    ch = choose_configurations(allowed, rz, rpm, length, p_stable_at_depth=p_at, **kw)
    seg = np.arange(m)
    assert np.all(p_at[seg, ch.rz_index, ch.speed_index] >= 0.95)
    # every segment on its own (no rate limit): the fastest feasible speed
    fastest = np.where(p_at >= 0.95, rpm, 0).max(axis=(1, 2))
    np.testing.assert_array_equal(rpm[ch.speed_index], fastest)
    np.testing.assert_array_equal(ch.depth_m, 2e-3)
    # segment 2 has nothing feasible: the configuration of highest P(stable) there
    p_bad = p_at.copy()
    p_bad[2] = rng.uniform(0.3, 0.9, (rz.size, rpm.size))
    ch = choose_configurations(allowed, rz, rpm, length, p_stable_at_depth=p_bad, **kw)
    assert p_bad[2, ch.rz_index[2], ch.speed_index[2]] == p_bad[2].max()
    keep = seg != 2
    assert np.all(p_bad[seg[keep], ch.rz_index[keep], ch.speed_index[keep]] >= 0.95)
    np.testing.assert_array_equal(rpm[ch.speed_index[keep]], fastest[keep])
    with pytest.raises(ValueError, match="p_stable_at_depth"):
        choose_configurations(allowed, rz, rpm, length, **kw)
