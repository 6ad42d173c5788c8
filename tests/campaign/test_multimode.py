"""Issue 29: every mode — multi-mode fit per recording, mode tracking across poses, the
multi-mode pose model and P(stable) from all modes.

References are independent: synthetic FRFs / fields with known parameters, the virtual robot's
truth, and a direct semi-discretization of the same modal parameters."""

import json

import numpy as np
import pandas as pd
import pytest
from helpers import synthetic_modes_table

from robovib.campaign import ProcessingSettings, fit_multimode_pose_model, track_modes
from robovib.campaign.multimode import fit_row_modes, mode_direction
from robovib.frf import FRF
from robovib.milling import ALUMINIUM_7075, CuttingConditions, MillingTool
from robovib.milling.sdm import sdm_lobes
from robovib.milling.uncertainty import (
    ModeDistribution,
    mode_distributions_at_pose,
    stability_probability,
)
from robovib.modal import ModalParameters


def test_two_mode_frf_recovered_by_row_fit():
    modes = [ModalParameters(18.0, 3.5e6, 0.08), ModalParameters(47.0, 3.0e7, 0.04)]
    f = np.arange(2.0, 120.0, 0.25)
    got = fit_row_modes(FRF(f, sum(m.compliance(f) for m in modes)), (5.0, 100.0))
    assert [g["rank"] for g in got] == [1, 2]
    for g, m in zip(got, modes, strict=True):
        assert g["fn_hz"] == pytest.approx(m.natural_frequency_hz, rel=1e-3)
        assert g["stiffness_n_per_m"] == pytest.approx(m.stiffness_n_per_m, rel=1e-2)
        assert g["damping_ratio"] == pytest.approx(m.damping_ratio, rel=2e-2)


def test_tracking_labels_missing_and_spurious_modes():
    table, _, _ = synthetic_modes_table()
    tracked, presence = track_modes(table)
    assert (tracked["mode_id"] == tracked["true_id"]).all()
    assert presence["x2"]["n_seen"] == 13 and presence["x2"]["presence"] == pytest.approx(13 / 14)
    assert presence["x1"]["presence"] == 1.0 and presence["y1"]["presence"] == 1.0
    assert mode_direction("x2") == "x"
    with pytest.raises(ValueError, match="mode id"):
        mode_direction("x")
    with pytest.raises(ValueError, match="lacks"):
        track_modes(table.drop(columns="row"))


def test_multimode_pose_model_predicts_every_mode(tmp_path):
    table, _, _ = synthetic_modes_table(n=16)
    tracked, _ = track_modes(table)
    fit = fit_multimode_pose_model(tracked, n_folds=3, covariance="se")
    model = fit.model
    assert model.directions == ("x1", "x2", "y1")
    pose = np.array([[2350.0, 100.0, 60.0]])
    row = model.modes(pose)[0]
    s = (2350.0 - 2100) / 500
    assert row["x1"].parameters.natural_frequency_hz == pytest.approx(15 + 6 * s, rel=0.03)
    assert row["x2"].parameters.natural_frequency_hz == pytest.approx(40 + 15 * s, rel=0.03)
    assert row["x2"].parameters.stiffness_n_per_m == pytest.approx(3e7 * (1 + 0.2 * s), rel=0.05)
    # saved in the pose-model HDF5 format, presence kept
    from robovib.gp import PoseModalModel

    back = PoseModalModel.load(model.save(tmp_path / "m.h5"))
    assert json.loads(back.provenance_["mode_presence"])["x2"]["n_seen"] == 15
    d = mode_distributions_at_pose(back, pose[0], n_draws=200)
    assert [m.name for m in d["x"]] == ["x1", "x2"] and [m.name for m in d["y"]] == ["y1"]
    assert d["x"][1].presence == pytest.approx(15 / 16)
    # mill lobes with the model: the envelope of every modelled mean mode, and it says so
    from robovib.milling.chart import lobes_chart

    rpm = np.array([1500.0, 2500.0])
    chart = lobes_chart(tool=TOOL, conditions=COND, coefficients=ALUMINIUM_7075, spindle_rpm=rpm,
                        method="sdm", steps_per_period=20,
                        pose_model=back, pose=tuple(pose[0]))  # fmt: skip
    mx = [m.mean for m in d["x"]]
    my = [m.mean for m in d["y"]]
    direct = sdm_lobes(mx, my, TOOL, COND, ALUMINIUM_7075, rpm, steps_per_period=20)
    np.testing.assert_allclose(chart.envelope.a_lim_m, direct.a_lim_m, rtol=1e-9)
    assert any("x1, x2, y1" in n for n in chart.notes)
    # milling vibration with every mode: the sum of the modal receptances filters the force
    from robovib.milling.at_pose import base_frame_forces, predict_at_pose
    from robovib.milling.forces import milling_forces

    res = predict_at_pose(back, 2350.0, 100.0, 60.0, COND, coefficients=ALUMINIUM_7075,
                          duration_s=1.0, n_samples=3)  # fmt: skip
    assert [r.direction for r in res] == ["x", "y"]
    assert len(res[0].modes) == 2 and len(res[1].modes) == 1
    t = np.arange(1000) / 1000.0
    fx = base_frame_forces(milling_forces(t, TOOL, COND, ALUMINIUM_7075), "x")[:, 0]
    n_fft = 1 << 17
    freq = np.fft.rfftfreq(n_fft, 1e-3)
    h = sum(m.compliance(freq) for m in mx)
    x = np.fft.irfft(np.fft.rfft(fx, n_fft) * h, n_fft)[:1000]
    per_rev = 1000 * 60 / COND.spindle_rpm
    revs = [x[round(a) : round(a + per_rev)] for a in np.arange(500, 1000 - per_rev, per_rev)]
    assert res[0].peak_to_valley_m == pytest.approx(np.mean([np.ptp(r) for r in revs]), rel=0.05)
    with pytest.raises(ValueError, match="mode_id"):
        fit_multimode_pose_model(table.drop(columns="mode_id", errors="ignore"))


TOOL = MillingTool()
COND = CuttingConditions(1900.0, 0.058e-3, 1e-3, 6e-3)
MX = [ModalParameters(16.5, 3.4e6, 0.11), ModalParameters(63.5, 4.2e7, 0.055)]
MY = [ModalParameters(8.2, 1.0e6, 0.18), ModalParameters(21.5, 1.0e7, 0.05)]


def _fixed(m, name=""):
    return ModeDistribution(m.natural_frequency_hz, m.stiffness_n_per_m, m.damping_ns_per_m,
                            name=name)  # fmt: skip


def test_lobes_from_every_mode_equal_a_direct_sdm():
    rpm = np.array([1300.0, 1900.0, 2600.0])
    direct = sdm_lobes(MX, MY, TOOL, COND, ALUMINIUM_7075, rpm, steps_per_period=20)
    dist = {"x": [_fixed(m, f"x{j + 1}") for j, m in enumerate(MX)],
            "y": [_fixed(m) for m in MY]}  # fmt: skip
    p = stability_probability(dist, TOOL, COND, ALUMINIUM_7075, rpm, n_samples=2,
                              method="sdm", steps_per_period=20, solver="numpy",
                              method_error=False, fit_bias=0.0, warm_from_mean=False)  # fmt: skip
    np.testing.assert_allclose(p.a_lim_samples_m, np.tile(direct.a_lim_m, (2, 1)), rtol=1e-9)
    np.testing.assert_allclose(p.mean.a_lim_m, direct.a_lim_m, rtol=1e-9)
    assert p.settings["modes"] == {"x": ["x1", "x2"], "y": ["y1", "y2"]}
    # the secondary modes matter here: the dominant-mode limit differs
    dom = sdm_lobes(MX[:1], MY[:1], TOOL, COND, ALUMINIUM_7075, rpm, steps_per_period=20)
    assert np.max(np.abs(dom.a_lim_m / direct.a_lim_m - 1)) > 0.1


def test_presence_keeps_a_mode_in_that_fraction_of_samples():
    rpm = np.array([1900.0])
    rare = ModeDistribution(63.5, 4.2e7, MX[1].damping_ns_per_m, presence=0.3)
    dist = {"x": [_fixed(MX[0]), rare], "y": [_fixed(m) for m in MY]}
    p = stability_probability(dist, TOOL, COND, ALUMINIUM_7075, rpm, n_samples=60,
                              method="sdm", steps_per_period=20, solver="numpy",
                              method_error=False, fit_bias=0.0, warm_from_mean=False, rng=3)  # fmt: skip
    with_all = sdm_lobes(MX, MY, TOOL, COND, ALUMINIUM_7075, rpm, steps_per_period=20).a_lim_m
    without = sdm_lobes(MX[:1], MY, TOOL, COND, ALUMINIUM_7075, rpm, steps_per_period=20).a_lim_m
    a = p.a_lim_samples_m[:, 0]
    is_all = np.isclose(a, with_all[0], rtol=1e-9)
    assert np.all(is_all | np.isclose(a, without[0], rtol=1e-9))
    assert 0.12 < is_all.mean() < 0.5  # binomial(60, 0.3): 3 sd either side
    with pytest.raises(ValueError, match="presence"):
        ModeDistribution(10.0, 1e6, 100.0, presence=0.0)


def test_modes_band_setting_checked():
    with pytest.raises(ValueError, match="modes_band_hz"):
        ProcessingSettings(modes_band_hz=(50.0, 10.0))
    assert ProcessingSettings(modes_band_hz=[5, 100]).modes_band_hz == (5.0, 100.0)


def test_campaign_process_tracks_the_virtual_robots_modes(tmp_path):
    """modes.csv of a virtual campaign holds the truth's modes under consistent ids."""
    import warnings

    from robovib.campaign import process_campaign
    from robovib.sim import VirtualRobot, simulate_campaign

    rng = np.random.default_rng(5)
    poses = np.column_stack([rng.uniform(2150, 2500, 5), rng.uniform(-250, 550, 5),
                             rng.uniform(10, 170, 5)])  # fmt: skip
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sim = simulate_campaign(poses, tmp_path, rng=2, n_hits=2, directions=("x", "y"),
                                n_truth=0, scatter=(0.0, 0.0, 0.0))  # fmt: skip
        process_campaign(sim.manifest, tmp_path / "out", n_workers=1,
                         settings=ProcessingSettings(modes_band_hz=(5.0, 100.0)))  # fmt: skip
    modes = pd.read_csv(tmp_path / "out" / "modes.csv")
    robot = VirtualRobot()
    for d in ("x", "y"):
        coords = np.column_stack([poses[:, 0] / 1e3, poses[:, 1] / 1e3, poses[:, 2]])
        truth = robot.workspace.modes(coords, d)
        sub = modes[modes["direction"] == d]
        assert set(sub["mode_id"]) == {f"{d}{j + 1}" for j in range(truth.n_modes)}
        for i in range(len(poses)):
            at = sub[np.isclose(sub["x_mm"], poses[i, 0], atol=0.1)].sort_values("mode_id")
            np.testing.assert_allclose(at["fn_hz"], truth.fn_hz[i], rtol=0.02)
            np.testing.assert_allclose(at["stiffness_n_per_m"], truth.stiffness_n_per_m[i],
                                       rtol=0.1)  # fmt: skip
