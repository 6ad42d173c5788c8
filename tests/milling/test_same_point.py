"""A point that coincides with a test cut shares the cut's local factor (issue 39,
``robovib.milling.same_point``), checked against Monte Carlo with rejection: rows, local
factors and noisy labels drawn from the model, kept where the labels are the observed ones."""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy import stats
from typer.testing import CliRunner

from robovib.cli import app
from robovib.milling.same_point import (
    SamePointTolerance,
    matching_cuts,
    shared_local_p_stable,
    shared_local_quantile,
)

LOCAL, COMMON, EPS = (0.55, 1.3), (0.9, 1.1), 0.05
POSE = (2400.0, 100.0, 45.0)
LOBES = ["mill", "lobes", "--x", "2400", "--y", "100", "--rz", "45", "--method", "zoa",
         "--rpm-range", "1500:2500:11", "--samples", "24"]  # fmt: skip
CUTS = ("x_mm,y_mm,rz_deg,spindle_rpm,depth_mm,result\n"
        "2400,100,45,1700,5.0,chatter\n2300,300,45,2100,4.0,stable\n")  # fmt: skip


def _rejection(w0, point_lim, depth, groups, n=600_000, seed=0):
    """P(stable at depth | labels) by rejection. ``groups``: per local factor, a list of
    (limits (R,), depth, chatter) cuts sharing it; the first group is the point's."""
    rng = np.random.default_rng(seed)
    rows = rng.choice(w0.size, n, p=w0 / w0.sum())
    keep = np.ones(n, bool)
    point_l = None
    for g, cuts in enumerate(groups):
        lf = stats.loguniform(*LOCAL).rvs(n, random_state=rng)
        if g == 0:
            point_l = lf
        for lim, d, chatter in cuts:
            truth = lf * lim[rows] <= d
            flip = rng.random(n) < EPS
            keep &= (truth ^ flip) == chatter
    stable = point_l[keep] * point_lim[rows[keep]] > depth
    return float(stable.mean()), int(keep.sum())


def _exact_weights(w0, groups):
    """Row weights w0 prod_groups int prod_c P(label | l) p(l) dl (quadrature in log l)."""
    u = np.linspace(np.log(LOCAL[0]), np.log(LOCAL[1]), 200_001)
    u = 0.5 * (u[1:] + u[:-1])
    w = np.array(w0, float)
    for cuts in groups:
        like = np.ones((w.size, u.size))
        for lim, d, chatter in cuts:
            chat = np.exp(u)[None, :] * lim[:, None] <= d
            p = np.where(chat, 1 - EPS, EPS)
            like *= p if chatter else 1 - p
        w *= like.mean(axis=1)
    return w / w.sum()


def test_shared_factor_against_rejection_with_two_cuts_at_the_point():
    rng = np.random.default_rng(5)
    r = 6
    w0 = rng.random(r) + 0.2
    point = rng.uniform(3e-3, 6e-3, r)
    # two cuts at the point (slightly different limits: a speed within the tolerance)
    c1, c2 = point * rng.uniform(0.97, 1.03, r), point * rng.uniform(0.97, 1.03, r)
    elsewhere = rng.uniform(3e-3, 6e-3, r)
    here = [(c1, 4.0e-3, True), (c2, 3.0e-3, False)]
    groups = [here, [(elsewhere, 4.0e-3, False)]]
    w = _exact_weights(w0, groups)
    for depth in (2.5e-3, 3.5e-3, 4.5e-3):
        ref, kept = _rejection(w0, point, depth, groups)
        assert kept > 50_000
        got = shared_local_p_stable(point, w, [depth], np.stack([c1, c2], 1), [4.0e-3, 3.0e-3],
                                    [True, False], LOCAL, EPS)[0]  # fmt: skip
        assert got == pytest.approx(ref, abs=4e-3)
    # the quantile inverts it
    q50 = shared_local_quantile(point, w, 0.5, np.stack([c1, c2], 1), [4.0e-3, 3.0e-3],
                                [True, False], LOCAL, EPS)  # fmt: skip
    p = shared_local_p_stable(point, w, [q50], np.stack([c1, c2], 1), [4.0e-3, 3.0e-3],
                              [True, False], LOCAL, EPS)[0]  # fmt: skip
    assert p == pytest.approx(0.5, abs=1e-9)


def test_above_a_chattered_depth_only_label_noise_is_left():
    point = np.array([4e-3, 5e-3, 6e-3])
    w = np.full(3, 1 / 3)
    p = shared_local_p_stable(point, w, [5e-3, 6e-3], point[:, None], [5e-3], [True], LOCAL, EPS)
    assert np.all(p < 2 * EPS)
    # no lobe at the point: stable at any depth, whatever the cut said
    p = shared_local_p_stable(np.array([np.inf]), [1.0], [5e-3], np.array([[4e-3]]), [5e-3],
                              [True], LOCAL, EPS)  # fmt: skip
    assert p[0] == 1.0


def test_tolerance_is_the_documented_one():
    tol = SamePointTolerance()
    cut_pose, cut_rpm = np.array([[2400.0, 100.0, 45.0]]), np.array([1700.0])
    poses = np.array([[2400, 100, 45], [2404.9, 95.1, 45.9], [2405.1, 100, 45], [2400, 100, 46.1],
                      [2400, 100, 45 + 360]], float)  # fmt: skip
    m = matching_cuts(poses, [1700, 1708.4, 1708.6], cut_pose, cut_rpm, tol)[:, :, 0]
    assert m.tolist() == [[True, True, False], [True, True, False], [False] * 3, [False] * 3,
                          [True, True, False]]  # fmt: skip
    with pytest.raises(ValueError, match="speed_rel"):
        SamePointTolerance(speed_rel=-0.1)


def _cli_rows(path):
    from robovib.cli import _mill_options as opt
    from robovib.cli._common import material, workspace_model
    from robovib.io.cuts import read_cuts_csv
    from robovib.milling.cut_posterior import update_with_cuts
    from robovib.milling.structures import sample_structures

    cutting = opt.cutting(material("al7075"), None, None, 25.4, 2, 30.0, 6.0, None, "down")
    structures = sample_structures(workspace_model(None, 0), 24, rng=0)
    upd = update_with_cuts(structures, read_cuts_csv(path), *cutting, feed_direction="x",
                           label_noise=EPS, local_factor=LOCAL, common_factor=COMMON)  # fmt: skip
    st = upd.structures

    def lim(pose, rpm):
        return st.limits(np.array([pose]), [rpm], *cutting, feed_direction="x")[:, 0, 0]

    return upd.prior_weights, lim


def test_lobes_at_a_chattered_cut_against_rejection(tmp_path):
    """The issue's example: a chatter cut at 1700 rpm / 5 mm at the chart's pose."""
    cuts = tmp_path / "cuts.csv"
    cuts.write_text(CUTS)
    w0, lim = _cli_rows(cuts)
    at_cut = lim(POSE, 1700.0)
    groups = [[(at_cut, 5e-3, True)], [(lim((2300.0, 300.0, 45.0), 2100.0), 4e-3, False)]]
    run = CliRunner()
    for depth_mm, seed in ((5.0, 1), (4.0, 2), (3.5, 3)):
        res = run.invoke(app, [*LOBES, "--cuts", str(cuts), "--operating-point",
                               f"1700,{depth_mm}", "--json"])  # fmt: skip
        assert res.exit_code == 0, res.output
        doc = json.loads(res.output)
        ref, _ = _rejection(w0, at_cut, depth_mm * 1e-3, groups, seed=seed)
        assert doc["operating_point"]["p_stable"] == pytest.approx(ref, abs=4e-3)
        if depth_mm == 5.0:
            assert ref < 2 * EPS
            assert doc["operating_point"]["p_stable_before_cuts"] > 0.3
    tol = {"position_mm": 5.0, "rz_deg": 1.0, "speed_rel": 0.005}
    assert doc["test_cuts"]["same_point_tolerance"] == tol
    assert doc["test_cuts"]["settings"]["same_point_tolerance"] == tol
    # just outside the speed tolerance (0.5 % of 1700 = 8.5 rpm): a fresh local factor
    res = run.invoke(app, [*LOBES, "--cuts", str(cuts), "--operating-point", "1709,5", "--json"])
    assert res.exit_code == 0, res.output
    outside = lim(POSE, 1709.0)
    ref, _ = _rejection(w0, outside, 5e-3, [[], *groups], seed=4)  # its own local factor
    assert json.loads(res.output)["operating_point"]["p_stable"] == pytest.approx(ref, abs=4e-3)
    assert ref > 0.3


def test_forecast_quantile_inverts_p_stable_at_the_cut():
    from robovib.cli import _mill_options as opt
    from robovib.cli._common import material, workspace_model
    from robovib.io.cuts import MeasuredCuts
    from robovib.milling.cut_forecast import forecast_with_cuts

    cutting = opt.cutting(material("al7075"), None, None, 25.4, 2, 30.0, 6.0, None, "down")
    cuts = MeasuredCuts(spindle_rpm=np.array([1700.0]), depth_m=np.array([5e-3]),
                        chatter=np.array([True]), pose_mm_deg=np.array([POSE]))  # fmt: skip
    poses = np.array([POSE, (2300.0, 300.0, 45.0)])
    kw = {"n_samples": 12, "local_factor": LOCAL, "common_factor": COMMON}
    fc = forecast_with_cuts(workspace_model(None, 0), poses, [1700.0], cuts, *cutting, **kw)
    fresh = forecast_with_cuts(workspace_model(None, 0), poses, [1700.0], cuts, *cutting,
                               same_point=None, **kw)  # fmt: skip
    p, p_fresh = fc.p_stable(5e-3), fresh.p_stable(5e-3)
    assert p[0, 0] < 2 * EPS < p_fresh[0, 0]
    assert p[1, 0] == p_fresh[1, 0]  # away from the cut: as before, bit for bit
    assert fc.p_stable(5e-3, posterior=False)[0, 0] == fresh.p_stable(5e-3, False)[0, 0]
    q = fc.quantile_m(0.5)
    assert q[1, 0] == fresh.quantile_m(0.5)[1, 0]
    assert fc.p_stable(q)[0, 0] == pytest.approx(0.5, abs=1e-9)


def test_map_at_a_chattered_cut_against_rejection(tmp_path):
    import xarray as xr

    cuts = tmp_path / "cuts.csv"
    cuts.write_text("x_mm,y_mm,rz_deg,spindle_rpm,depth_mm,result\n"
                    "2102,-298,45.5,1705,4.0,chatter\n")  # fmt: skip
    out = tmp_path / "map.nc"
    args = ["mill", "map", "--rz", "45", "--nx", "2", "--ny", "2", "--rpm", "1700",
            "--samples", "24", "--depth", "4", "--cuts", str(cuts), "-o", str(out)]  # fmt: skip
    res = CliRunner().invoke(app, args)
    assert res.exit_code == 0, res.output
    with xr.open_dataset(out) as ds:
        p = ds["p_stable"].load()
        tol = json.loads(ds.attrs["settings"])["same_point_tolerance"]
    assert tol == {"position_mm": 5.0, "rz_deg": 1.0, "speed_rel": 0.005}
    w0, lim = _cli_rows(cuts)
    cut = [(lim((2102.0, -298.0, 45.5), 1705.0), 4e-3, True)]
    for (x, y), shared, seed in (((2100.0, -300.0), True, 1), ((2700.0, 600.0), False, 2)):
        point = lim((x, y, 45.0), 1700.0)
        ref, _ = _rejection(w0, point, 4e-3, [cut] if shared else [[], cut], seed=seed)
        got = float(p.sel(x_mm=x, y_mm=y, rz_deg=45.0, spindle_rpm=1700.0))
        assert got == pytest.approx(ref, abs=4e-3)
        if shared:  # eps P(A) / (eps P(A) + (1 - eps) (1 - P(A))), A: l a > d before
            fresh, _ = _rejection(w0, point, 4e-3, [[], cut], seed=3)
            assert got < 0.15 < 0.5 < fresh


@pytest.mark.parametrize(("rpm", "shared"), [(1700.0, True), (1709.0, False)])
def test_plan_at_a_chattered_cut_against_rejection(tmp_path, rpm, shared):
    """``mill plan --cuts``: the plan's grid point at a cut's segment, Rz and speed shares its
    local factor (P(stable) at the asked depth, and the depth allowed inverts it); 9 rpm off
    (outside 0.5 %) it keeps a fresh one."""
    from robovib.cli import _mill_options as opt
    from robovib.cli._common import material
    from robovib.io.cuts import read_cuts_csv
    from robovib.milling.planning import plan_path

    cuts = tmp_path / "cuts.csv"
    cuts.write_text(CUTS)
    cutting = opt.cutting(material("al7075"), None, None, 25.4, 2, 30.0, 6.0, None, "down")
    w0, _ = _cli_rows(cuts)
    from robovib.cli._common import workspace_model
    from robovib.milling.cut_posterior import update_with_cuts
    from robovib.milling.structures import sample_structures

    measured = read_cuts_csv(cuts)
    st = update_with_cuts(sample_structures(workspace_model(None, 0), 24, rng=0), measured,
                          *cutting, label_noise=EPS, local_factor=LOCAL,
                          common_factor=COMMON).structures  # fmt: skip
    kw = {"n_segments": 1, "rz_range_deg": (45.0, 45.0), "rpm_range": (rpm, rpm), "n_speeds": 1,
          "vibration_samples": 0, "cuts": measured, "label_noise": EPS}  # fmt: skip
    plan = plan_path(st, [(2390.0, 100.0), (2410.0, 100.0)], *cutting, depth_m=5e-3, **kw)
    plan_kw = {"feed_direction": "x", "points_per_decade": 200.0, "depth_cap_m": 0.02}

    def lim(pose, n):
        return st.limits(np.array([pose]), [n], *cutting, **plan_kw)[:, 0, 0]

    groups = [[(lim(POSE, 1700.0), 5e-3, True)], [(lim((2300.0, 300.0, 45.0), 2100.0), 4e-3,
                                                    False)]]  # fmt: skip
    point = lim(POSE, rpm)
    ref, _ = _rejection(w0, point, 5e-3, groups if shared else [[], *groups], seed=7)
    assert plan.p_stable[0] == pytest.approx(ref, abs=4e-3)
    assert (ref < 2 * EPS) if shared else (ref > 0.3)
    assert ("same_point_tolerance" in plan.settings) and plan.settings["same_point_tolerance"][
        "speed_rel"] == 0.005  # fmt: skip
    deep = plan_path(st, [(2390.0, 100.0), (2410.0, 100.0)], *cutting, p_required=0.5, **kw)
    ref, _ = _rejection(w0, point, deep.depth_allowed_m[0], groups if shared else [[], *groups],
                        seed=8)  # fmt: skip
    assert ref == pytest.approx(0.5, abs=5e-3)
