"""Campaign: manifest -> process (pool) -> modal table -> pose model -> next poses, checked
against the virtual robot's truth (an independent reference: the simulator's modes)."""

import json

import numpy as np
import pandas as pd
import pytest

from robovib.campaign import (
    fit_pose_model_from_table,
    load_pose_model,
    next_poses,
    predict_at,
    process_campaign,
    read_manifest,
    save_pose_model,
)
from robovib.sim import VirtualRobot, simulate_campaign, truth_table


@pytest.fixture(scope="module")
def campaign(tmp_path_factory):
    """30 poses x 3 directions in the four layouts (x <= 2550 mm: no ~63 Hz X-mode switch)."""
    rng = np.random.default_rng(7)
    n = 30
    # Stratified in X so the box is covered; Y and Rz uniform.
    x = 2100 + 450 * (np.arange(n) + rng.uniform(size=n)) / n
    poses = np.column_stack([x, rng.uniform(-300, 600, n), rng.uniform(0, 180, n)])
    out = tmp_path_factory.mktemp("campaign")
    sim = simulate_campaign(poses, out, rng=1, n_hits=2, duration_s=2.0, n_truth=25)
    res = process_campaign(sim.manifest, out / "out", n_workers=2)
    return poses, sim, res, out


def test_every_row_processed_in_every_layout(campaign):
    poses, sim, res, out = campaign
    table = res.table
    assert len(table) == 90 and not res.skipped
    assert set(table["file"].str[-4:]) == {".uff", ".csv"}
    assert (table["n_hits_used"] == 2).all()
    # Measured modes at the campaign poses against the simulator's dominant modes.
    truth = truth_table(VirtualRobot(), poses)
    for d in "xyz":
        t = table[table["direction"] == d].sort_values("row")
        np.testing.assert_allclose(t["fn_hz"], truth[f"{d}_fn_hz"], rtol=0.02)
        np.testing.assert_allclose(
            t["stiffness_n_per_m"], truth[f"{d}_stiffness_n_per_m"], rtol=0.06
        )
        np.testing.assert_allclose(t["damping_ratio"], truth[f"{d}_damping_ratio"], rtol=0.06)
    frfs = __import__("robovib.io", fromlist=["read_frfs"]).read_frfs(out / "out" / "frfs.h5")
    # 30 triaxial-layout rows... every 4th recording has 3 channels: 2 extra FRFs each.
    n_tri = sum(1 for p in sim.recordings[2::4])
    assert len(frfs) == 90 + 2 * n_tri == res.n_frfs
    cross = [f for f in frfs if f.meta["reference_direction"] != f.direction]
    assert len(cross) == 2 * n_tri
    doc = json.loads((out / "out" / "campaign.json").read_text())
    assert doc["rows_processed"] == 90 and doc["robovib_version"]


def test_end_to_end_unseen_pose_errors(campaign, tmp_path):
    """Fit on modal.csv, predict at 25 unseen poses; stated tolerances (relative errors):
    median fn < 3 %, k < 6 %, zeta < 6 %; 90th percentile fn < 8 %, k < 15 %, zeta < 15 %."""
    _, sim, _, out = campaign
    fit = fit_pose_model_from_table(out / "out" / "modal.csv", inputs=["x_mm", "y_mm", "rz_deg"])
    assert list(fit.cv_table["output"]) == list(fit.model.output_names_)
    assert fit.model.provenance_["mode_switch_found"] == {"x": False, "y": False, "z": False}
    assert fit.model.provenance_["source"] == str(out / "out" / "modal.csv")  # the file read
    assert (fit.cv_table["relative_rmse_pct"] < 15).all()
    truth = pd.read_csv(sim.truth)
    X = truth[["x_mm", "y_mm", "rz_deg"]].to_numpy()
    pred = fit.model.predict(X)
    for j, d in enumerate("xyz"):
        fn, k, c = pred[:, 3 * j], pred[:, 3 * j + 1], pred[:, 3 * j + 2]
        zeta = c * 2 * np.pi * fn / (2 * k)
        errs = {
            "fn": np.abs(fn / truth[f"{d}_fn_hz"] - 1),
            "k": np.abs(k / truth[f"{d}_stiffness_n_per_m"] - 1),
            "zeta": np.abs(zeta / truth[f"{d}_damping_ratio"] - 1),
        }
        for name, e in errs.items():
            med_tol, p90_tol = {"fn": (0.03, 0.08), "k": (0.06, 0.15), "zeta": (0.06, 0.15)}[name]
            assert np.median(e) < med_tol, (d, name, np.median(e))
            assert np.quantile(e, 0.9) < p90_tol, (d, name, np.quantile(e, 0.9))
    # Save with CV + provenance, reload: same predictions, no refit.
    path = tmp_path / "model.h5"
    save_pose_model(fit, path)
    back = load_pose_model(path)
    np.testing.assert_allclose(back.predict(X), pred, rtol=1e-9)
    far = predict_at(back, {"x_mm": 9999.0, "y_mm": fit.X[0, 1], "rz_deg": fit.X[0, 2]})
    assert far.extrapolating and far.outside_inputs == ("x_mm",)
    near = predict_at(back, dict(zip(back.input_names, fit.X[0], strict=True)))
    assert not near.extrapolating
    assert near.outputs[0]["mean"] == pytest.approx(back.predict(fit.X[:1])[0, 0])
    with pytest.raises(ValueError, match=r"--rz\); missing rz_deg; not an input: a1_deg"):
        predict_at(back, {"x_mm": 1.0, "y_mm": 0.0, "a1_deg": 3.0})
    assert (
        back.extrapolating([[9999.0, 0.0, 0.0]])[0]
        and not back.extrapolating(X[:1] * 0 + fit.X[:1])[0]
    )


def test_next_poses_matches_brute_force_refit(campaign):
    """Greedy variance reduction equals adding the pose to the GP and re-predicting (Eq. 10)."""
    _, _, res, _ = campaign
    fit = fit_pose_model_from_table(res.table)
    rng = np.random.default_rng(3)
    cand = np.column_stack(
        [rng.uniform(2100, 2550, 40), rng.uniform(-300, 600, 40), rng.uniform(0, 180, 40)]
    )
    nx = next_poses(fit.model, cand, k=2)
    import copy

    from robovib.campaign.model import _gps_of

    # One GP per covariance family (no mode switch here), each output weighted by its band
    # calibration c² (the calibrated band, issue 24).
    best = np.zeros(len(cand))
    for gp, c in _gps_of(fit.model):
        prior = gp.hyperparameters_.signal_std**2
        _, s0 = gp.predict(cand, return_std=True)
        for i in range(len(cand)):
            g = copy.deepcopy(gp)
            g.add_observations(cand[i : i + 1], g.predict(cand[i : i + 1]))
            _, s1 = g.predict(cand, return_std=True)
            best[i] += np.sum(c**2 * (s0**2 - s1**2) / prior)
    assert nx.indices[0] == int(np.argmax(best))
    assert nx.variance_reduction[0] == pytest.approx(max(best), rel=0.02)
    assert nx.indices[1] != nx.indices[0]


def test_bad_row_named_and_nothing_written(campaign, tmp_path):
    _, sim, _, out = campaign
    man = pd.read_csv(sim.manifest)
    man["file"] = [str(out / f) for f in man["file"]]
    man = man.iloc[:4].copy()
    man.loc[2, "file"] = str(tmp_path / "missing.uff")
    path = tmp_path / "m.csv"
    man.to_csv(path, index=False)
    dest = tmp_path / "out"
    with pytest.raises(ValueError, match=r"line 4: missing.uff: .*no such file"):
        process_campaign(path, dest, n_workers=1)
    assert not dest.exists() or not any(dest.iterdir())
    res = process_campaign(path, dest, n_workers=1, skip_bad=True)
    assert len(res.table) == 3 and res.skipped[0][0] == 4
    assert len(pd.read_csv(dest / "modal.csv")) == 3
    assert [p.name for p in dest.iterdir() if p.name.startswith(".")] == []  # no temp files left


def test_manifest_errors(tmp_path):
    p = tmp_path / "m.csv"
    p.write_text("file,direction,x_mm,y_mm,z_mm,rz_deg\na.uff,w,1,2,3,4\n")
    with pytest.raises(ValueError, match="line 2: unknown direction 'w'"):
        read_manifest(p)
    p.write_text("file,direction,x_m,y_mm,z_mm,rz_deg\na.uff,x,1,2,3,4\n")
    with pytest.raises(ValueError, match="lacks column"):
        read_manifest(p)
    p.write_text("file,direction,x_mm,y_mm,z_mm,rz_deg,x_m\na.uff,x,1,2,3,4,5\n")
    with pytest.raises(ValueError, match="unknown manifest column"):
        read_manifest(p)
    p.write_text(
        "file,direction,x_mm,y_mm,z_mm,rz_deg,force_sensitivity_mv_per_n\na.uff,x,1,2,3,nan,2\n"
    )
    with pytest.raises(ValueError, match="rz_deg = 'nan' is not finite"):
        read_manifest(p)
    p.write_text(
        "file,direction,x_mm,y_mm,z_mm,rz_deg,force_sensitivity_mv_per_n\nsub/a.uff,x,1,2,3,4,-2\n"
    )
    with pytest.raises(ValueError, match="must be positive"):
        read_manifest(p)
    p.write_text("file,direction,x_mm,y_mm,z_mm,rz_deg\nsub/a.uff,X,1,2,3,4\n")
    (row,) = read_manifest(p)
    assert row.file == (tmp_path / "sub" / "a.uff").resolve() and row.direction == "x"
    assert row.pose_tuple_si() == pytest.approx((0.001, 0.002, 0.003, 0, 0, 4))


def test_plot_next_poses(campaign, tmp_path):
    import matplotlib

    matplotlib.use("Agg")
    from robovib.campaign import plot_next_poses

    _, _, res, _ = campaign
    fit = fit_pose_model_from_table(res.table)
    cand = pd.DataFrame({"x_mm": [2200.0, 2300, 2400, 2500], "y_mm": [0.0, 100, -200, 500],
                         "rz_deg": [10.0, 90, 170, 45]})  # fmt: skip
    nx = next_poses(fit.model, cand, k=2)
    fig = plot_next_poses(nx)
    fig.savefig(tmp_path / "next.png")
    assert (tmp_path / "next.png").stat().st_size > 5000


@pytest.mark.parametrize("reader", ["read_pose_table", "read_pose_array"])
def test_pose_table_errors(tmp_path, reader):
    import robovib.io

    read = getattr(robovib.io, reader)
    p = tmp_path / "poses.csv"
    p.write_text("x_mm,y_mm,rz_deg\n2100,0,0\n2200,abc,0\n")
    with pytest.raises(ValueError, match=r"line 3: y_mm = 'abc' is not a finite number"):
        read(p, ["x_mm", "y_mm", "rz_deg"])
    with pytest.raises(ValueError, match="lacks column"):
        read(p, ["a1_deg"])
    p.write_text("x_mm,y_mm,rz_deg\n")
    with pytest.raises(ValueError, match="no rows"):
        read(p, ["x_mm"])
    with pytest.raises(ValueError, match="no such pose table"):
        read(tmp_path / "none.csv", ["x_mm"])


def test_mode_switch_detected_end_to_end(tmp_path):
    """X hammer tests incl. full extension at Rz 0/180° (virtual robot: ~63 Hz mode dominant
    there): the modal table shows it and the fitted model reports a switch in X."""
    import warnings

    from robovib.campaign import mode_switches_found

    rng = np.random.default_rng(3)
    base = np.column_stack([rng.uniform(2100, 2600, 24), rng.uniform(-300, 600, 24),
                            rng.uniform(30, 150, 24)])  # fmt: skip
    ext = np.column_stack([rng.uniform(2660, 2700, 8), rng.uniform(-300, 600, 8),
                           rng.choice([0.0, 5, 175, 180], 8)])  # fmt: skip
    poses = np.vstack([base, ext])
    sim = simulate_campaign(poses, tmp_path, rng=1, n_hits=2, directions=("x",), n_truth=0)
    res = process_campaign(sim.manifest, tmp_path / "out", n_workers=1)
    high = res.table["x_mm"] > 2650
    assert (res.table.loc[high, "fn_hz"] > 60).all() and (res.table.loc[~high, "fn_hz"] < 30).all()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        fit = fit_pose_model_from_table(tmp_path / "out" / "modal.csv")
    assert mode_switches_found(fit.model) == {"x": True}


def test_modal_table_read_by_the_one_csv_reader(tmp_path):
    """A modal/mode table is read by io.csv_table.read_table: spreadsheet layouts work and a
    broken line is named."""
    from robovib.campaign import fit_multimode_pose_model

    head = "x_mm;y_mm;rz_deg;direction;fn_hz;stiffness_n_per_m;damping_ns_per_m;flags\n"
    good = tmp_path / "excel.csv"
    good.write_text(head + "2100;0;45;x;12,5;3,2e6;900;\n", encoding="utf-8-sig")
    with pytest.raises(ValueError, match="needs at least 2 poses, got 1"):  # read, columns found
        fit_pose_model_from_table(good)
    ragged = tmp_path / "ragged.csv"
    ragged.write_text(head.replace(";", ",") + "2100,0,45,x,12.5,3.2e6,900,\n2200,0,45\n")
    with pytest.raises(ValueError, match=r"ragged\.csv line 3: 3 cells, expected 8"):
        fit_pose_model_from_table(ragged)
    with pytest.raises(ValueError, match=r"ragged\.csv line 3: 3 cells, expected 8"):
        fit_multimode_pose_model(ragged)


def test_fit_campaign_table_picks_the_fit_by_the_table(tmp_path):
    """modes.csv (a mode_id column) goes to the multi-mode fit, modal.csv to the dominant one
    (``model fit`` calls this; the CLI picks no route itself)."""
    from robovib.campaign import fit_campaign_table

    head = "row,x_mm,y_mm,rz_deg,direction,fn_hz,stiffness_n_per_m,damping_ns_per_m"
    modal = tmp_path / "modal.csv"
    modal.write_text(head + "\n2,2100,0,45,x,12.5,3.2e6,900\n")
    with pytest.raises(ValueError, match="needs at least 2 poses, got 1"):
        fit_campaign_table(modal)
    modes = tmp_path / "modes.csv"
    modes.write_text(head + ",mode_id\n2,2100,0,45,x,12.5,3.2e6,900,\n")
    with pytest.raises(ValueError, match="no mode id of directions"):
        fit_campaign_table(modes)
