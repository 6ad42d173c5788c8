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
    # brute force over every Rz sequence allowed, from single-Rz plans (the same forecast)
    single = {a: plan_path(st, pts, TOOL, COND, ALUMINIUM_7075, rz_range_deg=(a, a), **kw)
              for a in rz}  # fmt: skip
    t = {a: single[a].length_mm / single[a].spindle_rpm for a in rz}
    best = max(
        sum(single[a].mrr_m3_per_s[i] * t[a][i] for i, a in enumerate(seq))
        for seq in itertools.product(rz, repeat=4)
        if all(abs(b - a) <= 60 for a, b in itertools.pairwise(seq))
    )
    got = np.sum(plan.mrr_m3_per_s * plan.length_mm / plan.spindle_rpm)
    assert got == pytest.approx(best, rel=1e-9)
    assert plan.mean_mrr_m3_per_s * 1e9 >= plan.fixed["mean_mrr_mm3_per_s"] * (1 - 1e-9)
    assert np.all(plan.p_stable >= 0.95)
    # a depth asked: P(stable) there reported, infeasible segments flagged
    asked = plan_path(st, pts, TOOL, COND, ALUMINIUM_7075, depth_m=2e-3, **kw)
    assert np.all(asked.depth_m == 2e-3)
    np.testing.assert_array_equal(asked.feasible, asked.p_stable_at_asked >= 0.95)
    with pytest.raises(ValueError, match="p_required"):
        plan_path(st, pts, TOOL, COND, ALUMINIUM_7075, p_required=1.0, **kw)
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
