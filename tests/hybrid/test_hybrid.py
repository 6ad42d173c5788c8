"""Hybrid EMA + OMA FRF model: OMA against the truth, GP model behaviour, persistence, errors."""

import numpy as np
import pytest

from robovib.hybrid import FRFPoseModel, oma_frfs
from robovib.milling import ACETAL, CuttingConditions, MillingTool
from robovib.sim import LinearMove, VirtualRobot, simulate_milling


@pytest.fixture(scope="module")
def robot():
    return VirtualRobot()


def test_oma_frf_agrees_with_truth_where_coherence_is_high(robot):
    cond = CuttingConditions(2700.0, 0.3e-3, 6e-3, 6e-3)
    run = simulate_milling(robot, LinearMove("path", (1.0,), (1.1,)), MillingTool(), cond, ACETAL,
                           background_noise_rel=1.0, rng=0)  # fmt: skip
    segs = oma_frfs(run.time_s, run.force_n, run.displacement_m, run.coords, direction="x",
                    spindle_rpm=cond.spindle_rpm, f_max_hz=30.0)  # fmt: skip
    assert len(segs) >= 1
    seg = segs[0]
    good = ~seg.flagged & (seg.frf.coherence > 0.8)
    assert good.sum() >= 3
    truth = robot.path.modes(seg.s_mid_m, "x").compliance(seg.frf.frequency_hz)[0]
    rel = np.abs(np.abs(seg.frf.values[good]) / np.abs(truth[good]) - 1)
    assert np.median(rel) < 0.2
    # Spindle harmonics (45 Hz and multiples) would be flagged; none below 30 Hz here, so
    # flags come from coherence alone.
    np.testing.assert_array_equal(seg.flagged, seg.frf.coherence < 0.5)


def _family(s, f):
    fn = 10.0 - 3.0 * s
    r = f[None, :] / fn[:, None]
    return 1.0 / (1e6 * (1 + 0.5 * s[:, None]) * (1 - r**2 + 0.3j * r))


def test_frf_pose_model_interpolates_and_round_trips(tmp_path):
    f = np.linspace(2, 30, 25)
    s = np.linspace(0, 1.2, 7)
    model = FRFPoseModel(f, rng=0).fit(s, _family(s, f))
    pred, std = model.predict([0.5], return_std=True)
    truth = _family(np.array([0.5]), f)
    assert np.sqrt(np.mean(np.abs(pred - truth) ** 2)) < 0.1 * np.max(np.abs(truth))
    assert np.all(std >= 0)
    path = tmp_path / "model.h5"
    model.save(path)
    back = FRFPoseModel.load(path)
    np.testing.assert_allclose(back.predict([0.5, 0.9]), model.predict([0.5, 0.9]), rtol=1e-10)
    assert back.extrapolating([1.5])[0] and not back.extrapolating([0.6])[0]
    import h5py

    with h5py.File(path, "a") as h5:  # the header before io.h5format: "version", version 2
        assert int(h5.attrs["format_version"]) == 2 and "created_utc" in h5.attrs
        assert "um/N" in h5.attrs["units"]
        del h5.attrs["format_version"], h5.attrs["created_utc"], h5.attrs["content_sha256"]
        h5.attrs["version"] = 2
    _unseal(path)
    old = FRFPoseModel.load(path)
    np.testing.assert_allclose(old.predict([0.5, 0.9]), model.predict([0.5, 0.9]), rtol=1e-10)
    with h5py.File(path, "a") as h5:
        h5.attrs["version"] = 3
    _unseal(path)
    with pytest.raises(ValueError, match="format version 3; this robovib reads versions 1 to 2"):
        FRFPoseModel.load(path)
    bad = tmp_path / "bad.h5"
    bad.write_bytes(b"garbage")
    with pytest.raises(ValueError, match="HDF5"):
        FRFPoseModel.load(bad)


def _unseal(path):
    """Blank the byte checksum robovib writes in the user block (older files have none)."""
    from robovib.files.h5safe import USERBLOCK_SIZE

    data = bytearray(path.read_bytes())
    data[:USERBLOCK_SIZE] = bytes(USERBLOCK_SIZE)
    path.write_bytes(bytes(data))


def test_updating_modes_and_next_poses():
    f = np.linspace(2, 30, 20)
    s_ema = np.array([0.0, 0.6, 1.2])
    s_oma = np.linspace(0.1, 1.1, 8)
    rng = np.random.default_rng(0)
    oma = _family(s_oma, f) * (1 + 0.05 * rng.normal(size=(8, 20)))
    for mode, expect_iter in (("posterior", False), ("warm", True)):
        m = FRFPoseModel(f, rng=0).fit(s_ema, _family(s_ema, f))
        rep = m.update(s_oma, oma, mode=mode)
        assert (rep.iterations_total > 0) == expect_iter
    model = FRFPoseModel(f, rng=0).fit(
        np.array([0.0, 0.1, 1.2]), _family(np.array([0.0, 0.1, 1.2]), f)
    )
    picks = model.next_poses(np.linspace(0, 1.2, 25), k=2).poses
    assert 0.3 < picks[0, 0] < 1.0  # the big gap between 0.1 and 1.2 first
    assert abs(picks[1, 0] - picks[0, 0]) > 0.1  # then somewhere else


def test_oma_bad_input():
    t = np.arange(1000) / 1000.0
    f = np.ones((1000, 3))
    with pytest.raises(ValueError, match="unsynchronised"):
        oma_frfs(t, f, np.ones((999, 3)), np.linspace(0, 0.1, 1000))
    with pytest.raises(ValueError, match="fewer than one Welch window"):
        oma_frfs(
            t,
            np.random.default_rng(0).normal(size=(1000, 3)),
            np.ones((1000, 3)),
            np.linspace(0, 0.2, 1000),
        )
    x = np.ones((1000, 3))
    x[3, 0] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        oma_frfs(t, f, x, np.linspace(0, 0.1, 1000))
    with pytest.raises(ValueError, match="on the model's frequency grid"):
        FRFPoseModel(np.linspace(1, 10, 5)).fit([0.0, 1.0], np.ones((2, 4)))


def test_hybrid_file_workflow_cli(tmp_path):
    """sim hammer/mill -> frf compute -> hybrid oma/fit/update/predict, all through files."""
    import json

    from typer.testing import CliRunner

    from robovib.cli import app

    run = CliRunner().invoke
    for s in (0.0, 0.6, 1.2):
        rec, frf = tmp_path / f"e{s}.uff", tmp_path / f"e{s}.h5"
        assert run(app, ["sim", "hammer", "--path-s", str(s), "--sample-rate-hz", "2048", "--hits", "2",
                         "--duration-s", "4", "-o", str(rec)]).exit_code == 0  # fmt: skip
        res = run(
            app, ["frf", "compute", str(rec), "-o", str(frf), "--path-s", str(s), "--fmax", "100"]
        )
        assert res.exit_code == 0, res.output
    cut = tmp_path / "cut.csv"
    res = run(app, ["sim", "mill", "--path-s-from", "0.8", "--path-s-to", "1.0", "--rpm", "2700", "--fz", "0.3", "--ap", "6",
                    "--ae", "6", "--material", "acetal", "--background", "1.0", "-o", str(cut)])  # fmt: skip
    assert res.exit_code == 0, res.output
    oma = tmp_path / "oma.h5"
    res = run(app, ["hybrid", "oma", str(cut), "-o", str(oma), "--rpm", "2700", "--json"])
    assert res.exit_code == 0, res.output
    assert json.loads(res.output)["segments"] >= 3
    model, updated = tmp_path / "m.h5", tmp_path / "m2.h5"
    ema_files = [str(tmp_path / f"e{s}.h5") for s in (0.0, 0.6, 1.2)]
    assert run(app, ["hybrid", "fit", *ema_files, "-o", str(model)]).exit_code == 0
    res = run(app, ["hybrid", "update", str(model), str(oma), "-o", str(updated), "--json"])
    assert res.exit_code == 0, res.output
    res = run(app, ["hybrid", "predict", str(updated), "--path-s", "0.9", "--json"])
    assert res.exit_code == 0, res.output
    doc = json.loads(res.output)
    assert not doc["extrapolating"] and len(doc["compliance_abs_um_per_n"]) == len(
        doc["frequency_hz"]
    )
    res = run(app, ["hybrid", "fit", str(oma).replace("oma", "missing"), "-o", str(model)])
    assert res.exit_code == 1
    # OMA FRFs are no start for the model (they were counted as "2 EMA FRFs" before)
    res = run(app, ["hybrid", "fit", str(oma), "-o", str(tmp_path / "m3.h5")])
    assert res.exit_code == 1 and "not hammer-test (EMA) ones" in res.output


def _ema_oma(rng, n_oma=10, noise=0.02):
    f = np.linspace(2, 30, 20)
    s_ema = np.array([0.0, 0.6, 1.2])
    s_oma = np.linspace(0.05, 1.15, n_oma)
    truth = _family(s_oma, f)
    err = noise * np.abs(truth) * (rng.normal(size=truth.shape) + 1j * rng.normal(size=truth.shape))
    return f, s_ema, _family(s_ema, f), s_oma, truth + err


def test_robust_update_detects_known_scale_and_bin_bias():
    """OMA with a known 1.35 source gain and an offset in two bins: both found and removed."""
    rng = np.random.default_rng(1)
    f, s_ema, h_ema, s_oma, h_oma = _ema_oma(rng)
    biased = h_oma * 1.35
    bad_bins = [4, 11]
    biased[:, bad_bins] += 3.0 * np.abs(h_oma[:, bad_bins]).mean(axis=0)  # systematic offset
    model = FRFPoseModel(f, rng=0).fit(s_ema, h_ema)
    rep = model.update(s_oma, biased, mode="robust")
    assert rep.scale_applied and abs(rep.scale - 1.35) < 0.1
    np.testing.assert_allclose(sorted(rep.rejected_bins_hz), f[bad_bins])
    assert rep.n_rejected >= 2 * len(s_oma)
    # The plain posterior update trusts the biased data and gets worse than EMA alone.
    s_val = np.array([0.33, 0.91])
    truth = _family(s_val, f)
    ema_err = np.abs(FRFPoseModel(f, rng=0).fit(s_ema, h_ema).predict(s_val) - truth).mean()
    naive = FRFPoseModel(f, rng=0).fit(s_ema, h_ema)
    naive.update(s_oma, biased, mode="posterior")
    assert np.abs(naive.predict(s_val) - truth).mean() > ema_err
    assert np.abs(model.predict(s_val) - truth).mean() <= 1.05 * ema_err
    d = rep.to_dict()
    assert d["rejected_bins_hz"] == list(rep.rejected_bins_hz) and "scale_real" in d


def test_robust_update_keeps_unbiased_data_and_estimates_noise():
    """Unbiased OMA with known per-bin noise: nothing rejected, noise recovered by Eq. 33."""
    rng = np.random.default_rng(2)
    f = np.linspace(2, 30, 12)
    s_ema = np.array([0.0, 0.6, 1.2])
    s_oma = np.linspace(0.02, 1.18, 40)
    sigma = 0.05e-6  # m/N per Re/Im component
    h_oma = _family(s_oma, f) + sigma * (
        rng.normal(size=(40, f.size)) + 1j * rng.normal(size=(40, f.size))
    )
    model = FRFPoseModel(f, rng=0).fit(s_ema, _family(s_ema, f))
    # Exact FRFs plus noise, no Welch window: no window bias at the peak (resolution 0 Hz).
    rep = model.update(s_oma, h_oma, mode="robust", oma_resolution_hz=0.0)
    assert not rep.scale_applied and rep.rejected_bins_hz == ()
    assert rep.rejected_fraction < 0.01
    noise = model.gp_.hyperparameters_.noise_std[:, 1] / 1e6
    assert 0.6 < np.median(noise) / sigma < 1.5
    truth = _family(np.array([0.3, 0.9]), f)
    assert np.abs(model.predict([0.3, 0.9]) - truth).max() < 0.1 * np.abs(truth).max()


def test_update_bad_input():
    f = np.linspace(2, 30, 5)
    s = np.array([0.0, 0.6, 1.2])
    model = FRFPoseModel(f).fit(s, _family(s, f))
    with pytest.raises(ValueError, match="unknown update mode"):
        model.update(s, _family(s, f), mode="magic")
    with pytest.raises(ValueError, match="noise_std"):
        model.update(s, _family(s, f), noise_std=np.ones((2, 5)))
    with pytest.raises(ValueError, match=r"poses must be \(n, 1\)"):
        model.predict(np.ones((2, 3)))
    with pytest.raises(ValueError, match="group 1"):
        model.update(s, _family(s, f), groups=np.zeros(3, int))
    from sklearn.base import clone

    twin = clone(model)
    assert twin.get_params()["input_names"] == ("s_m",) and not hasattr(twin, "gp_")


def test_oma_random_error_and_quality_warning(robot):
    from robovib.hybrid import OMAQualityWarning

    cond = CuttingConditions(2700.0, 0.3e-3, 6e-3, 6e-3)
    run = simulate_milling(robot, LinearMove("path", (1.0,), (1.1,)), MillingTool(), cond, ACETAL,
                           background_noise_rel=0.0, force_noise_n=5.0, rng=0)  # fmt: skip
    with pytest.warns(OMAQualityWarning, match="pass the coherence"):
        segs = oma_frfs(run.time_s, run.force_n, run.displacement_m, run.coords, direction="z",
                        spindle_rpm=cond.spindle_rpm, f_max_hz=30.0, window="hann", noverlap=128)  # fmt: skip
    err = segs[0].random_error_m_per_n
    coh = segs[0].frf.coherence
    # Bendat & Piersol: error / |H| = sqrt(1 - g2) / (|g| sqrt(2 n_d)), larger where coherence
    # is lower, with g2 debiased for n_d averages: (n_d g2_hat - 1) / (n_d - 1), >= 1e-3.
    n_d = segs[0].frf.n_averages
    g2 = np.maximum((n_d * coh - 1) / (n_d - 1), 1e-3)
    np.testing.assert_allclose(
        err / np.abs(segs[0].frf.values), np.sqrt((1 - g2) / (2 * n_d * g2)), rtol=1e-9
    )
    with pytest.raises(ValueError, match="noverlap"):
        oma_frfs(run.time_s, run.force_n, run.displacement_m, run.coords, noverlap=600)


def test_hybrid_core_does_not_import_sim_or_studies():
    import subprocess
    import sys

    code = (
        "import sys, robovib.hybrid; bad = [m for m in sys.modules "
        "if m.startswith(('robovib.sim', 'robovib.studies'))]; print(bad); sys.exit(bool(bad))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.returncode == 0, out.stdout + out.stderr


def test_study_is_reproducible_per_seed():
    from robovib.studies.hybrid import hybrid_study

    kw = {"seeds": (3,), "directions": ("y",), "models": ("robust",)}
    a, b = hybrid_study(**kw).to_frame(), hybrid_study(**kw).to_frame()
    cols = [c for c in a.columns if c != "wall_time_s"]
    assert list(a.model) == ["ema", "robust"]
    assert a[cols].equals(b[cols])
    doc = hybrid_study.__module__  # studies, not the core
    assert doc == "robovib.studies.hybrid.study"
    with pytest.raises(ValueError, match="unknown models"):
        hybrid_study(models=("magic",))


def test_workspace_model_end_to_end(tmp_path):
    """EMA at 9 workspace poses + OMA along a cut -> FRF at unseen poses vs the sim's truth.

    Tolerance: RMSE over 2-40 Hz within 15 % of the true peak compliance at each unseen pose,
    and the updated model no worse than 1.5 x the EMA-only one. The model round-trips through
    HDF5 with its input names and units.
    """
    import h5py

    from robovib.studies.hybrid import workspace_study

    res = workspace_study(direction="y", seed=0)
    assert res.model.input_names == ("x_m", "y_m", "rz_deg")
    rel = res.relative_rmse()
    assert np.all(rel < 0.15), rel
    assert np.all(rel <= 1.5 * res.relative_rmse("ema") + 0.02)
    assert res.band_coverage(3.0) > 0.6
    path = tmp_path / "ws.h5"
    res.model.save(path, provenance={"source": "virtual robot", "seed": 0})
    with h5py.File(path) as h5:
        assert list(h5.attrs["input_names"]) == ["x_m", "y_m", "rz_deg"]
        assert h5.attrs["compliance_unit"] == "um/N" and "robovib_version" in h5.attrs
        assert h5.attrs["provenance/source"] == "virtual robot"
    back = FRFPoseModel.load(path)
    np.testing.assert_allclose(back.predict(res.test_poses), res.predicted_m_per_n, rtol=1e-9)
    with pytest.raises(ValueError, match=r"poses must be \(n, 3\)"):
        back.predict([0.5])


def test_hybrid_workspace_cli(tmp_path):
    """Workspace poses through the files: frf compute --x/--y/--rz, fit --inputs workspace,
    oma of a workspace cut, robust update (rejections reported), predict --x/--y/--rz."""
    import json

    from typer.testing import CliRunner

    from robovib.cli import app

    run = CliRunner().invoke
    files = []
    for x, y in ((2100, -300), (2100, 600), (2700, -300), (2700, 600)):
        rec, frf = tmp_path / f"e{x}_{y}.uff", tmp_path / f"e{x}_{y}.h5"
        args = ["--x", str(x), "--y", str(y), "--rz", "45"]
        res = run(app, ["sim", "hammer", *args, "--direction", "y", "--hits", "2",
                        "--sample-rate-hz", "2048", "-o", str(rec)])  # fmt: skip
        assert res.exit_code == 0, res.output
        res = run(app, ["frf", "compute", str(rec), "--fmax", "100", *args, "-o", str(frf)])
        assert res.exit_code == 0, res.output
        files.append(str(frf))
    model = tmp_path / "m.h5"
    res = run(app, ["hybrid", "fit", *files, "--inputs", "workspace", "-o", str(model), "--json"])
    assert res.exit_code == 0, res.output
    assert json.loads(res.output)["input_names"] == ["x_m", "y_m", "rz_deg"]
    cut, oma = tmp_path / "cut.csv", tmp_path / "oma.h5"
    res = run(app, ["sim", "mill", "--x0", "2300", "--y0", "0", "--x1", "2450", "--y1", "100", "--rz", "45",
                    "--rpm", "2700", "--fz", "0.3", "--ap", "6", "--ae", "6", "--material", "acetal",
                    "--background", "1", "-o", str(cut)])  # fmt: skip
    assert res.exit_code == 0, res.output
    res = run(app, ["hybrid", "oma", str(cut), "--rpm", "2700", "--direction", "y",
                    "--window", "hann", "--noverlap", "256", "-o", str(oma), "--json"])  # fmt: skip
    assert res.exit_code == 0, res.output
    assert json.loads(res.output)["segments"] >= 3
    updated = tmp_path / "m2.h5"
    res = run(app, ["hybrid", "update", str(model), str(oma), "-o", str(updated), "--json"])
    assert res.exit_code == 0, res.output
    doc = json.loads(res.output)
    assert doc["mode"] == "robust" and 0 <= doc["n_rejected"] <= doc["n_observations"]
    res = run(app, ["hybrid", "predict", str(updated), "--x", "2400", "--y", "50", "--rz", "45", "--json"])  # fmt: skip
    assert res.exit_code == 0, res.output
    doc = json.loads(res.output)
    assert doc["x_m"] == 2.4 and not doc["extrapolating"]
    res = run(app, ["hybrid", "predict", str(updated), "--path-s", "0.5"])
    assert res.exit_code == 1 and "--x [mm]" in res.output


def test_fit_frf_model_grid_starts_where_every_frf_has_data_and_checks_inputs():
    from robovib.frf.core import FRF
    from robovib.hybrid import fit_frf_model

    def frf(s_m, f0_hz):
        f = np.arange(f0_hz, 45.0, 0.5)
        fn_hz = 18.0 + 4.0 * s_m  # one mode that stiffens along the path
        h = 1e-6 / (1 - (f / fn_hz) ** 2 + 0.1j * f / fn_hz)
        return FRF(f, h, quantity="compliance", direction="x", source="EMA", meta={"path_s_m": s_m})

    frfs = [frf(0.0, 1.0), frf(0.6, 3.0), frf(1.2, 1.5)]
    model = fit_frf_model(frfs, "path", f_max_hz=40.0, df_hz=1.0)
    assert model.frequency_hz_[0] == pytest.approx(3.0)  # the latest first bin
    assert model.frequency_hz_[-1] <= 40.0
    with pytest.raises(ValueError, match="inputs must be one of"):
        fit_frf_model(frfs, "joints")
    with pytest.raises(ValueError, match="no EMA FRFs"):
        fit_frf_model([], "path")


def test_robust_update_holds_back_uninformative_oma_and_says_why():
    """OMA buried in noise (10x |H|) predicts held-out segments no better than EMA: the whole
    direction is held back and the model stays the EMA model; informative OMA is used."""
    rng = np.random.default_rng(5)
    f, s_ema, h_ema, s_oma, _ = _ema_oma(rng, n_oma=16)
    truth_oma = _family(s_oma, f)
    junk = truth_oma + 10 * np.abs(truth_oma).max() * (
        rng.normal(size=truth_oma.shape) + 1j * rng.normal(size=truth_oma.shape)
    )
    s_val = np.array([0.33, 0.91])
    ema_pred = FRFPoseModel(f, rng=0).fit(s_ema, h_ema).predict(s_val)
    model = FRFPoseModel(f, rng=0).fit(s_ema, h_ema)
    rep = model.update(s_oma, junk, mode="robust")
    assert rep.held_back_all and rep.heldout_log_density_gain < 1.0
    assert "held back" in rep.describe() and rep.to_dict()["held_back_all"]
    np.testing.assert_allclose(model.predict(s_val), ema_pred, rtol=1e-6, atol=1e-12)
    # Informative OMA (2 % noise) passes the held-out check and beats EMA alone vs truth.
    _, _, _, _, good = _ema_oma(np.random.default_rng(6), n_oma=16)
    model = FRFPoseModel(f, rng=0).fit(s_ema, h_ema)
    rep = model.update(s_oma, good, mode="robust")
    assert not rep.held_back_all and rep.heldout_log_density_gain > 1.0
    truth = _family(s_val, f)
    assert np.abs(model.predict(s_val) - truth).mean() < np.abs(ema_pred - truth).mean()


def test_robust_update_keeps_weakly_informative_bins():
    """Unbiased OMA with 15 % noise: many bins gain little on held-out segments (< 1 nat) but
    still carry information. They keep their posterior (only evidence *against* OMA holds a
    bin back), and the update beats EMA alone against the known family."""
    e0, e1 = [], []
    for seed in (1, 2, 4):
        f, s_ema, h_ema, s_oma, h_oma = _ema_oma(np.random.default_rng(seed), 16, noise=0.15)
        s_val = np.linspace(0.1, 1.1, 9)
        truth = _family(s_val, f)
        model = FRFPoseModel(f, rng=0).fit(s_ema, h_ema)
        e0.append(np.abs(model.predict(s_val) - truth))
        rep = model.update(s_oma, h_oma, mode="robust")
        e1.append(np.abs(model.predict(s_val) - truth))
        assert not rep.held_back_all and len(rep.held_back_bins_hz) <= 2  # of 20 bins
    rms = lambda e: np.sqrt(np.mean(np.square(e)))  # noqa: E731
    assert rms(e1) < 0.85 * rms(e0)


def test_peak_band_follows_the_window_bias_of_a_known_sdof():
    """Half-power band B_r = 2 zeta f_n of an SDOF: (1/3)(1.5 df / B_r)^2 > 5 % flags it."""
    f = np.arange(2.0, 40.0, 1.0)
    from robovib.hybrid.robust_update import peak_band

    for zeta, flagged in ((0.02, True), (0.3, False)):
        h = 1.0 / (1 - (f / 12.0) ** 2 + 2j * zeta * f / 12.0)
        band, bias = peak_band(f, np.vstack([h, h]))
        assert band.any() == flagged
        if flagged:
            assert band[np.argmin(abs(f - 12.0))] and bias > 0.05
        else:
            assert bias <= 0.05


def test_background_study_table_and_bad_input():
    from robovib.studies.hybrid import background_study, background_table, parse_backgrounds

    assert parse_backgrounds(["0.05,0.15", "1 2"]) == [0.05, 0.15, 1.0, 2.0]
    for bad in (["x"], ["0"], ["-1"], ["nan"], []):
        with pytest.raises(ValueError):
            parse_backgrounds(bad)
    with pytest.raises(ValueError, match="backgrounds"):
        background_study([0.0])
    res = background_study([0.15, 1.0], seeds=(3,), directions=("y",))
    tab = background_table(res)
    assert [(r["background"], r["direction"]) for r in tab] == [(0.15, "y"), (1.0, "y")]
    rows = {(r["background"], r["model"]): r for r in res.rows}
    r, e = rows[(1.0, "robust")], rows[(1.0, "ema")]
    want = 100 * (r["rmse_vs_truth_um_per_n"] / e["rmse_vs_truth_um_per_n"] - 1)
    assert tab[1]["rmse_change_mean_pct"] == pytest.approx(want)


def test_debiased_coherence_of_unrelated_and_related_signals():
    """SciPy's Welch coherence with n_d = 4 averages: of a known true coherence 0.5 (y = x +
    unit noise) it is biased up, the debiased one less; of unrelated noises the raw value
    averages 1/n_d and the debiased one is 0 in the Beta(1, n_d - 1) share below 1/n_d;
    a noise-free relation keeps 1; one average carries no information."""
    from scipy import signal

    from robovib.hybrid import debiased_coherence

    rng = np.random.default_rng(0)
    n_d, nperseg = 4, 256
    a, b = rng.normal(size=(2, 400, n_d * nperseg))

    def coh(u, v):
        return np.array(
            [signal.coherence(u[i], v[i], nperseg=nperseg, noverlap=0)[1] for i in range(len(u))]
        )[:, 1:-1]

    half = coh(a, a + b)  # true coherence 1 / (1 + 1) = 0.5
    raw_bias = half.mean() - 0.5  # biased up by ~(1 - 0.5) / n_d = 0.125 to first order
    assert raw_bias > 0.06
    assert abs(debiased_coherence(half, n_d).mean() - 0.5) < 0.7 * raw_bias
    raw = coh(a, b)
    assert abs(raw.mean() - 1 / n_d) < 0.02
    zero_share = np.mean(debiased_coherence(raw, n_d) == 0.0)
    assert abs(zero_share - (1 - (1 - 1 / n_d) ** (n_d - 1))) < 0.02
    _, same = signal.coherence(a[0], 2 * a[0], nperseg=nperseg, noverlap=0)
    np.testing.assert_allclose(debiased_coherence(same, n_d), 1.0, atol=1e-9)
    assert np.all(debiased_coherence(np.full(5, 0.9), 1) == 0.0)


def test_hann_window_bias_ratio_matches_welch_h1_of_a_sharp_mode():
    """E[H1] / H of a Hann Welch estimate at a sharp resonance (zeta 1 %, 1 Hz bins) from a
    long white-noise simulation (SciPy csd / welch) vs the one-mode-fit prediction."""
    from scipy import signal

    from robovib.hybrid.robust_update import _hann_bias_ratio

    fs, nperseg = 64.0, 64  # 1 Hz resolution
    fn, zeta = 12.3, 0.01
    wn = 2 * np.pi * fn
    b, a = signal.bilinear([1.0], [1.0, 2 * zeta * wn, wn**2], fs=fs)
    x = np.random.default_rng(1).normal(size=400_000)
    y = signal.lfilter(b, a, x)
    f, gxy = signal.csd(x, y, fs=fs, window="hann", nperseg=nperseg, noverlap=nperseg // 2)
    _, gxx = signal.welch(x, fs=fs, window="hann", nperseg=nperseg, noverlap=nperseg // 2)
    sel = (f >= 2) & (f <= 30)
    f, h1 = f[sel], (gxy / gxx)[sel]
    _, h = signal.freqz(b, a, worN=f, fs=fs)
    band = np.abs(f - fn) <= 2.0
    ratio = _hann_bias_ratio(f, h, band)
    measured = h1 / h
    assert np.all(ratio[~band] == 1.0)
    assert np.max(np.abs(measured[band] - 1)) > 0.5  # the window smears the peak: a real bias
    np.testing.assert_allclose(ratio[band], measured[band], atol=0.04)


def test_robust_update_keeps_the_dominant_peak_bin_of_the_ema_model():
    """A sharp mode on a coarse grid (window bias > 5 %): the OMA data are not used at the
    dominant peak bin, so the prediction there is the EMA model's; the report says so."""
    f = np.arange(2.0, 30.0, 1.0)

    def fam(s):
        r = f[None, :] / (10.3 - 0.5 * s)[:, None]
        return 1e-6 / (1 - r**2 + 0.04j * r)

    s_ema = np.array([0.0, 0.6, 1.2])
    s_oma = np.linspace(0.05, 1.15, 16)
    rng = np.random.default_rng(3)
    h_oma = fam(s_oma) * (
        1 + 0.03 * (rng.normal(size=(16, f.size)) + 1j * rng.normal(size=(16, f.size)))
    )
    ema_only = FRFPoseModel(f, rng=0).fit(s_ema, fam(s_ema))
    model = FRFPoseModel(f, rng=0).fit(s_ema, fam(s_ema))
    rep = model.update(s_oma, h_oma)
    k = int(np.argmax(np.mean(np.abs(ema_only.predict(s_oma)) ** 2, axis=0)))
    s_val = np.array([0.3, 0.9])
    np.testing.assert_allclose(model.predict(s_val)[:, k], ema_only.predict(s_val)[:, k], rtol=1e-6)
    assert any("dominant peak bin" in r for r in rep.reasons)


def test_robust_update_finds_a_source_gain_in_noisy_oma():
    """A 1.7 source gain (e.g. a coarsely quantised displacement) under 40 % random error per
    bin: most bins disagree with neither 1 nor 1.7 on their own, the pooled gain is still
    significant and applied; an unbiased source with the same noise is left alone."""
    rng = np.random.default_rng(7)
    f, s_ema, h_ema, s_oma, h_oma = _ema_oma(rng, n_oma=12, noise=0.4)
    model = FRFPoseModel(f, rng=0).fit(s_ema, h_ema)
    rep = model.update(s_oma, 1.7 * h_oma, oma_resolution_hz=0.0)
    assert rep.scale_applied and abs(rep.scale - 1.7) < 0.25
    model = FRFPoseModel(f, rng=0).fit(s_ema, h_ema)
    rep = model.update(s_oma, h_oma, oma_resolution_hz=0.0)
    assert not rep.scale_applied


def test_frf_pose_model_extrapolation_is_the_pose_models_rule():
    """FRFPoseModel.extrapolating is gp.extrapolation's box rule (as milling.at_pose sees it):
    outside a coordinate's training range by more than 1e-9 of that range."""
    from robovib.gp.extrapolation import extrapolating

    f = np.linspace(2, 30, 10)
    s = np.linspace(0.2, 1.2, 5)
    model = FRFPoseModel(f, rng=0).fit(s, _family(s, f))
    q = np.array([0.2, 1.2, 0.7, 1.2 + 1e-12, 0.2 - 5e-10, 1.2 + 1e-6, 0.1999, 1.3])
    expect = (q < 0.2 - 1e-9) | (q > 1.2 + 1e-9)  # range 1.0: tolerance 1e-9
    np.testing.assert_array_equal(model.extrapolating(q), expect)
    np.testing.assert_array_equal(extrapolating(model, q[:, None]), expect)


def test_a_model_file_written_before_the_split_of_hybrid_model_still_loads(tmp_path):
    """``tests/hybrid/data/hybrid_frf_model_v2.h5`` was written by robovib before hybrid/model.py was
    split (6 EMA poses of ``_family`` on 15 bins, 3 OMA poses added by ``mode="posterior"``,
    direction x). It loads, predicts the family it was fitted on, and saves to the same
    layout (same members, same stored state)."""
    from pathlib import Path

    import h5py

    old = Path(__file__).parent / "data" / "hybrid_frf_model_v2.h5"
    model = FRFPoseModel.load(old)
    f = np.linspace(2, 30, 15)
    np.testing.assert_allclose(model.frequency_hz_, f)
    assert model.direction_ == "x"
    np.testing.assert_allclose(
        np.sort(model.X_train_[:, 0]), np.sort([*np.linspace(0, 1.2, 6), 0.3, 0.7, 1.1])
    )
    s = np.array([0.5, 0.9])
    truth = _family(s, f)
    assert np.sqrt(np.mean(np.abs(model.predict(s) - truth) ** 2)) < 0.1 * np.max(np.abs(truth))
    again = tmp_path / "again.h5"
    model.save(again)
    with h5py.File(old) as a, h5py.File(again) as b:
        assert sorted(a) == sorted(b)
        for name in (n for n in a if isinstance(a[n], h5py.Dataset)):
            np.testing.assert_array_equal(a[name][()], b[name][()], err_msg=name)
            assert a[name].attrs["units"] == b[name].attrs["units"]
        same = ("format", "format_version", "kernel", "direction", "compliance_unit", "groups")
        assert all(a.attrs[k] == b.attrs[k] for k in same)
        assert list(a.attrs["input_names"]) == list(b.attrs["input_names"])
    np.testing.assert_array_equal(FRFPoseModel.load(again).predict(s), model.predict(s))
