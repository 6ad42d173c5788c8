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
    bad = tmp_path / "bad.h5"
    bad.write_bytes(b"garbage")
    with pytest.raises(ValueError, match="HDF5"):
        FRFPoseModel.load(bad)


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
    picks = model.next_poses(np.linspace(0, 1.2, 25), k=2)
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
