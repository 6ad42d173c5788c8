"""Computations the CLI used to do inline, now library functions: checked on hand-built inputs."""

import numpy as np
import pytest

from robovib.frf import FRF


def test_principal_stiffness_diagonalises_kt():
    from robovib.robot.dynamics import CartesianModes

    rot = np.linalg.qr(np.random.default_rng(0).normal(size=(3, 3)))[0]
    k_true = np.array([1e6, 3e6, 7e6])
    modes = CartesianModes(np.ones(3), np.eye(3), rot @ np.diag(k_true) @ rot.T, np.eye(3))
    values, vectors = modes.principal_stiffness()
    np.testing.assert_allclose(values, k_true, rtol=1e-10)
    # each direction is a column of the rotation, up to sign
    np.testing.assert_allclose(np.abs(vectors.T @ rot), np.eye(3), atol=1e-9)


def test_peak_vibration_is_the_largest_absolute_displacement():
    from robovib.sim.experiments import MotionRecord

    t = np.linspace(0, 1, 101)
    disp = np.column_stack([1e-4 * np.sin(2 * np.pi * t), -3e-4 * t, np.zeros_like(t)])
    rec = MotionRecord(t, disp, disp, t, "path", disp, disp)
    np.testing.assert_allclose(rec.peak_vibration_m, [1e-4, 3e-4, 0.0], rtol=1e-3)


def test_frf_prediction_peak_and_flagged_fraction():
    from robovib.hybrid import FRFPrediction, flagged_fraction

    f = np.linspace(1, 50, 50)
    h = 1.0 / (20.0**2 - f**2 + 2j * 0.05 * 20.0 * f) * 1e-3
    pred = FRFPrediction(np.nan, f, h, np.full(50, 1e-9), False)
    f_peak, h_peak, sd = pred.peak()
    assert f_peak == f[np.argmin(np.abs(f - 20.0))]
    assert h_peak == h[np.argmax(np.abs(h))] and sd == 1e-9

    flagged = np.zeros(50, bool)
    flagged[:10] = True
    a = FRF(f, h, meta={"flagged": flagged})
    b = FRF(f, h)  # no flags: counts as 0 %
    assert flagged_fraction([a, b]) == pytest.approx(0.1)
    with pytest.raises(ValueError, match="no FRFs"):
        flagged_fraction([])
    with pytest.raises(ValueError, match="flagged has 3 entries for 50 bins"):
        flagged_fraction([FRF(f, h, meta={"flagged": np.zeros(3, bool)})])


def test_map_speeds_and_best_pose():
    import xarray as xr

    from robovib.milling.maps import best_pose, map_speeds

    np.testing.assert_array_equal(map_speeds(1750.0), [1750.0])
    np.testing.assert_array_equal(map_speeds(1750.0, [1000.0, 2000.0]), [1000.0, 1750.0, 2000.0])
    with pytest.raises(ValueError, match="rpm"):
        map_speeds(-1.0)

    xs, ys = np.array([2100.0, 2400.0, 2700.0]), np.array([-300.0, 600.0])
    a = np.full((3, 2, 1, 1), 1e-3)
    a[2, 0, 0, 0] = 4e-3  # deepest at X=2700, Y=-300
    a[0, 1, 0, 0] = 0.5e-3
    a[1, 1, 0, 0] = np.nan
    ds = xr.Dataset(
        {"a_lim_m": (("x_mm", "y_mm", "rz_deg", "spindle_rpm"), a)},
        coords={"x_mm": xs, "y_mm": ys, "rz_deg": [0.0], "spindle_rpm": [1750.0]},
    )
    best = best_pose(ds, 1750.0, 0.0)
    assert best["best_pose_mm"] == [2700.0, -300.0]
    assert best["best_depth_m"] == 4e-3 and best["shallowest_depth_m"] == 0.5e-3
    assert best["critical_depth_m"].shape == (2, 3)  # (n_y, n_x)
    ds["a_lim_m"][:] = np.nan
    with pytest.raises(ValueError, match="no finite critical depth"):
        best_pose(ds, 1750.0, 0.0)


def test_parse_seeds():
    from robovib.studies.hybrid import parse_seeds

    assert parse_seeds("0-4") == [0, 1, 2, 3, 4]
    assert parse_seeds("3,1") == [3, 1]
    assert parse_seeds("7") == [7]
    for bad in ("a-b", "4-1", "1,,2"):
        with pytest.raises(ValueError, match="seeds"):
            parse_seeds(bad)


def test_cutting_setup_units_and_overrides():
    from robovib.milling import ALUMINIUM_7075
    from robovib.milling.chart import cutting_setup

    tool, cond, coef = cutting_setup(ALUMINIUM_7075, diameter_m=0.02, n_flutes=3, helix_deg=30.0,
                                     radial_immersion=0.5, milling="up", ktc_n_per_m2=1e9)  # fmt: skip
    assert tool.diameter_m == 0.02 and tool.n_flutes == 3
    assert cond.radial_depth_m == pytest.approx(0.01) and not cond.down_milling
    assert coef.ktc == 1e9 and coef.krc == ALUMINIUM_7075.krc
    with pytest.raises(ValueError, match="a/D"):
        cutting_setup(
            ALUMINIUM_7075, diameter_m=0.02, n_flutes=3, helix_deg=0, radial_immersion=1.5
        )
    with pytest.raises(ValueError, match="'up' or 'down'"):
        cutting_setup(ALUMINIUM_7075, diameter_m=0.02, n_flutes=3, helix_deg=0,
                      radial_depth_m=0.01, milling="climb")  # fmt: skip


def test_command_settings_units_from_help_and_input_files(tmp_path):
    from pathlib import Path

    from robovib.files.provenance import command_settings

    src, out = tmp_path / "in.csv", tmp_path / "out.h5"
    src.write_text("a\n1\n")
    out.write_text("old")
    doc = command_settings([
        ("x_mm", 1200.0, "Tool-tip X [mm]."), ("k", 3, "Poses to choose."),
        ("fast", True, "Skip checks."), ("speeds", (480.0, 960.0), "Spindle speeds [rpm]."),
        ("table", src, "Modes table [Hz, N/m]."), ("output", out, "File to write."),
        ("missing", Path(tmp_path / "nope.csv"), None),
    ])  # fmt: skip
    assert doc["units"] == {"x_mm": "mm", "k": "1", "speeds": "rpm"}  # no unit for files, bools
    assert doc["settings"]["speeds"] == [480.0, 960.0] and doc["settings"]["table"] == str(src)
    assert doc["inputs"] == [str(src)]  # the output and a missing file are not inputs


def test_workspace_predictor_reads_the_shipped_model_and_checks_inputs():
    from robovib.gp.chapter3_model import CHAPTER3_INPUTS, chapter3_model_path, workspace_predictor

    model = workspace_predictor()
    assert tuple(model.input_names) == CHAPTER3_INPUTS and type(model).__name__ == "PosePredictor"
    same = workspace_predictor(chapter3_model_path())
    np.testing.assert_array_equal(
        same.predict([[2400.0, 0.0, 45.0]]), model.predict([[2400.0, 0.0, 45.0]])
    )
    with pytest.raises(ValueError, match="s_m"):
        workspace_predictor(chapter3_model_path(), require_inputs=("s_m",))
