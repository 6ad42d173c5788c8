"""``mill lobes --cuts`` and ``mill map --cuts`` use the re-plan's factor split (issue 39): a
learnt common factor x a local factor drawn afresh at every point, P(stable) in the smooth
per-row form, checked against ``update_with_cuts`` + Monte Carlo over rows and local factors.
The points checked here are away from the cuts (a cut's own point shares its local factor:
``test_same_point.py``)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy import stats
from typer.testing import CliRunner

from robovib.cli import app
from robovib.io.cuts import read_cuts_csv
from robovib.milling.cut_posterior import update_with_cuts

LOCAL, COMMON = (0.55, 1.3), (0.9, 1.1)
POSE = (2400.0, 100.0, 45.0)
CUTS = ("x_mm,y_mm,rz_deg,spindle_rpm,depth_mm,result\n"
        "2400,100,45,1600,5.0,chatter\n2300,300,45,2100,4.0,stable\n")  # fmt: skip
LOBES = ["mill", "lobes", "--x", "2400", "--y", "100", "--rz", "45", "--method", "zoa",
         "--rpm-range", "1500:2500:11", "--samples", "24"]  # fmt: skip


def _cutting():
    from robovib.cli import _mill_options as opt
    from robovib.cli._common import material

    return opt.cutting(material("al7075"), None, None, 25.4, 2, 30.0, 6.0, None, "down")


def _posterior(path, local_factor):
    """The re-plan's posterior (``mill plan --cuts``): the same structures and cuts."""
    from robovib.cli._common import workspace_model
    from robovib.milling.structures import sample_structures

    tool, cond, coef = _cutting()
    structures = sample_structures(workspace_model(None, 0), 24, rng=0)
    upd = update_with_cuts(structures, read_cuts_csv(path), tool, cond, coef, feed_direction="x",
                           label_noise=0.05, local_factor=local_factor,
                           common_factor=COMMON)  # fmt: skip
    return upd, (tool, cond, coef)


def _monte_carlo(weights, limits_m, depth_m, n=400_000, seed=1):
    """P(rho a_r > d): rows drawn by their weights, rho log-uniform on LOCAL (per point)."""
    rng = np.random.default_rng(seed)
    rows = rng.choice(weights.size, n, p=weights / weights.sum())
    rho = stats.loguniform(*LOCAL).rvs(n, random_state=rng)
    return float(np.mean(rho * limits_m[rows] > depth_m))


def test_lobes_cuts_p_stable_is_the_replans_posterior(tmp_path):
    cuts = tmp_path / "cuts.csv"
    cuts.write_text(CUTS)
    upd, cutting = _posterior(cuts, LOCAL)
    st = upd.structures
    lim = st.limits(np.array([POSE]), [1700.0], *cutting, feed_direction="x")[:, 0, 0]
    w = st.weights
    # a depth where the forecast is uncertain: the prior's median limit there
    depth_m = float(np.median(lim))
    op = f"1700,{depth_m * 1e3!r}"
    res = CliRunner().invoke(app, [*LOBES, "--cuts", str(cuts), "--operating-point", op, "--json"])
    assert res.exit_code == 0, res.output
    doc = json.loads(res.output)
    p_cli = doc["operating_point"]["p_stable"]
    mc = _monte_carlo(w, lim, depth_m)
    assert 0.1 < mc < 0.9  # not a trivial point
    assert p_cli == pytest.approx(mc, abs=3e-3)
    before = _monte_carlo(upd.prior_weights, lim, depth_m, seed=2)
    assert doc["operating_point"]["p_stable_before_cuts"] == pytest.approx(before, abs=3e-3)
    # the chart's median limit at 1700 rpm: P(stable) there is one half (Monte Carlo)
    j = int(np.flatnonzero(np.isclose(np.linspace(1500, 2500, 11), 1700))[0])
    a50 = doc["probability"]["a_lim_p50_m"][j]
    assert _monte_carlo(w, lim, a50, seed=3) == pytest.approx(0.5, abs=3e-3)
    assert doc["test_cuts"]["local_factor_range"] == list(LOCAL)
    assert doc["test_cuts"]["common_factor_range"] == list(COMMON)
    assert doc["test_cuts"]["settings"]["local_factor_range"] == list(LOCAL)
    # the old behaviour: one common factor over the whole range, the step form
    res = CliRunner().invoke(app, [*LOBES, "--cuts", str(cuts), "--operating-point", op,
                                   "--json", "--local-factor", "none"])  # fmt: skip
    assert res.exit_code == 0, res.output
    old = json.loads(res.output)
    upd0, _ = _posterior(cuts, None)
    lim0 = upd0.structures.limits(np.array([POSE]), [1700.0], *cutting, feed_direction="x")
    step = float(np.sum(upd0.structures.weights * (lim0[:, 0, 0] > depth_m)))
    assert old["operating_point"]["p_stable"] == pytest.approx(step, abs=1e-12)
    assert "local_factor_range" not in old["test_cuts"]
    assert abs(step - p_cli) > 0.02  # the split is a different posterior


def test_map_cuts_p_stable_is_the_replans_posterior(tmp_path):
    import xarray as xr

    cuts = tmp_path / "cuts.csv"
    cuts.write_text(CUTS)
    out = tmp_path / "map.nc"
    args = ["mill", "map", "--rz", "45", "--nx", "2", "--ny", "2", "--rpm", "1700",
            "--samples", "24", "--depth", "4", "--cuts", str(cuts), "-o", str(out)]  # fmt: skip
    res = CliRunner().invoke(app, args)
    assert res.exit_code == 0, res.output
    with xr.open_dataset(out) as ds:
        p = ds["p_stable"].load()
        settings = json.loads(ds.attrs["settings"])
    assert settings["local_factor_range"] == list(LOCAL)
    assert settings["common_factor_range"] == list(COMMON)
    upd, cutting = _posterior(cuts, LOCAL)
    for x in p["x_mm"].values[:1]:
        for y in p["y_mm"].values:
            pose = np.array([[x, y, 45.0]])
            lim = upd.structures.limits(pose, [1700.0], *cutting, feed_direction="x")[:, 0, 0]
            mc = _monte_carlo(upd.structures.weights, lim, 4e-3)
            got = float(p.sel(x_mm=x, y_mm=y, rz_deg=45.0, spindle_rpm=1700.0))
            assert got == pytest.approx(mc, abs=3e-3)


@pytest.mark.parametrize(
    ("option", "value"),
    [("--local-factor", "1.3,0.55"), ("--local-factor", "0,1"), ("--local-factor", "a,b"),
     ("--common-factor", "1.1"), ("--common-factor", "-1,1.1"), ("--common-factor", "0.9,inf")],
)  # fmt: skip
def test_bad_factor_options_name_the_option(tmp_path, option, value):
    cuts = tmp_path / "cuts.csv"
    cuts.write_text(CUTS)
    mp = ["mill", "map", "--rz", "45", "--nx", "2", "--ny", "2", "--rpm", "1700", "--samples", "8"]
    for cmd in (LOBES, mp):
        res = CliRunner().invoke(app, [*cmd, "--cuts", str(cuts), option, value])
        assert res.exit_code != 0
        assert option in res.output, res.output


def test_lobes_and_replan_share_the_posterior(tmp_path):
    """``mill plan --cuts`` at one segment on the chart's pose and ``mill lobes --cuts`` give
    the same posterior: each equals ``local_p_stable`` of ``update_with_cuts``' rows on its own
    limits (the planner computes them at 200 points a decade, capped at the tool's 20 mm; the
    chart at 250), and the two agree to that resolution."""
    from robovib.milling.factor_grid import local_p_stable

    cuts = tmp_path / "cuts.csv"
    cuts.write_text(CUTS)
    run = CliRunner()
    res = run.invoke(app, [*LOBES, "--cuts", str(cuts), "--operating-point", "1700,5", "--json"])
    assert res.exit_code == 0, res.output
    p_lobes = json.loads(res.output)["operating_point"]["p_stable"]
    res = run.invoke(app, ["mill", "plan", "--start", "2390,100", "--end", "2410,100",
                           "--segments", "1", "--rz-range", "45:45", "--rpm-range", "1500:1700:2",
                           "--samples", "24", "--ap", "5", "--cuts", str(cuts), "--json"])  # fmt: skip
    assert res.exit_code == 0, res.output
    seg = json.loads(res.output)["segments"][0]
    assert (seg["x_mm"], seg["y_mm"], seg["rz_deg"], seg["spindle_rpm"]) == (*POSE, 1700.0)
    upd, cutting = _posterior(cuts, LOCAL)
    w = upd.structures.weights
    for p_cli, kw in ((p_lobes, {}), (seg["p_stable"], {"points_per_decade": 200.0,
                                                         "depth_cap_m": 0.02})):  # fmt: skip
        lim = upd.structures.limits(np.array([POSE]), [1500.0, 1700.0], *cutting,
                                    feed_direction="x", **kw)[:, 0, 1]  # fmt: skip
        assert p_cli == pytest.approx(float(local_p_stable(lim, w, 5e-3, LOCAL)), rel=1e-9)
    assert p_lobes == pytest.approx(seg["p_stable"], abs=1e-3)
