"""Test cuts update the forecast of ``mill lobes`` and ``mill map`` (issue 39, cut_forecast)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from robovib.io.cuts import MeasuredCuts, read_cuts_csv
from robovib.milling import ALUMINIUM_7075, CuttingConditions, MillingTool
from robovib.milling.cut_forecast import add_cut_forecast, cuts_at_pose, forecast_with_cuts
from robovib.milling.structures import StructureSamples

TOOL = MillingTool()
COND = CuttingConditions(1750.0, 0.058e-3, 1e-3, 6e-3)
A0_M = 2e-3  # the family's limit at process factor 1, at every pose and speed


class _Family(StructureSamples):
    """A 1-parameter family of structures: limit = q_s * A0_M everywhere (known limits)."""

    def limits(self, poses, spindle_rpm, *args, **kwargs):
        shape = (np.atleast_2d(poses).shape[0], np.atleast_1d(spindle_rpm).size)
        return self.process_factor[:, None, None] * A0_M * np.ones(shape)[None]


def _family(n):
    q = np.linspace(0.5, 1.5, n)
    return _Family(None, np.full(n, 1.0 / n), q, (1.0, 1.0, 1.0), np.zeros((1, 1, 3)),
                   np.zeros((1, 1)), np.zeros((n, 1, 1)))  # fmt: skip


@pytest.mark.parametrize("eps", [1e-9, 0.1])
def test_weighted_forecast_equals_the_count_of_structures_a_cut_leaves(eps):
    """A chatter cut at 1.005 x A0 rules out the structures with q > 1.005 (21 of 41): the
    weighted P(stable), median and ESS are the label-noise-weighted counts (closed form)."""
    st = _family(41)
    q = st.process_factor
    cut = MeasuredCuts(np.array([2000.0]), np.array([1.005 * A0_M]), np.array([True]),
                       np.array([[2400.0, 0.0, 45.0]]))  # fmt: skip
    fc = forecast_with_cuts(None, [[2300.0, 100.0, 0.0]], [1500.0, 2000.0], cut, TOOL, COND,
                            ALUMINIUM_7075, structures=st, label_noise=eps,
                            n_factors=None)  # fmt: skip
    kept = q * A0_M <= 1.005 * A0_M
    assert kept.sum() == 21
    like = np.where(kept, 1 - eps, eps)  # P(chatter | structure)
    for depth in (0.8 * A0_M, 1.3 * A0_M, 1.6 * A0_M):
        expected = np.sum(like * (q * A0_M > depth)) / like.sum()
        np.testing.assert_allclose(fc.p_stable(depth), expected, rtol=1e-12)
        np.testing.assert_allclose(fc.p_stable(depth, posterior=False), np.mean(q * A0_M > depth))
    w = like / like.sum()
    assert fc.update.effective_sample_size == pytest.approx(1.0 / np.sum(w**2))
    if eps < 1e-6:  # the survivors alone: their median (21 of them, no tie at one half)
        np.testing.assert_allclose(fc.quantile_m(0.5), np.median(q[kept]) * A0_M)
        np.testing.assert_allclose(fc.quantile_m(0.5, posterior=False), np.median(q) * A0_M)
        assert fc.median_shift_rel() == pytest.approx(np.median(q[kept]) / np.median(q) - 1)
    # the chart's view of the same forecast (speeds x depths), weights kept
    from robovib.milling.lobes import LobeEnvelope

    env = LobeEnvelope(
        fc.spindle_rpm, np.full(2, A0_M), np.full(2, 500.0), np.full(2, "hopf"), "zoa"
    )
    prob = fc.stability_probability(env)
    assert prob.p_stable_at(1750.0, 1.3 * A0_M) == pytest.approx(
        float(fc.p_stable(1.3 * A0_M)[0, 0])
    )
    np.testing.assert_allclose(prob.depth_quantile_m(0.5), fc.quantile_m(0.5)[0])
    np.testing.assert_allclose(prob.p_unconditionally_stable([1.3 * A0_M]),
                               fc.p_stable(1.3 * A0_M)[0, :1])  # fmt: skip


def test_cuts_without_poses_are_taken_at_the_charts_pose():
    cuts = MeasuredCuts(np.array([1500.0, 1800.0]), np.array([1e-3, 2e-3]), np.array([0, 1], bool))
    at = cuts_at_pose(cuts, (2400.0, 0.0, 45.0))
    np.testing.assert_array_equal(at.pose_mm_deg, [[2400, 0, 45]] * 2)
    assert cuts_at_pose(at, (0.0, 0.0, 0.0)) is at  # cuts with poses keep theirs
    with pytest.raises(ValueError, match="x_mm, y_mm, rz_deg"):
        cuts_at_pose(cuts)


@pytest.fixture(scope="module")
def model():
    from robovib.gp.chapter3_model import workspace_predictor

    return workspace_predictor(None, seed=0, require_inputs=("x_mm", "y_mm", "rz_deg"))


def test_lobes_and_map_use_one_posterior(model, tmp_path):
    """The chart at a pose and the map at the same grid pose give the same posterior, and the
    chart's P(stable) at a cut's own speed and depth is the update's posterior for that cut."""
    from robovib.milling.chart import lobes_chart
    from robovib.milling.maps import workspace_lobe_map

    pose = (2400.0, 100.0, 45.0)
    rpm = np.linspace(1500.0, 2500.0, 11)
    path = tmp_path / "cuts.csv"  # no pose columns: at the chart's pose
    path.write_text("spindle_rpm,depth_mm,result\n1700,5.0,chatter\n2100,4.0,stable\n")
    chart = lobes_chart(tool=TOOL, conditions=COND, coefficients=ALUMINIUM_7075, spindle_rpm=rpm,
                        method="zoa", pose_model=model, pose=pose, n_samples=48, rng=1,
                        cuts=read_cuts_csv(path), operating_point=(1700.0, 5e-3))  # fmt: skip
    fc = chart.cut_forecast
    upd = fc.update
    assert upd.effective_sample_size < 48 and upd.information_nats > 0
    p_cut = [
        chart.probability.p_stable_at(r, d) for r, d in zip([1700, 2100], [5e-3, 4e-3], strict=True)
    ]
    np.testing.assert_allclose(p_cut, upd.p_stable_posterior, atol=1e-12)
    # the chatter cut lowered P(stable) at its point, the stable one raised it
    assert upd.p_stable_posterior[0] < upd.p_stable_prior[0]
    assert upd.p_stable_posterior[1] > upd.p_stable_prior[1]
    doc = chart.to_dict()
    assert doc["operating_point"]["p_stable"] == pytest.approx(upd.p_stable_posterior[0])
    assert doc["operating_point"]["p_stable_before_cuts"] == pytest.approx(upd.p_stable_prior[0])
    assert doc["test_cuts"]["effective_sample_size"] == pytest.approx(upd.effective_sample_size)
    np.testing.assert_allclose(doc["probability"]["a_lim_p50_m"], fc.quantile_m(0.5)[0])
    # the map over a grid through the chart's pose, with the same cuts (poses now explicit)
    ds = workspace_lobe_map(model, [2300.0, 2400.0], [100.0, 300.0], [45.0], rpm, TOOL, COND,
                            ALUMINIUM_7075, method="zoa", scheduler="sync")  # fmt: skip
    ds, mfc = add_cut_forecast(ds, model, cuts_at_pose(chart.cuts, pose), TOOL, COND,
                               ALUMINIUM_7075, n_samples=48, rng=1, depth_m=4e-3)  # fmt: skip
    np.testing.assert_allclose(mfc.update.structures.weights, upd.structures.weights)
    at = {"x_mm": 2400.0, "y_mm": 100.0, "rz_deg": 45.0}
    np.testing.assert_allclose(ds["a_lim_p50_m"].sel(at).values, fc.quantile_m(0.5)[0])
    np.testing.assert_allclose(ds["p_stable"].sel(at).values, fc.p_stable(4e-3)[0])
    np.testing.assert_allclose(ds["p_stable_before_cuts"].sel(at).values,
                               fc.p_stable(4e-3, posterior=False)[0])  # fmt: skip
    assert json.loads(ds.attrs["test_cuts"])["n_cuts"] == 2
    # the chart draws only the cuts made at its own pose
    import matplotlib

    matplotlib.use("Agg")
    from robovib.milling.chart import plot_lobes_chart

    elsewhere = tmp_path / "elsewhere.csv"
    elsewhere.write_text("x_mm,y_mm,rz_deg,spindle_rpm,depth_mm,result\n"
                         "2400,100,45,1700,5.0,chatter\n2300,300,45,2100,4.0,stable\n")  # fmt: skip
    other = lobes_chart(tool=TOOL, conditions=COND, coefficients=ALUMINIUM_7075, spindle_rpm=rpm,
                        method="zoa", pose_model=model, pose=pose, n_samples=8, cuts=read_cuts_csv(elsewhere))  # fmt: skip
    drawn = {ln.get_label(): ln.get_xdata().size for ln in plot_lobes_chart(other).axes[0].lines}
    assert drawn["cut: chatter"] == 1 and drawn["cut: stable"] == 0
    with pytest.raises(ValueError, match="poses"):
        add_cut_forecast(ds, model, chart.cuts, TOOL, COND, ALUMINIUM_7075)
    with pytest.raises(ValueError, match="time-domain margin"):
        lobes_chart(tool=TOOL, conditions=COND, coefficients=ALUMINIUM_7075, spindle_rpm=rpm,
                    method="zoa", pose_model=model, pose=pose, n_samples=8, cuts=read_cuts_csv(path),
                    time_domain_margin=True)  # fmt: skip


def test_cli_lobes_and_map_print_the_update(tmp_path):
    from typer.testing import CliRunner

    from robovib.cli import app

    cuts = tmp_path / "cuts.csv"
    cuts.write_text("x_mm,y_mm,rz_deg,spindle_rpm,depth_mm,result\n"
                    "2400,100,45,1700,5.0,chatter\n2300,300,45,2100,4.0,stable\n")  # fmt: skip
    lobes = ["mill", "lobes", "--x", "2400", "--y", "100", "--rz", "45", "--method", "zoa",
             "--rpm-range", "1500:2500:11", "--samples", "24", "--cuts", str(cuts)]  # fmt: skip
    res = CliRunner().invoke(app, [*lobes, "--operating-point", "1700,5"])
    assert res.exit_code == 0, res.output
    assert "test cuts: 2 (label noise 0.05): effective sample size 24 ->" in res.output
    assert "at this pose" in res.output and "before the test cuts" in res.output
    res = CliRunner().invoke(app, [*lobes, "--json", "--label-noise", "0.2"])
    doc = json.loads(res.output)
    assert doc["test_cuts"]["label_noise"] == 0.2 and doc["test_cuts"]["n_cuts"] == 2
    mp = ["mill", "map", "--rz", "45", "--nx", "2", "--ny", "2", "--rpm", "1700"]
    res = CliRunner().invoke(app, [*mp, "--samples", "24", "--depth", "4", "--cuts", str(cuts)])
    assert res.exit_code == 0, res.output
    assert "test cuts: 2" in res.output and "over the map" in res.output
    # bad input: clear errors
    res = CliRunner().invoke(app, [*mp, "--cuts", str(cuts)])
    assert res.exit_code != 0 and "--samples" in res.output
    no_pose = tmp_path / "no_pose.csv"
    no_pose.write_text("spindle_rpm,depth_mm,result\n1700,5.0,chatter\n")
    res = CliRunner().invoke(app, [*mp, "--samples", "8", "--cuts", str(no_pose)])
    assert res.exit_code != 0 and "x_mm, y_mm, rz_deg" in res.output
    bad = tmp_path / "bad.csv"
    bad.write_text("x_mm,y_mm,rz_deg,spindle_rpm,depth_mm,result\n2400,100,45,1700,5.0,maybe\n")
    for cmd in (lobes[:-1], [*mp, "--samples", "8", "--cuts"]):
        res = CliRunner().invoke(app, [*cmd, str(bad)])
        assert res.exit_code != 0 and "line 2" in res.output and "maybe" in res.output
    half = tmp_path / "half.csv"
    half.write_text("x_mm,spindle_rpm,depth_mm,result\n2400,1700,5.0,chatter\n")
    res = CliRunner().invoke(app, [*lobes[:-1], str(half)])
    assert res.exit_code != 0 and "give all of x_mm, y_mm, rz_deg" in res.output
