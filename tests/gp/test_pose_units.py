"""One pose unit convention: values named with their units, converted to a model's inputs."""

from __future__ import annotations

import math

import numpy as np
import pytest

from robovib.gp.pose_units import pose_in_units, split_unit


def test_millimetres_and_radians_reach_the_model_units():
    pose = pose_in_units(
        ("x_m", "y_m", "rz_deg"), {"x_mm": 1200.0, "y_mm": -50.0, "rz_rad": math.pi}
    )
    np.testing.assert_allclose(pose, [1.2, -0.05, 180.0], rtol=1e-15)
    # the CLI's former hand conversion (x / 1e3) is reproduced bit for bit
    assert pose[0] == 1200.0 / 1e3 and pose[1] == -50.0 / 1e3
    back = pose_in_units(("x_mm", "rz_deg"), {"x_m": 1.2, "rz_deg": 45.0, "s_m": None})
    np.testing.assert_allclose(back, [1200.0, 45.0], rtol=1e-15)


def test_unused_and_missing_values():
    assert pose_in_units(("s_m",), {"s_m": 0.585, "x_mm": None, "y_mm": 3.0}).tolist() == [0.585]
    with pytest.raises(ValueError, match=r"give x \[mm\], y \[m\], rz \[deg\].*given: s \[m\]"):
        pose_in_units(("x_m", "y_m", "rz_deg"), {"s_m": 0.5, "x_mm": None})
    with pytest.raises(ValueError, match="given in deg"):
        pose_in_units(("x_m",), {"x_deg": 1.0})
    with pytest.raises(ValueError, match="finite"):
        pose_in_units(("x_m",), {"x_mm": float("nan")})
    with pytest.raises(ValueError, match="<quantity>_<unit>"):
        split_unit("x")
    with pytest.raises(ValueError, match="<quantity>_<unit>"):
        split_unit("x_furlong")


def test_hybrid_predict_cli_takes_millimetres_for_a_metre_model(tmp_path):
    """``hybrid predict --x/--y [mm]`` on a workspace model with inputs in metres: the CLI
    passes named values, the library converts; the result is the model's at the SI pose."""
    import json

    from typer.testing import CliRunner

    from robovib.cli import app
    from robovib.hybrid import FRFPoseModel

    f = np.linspace(2.0, 30.0, 15)
    rng = np.random.default_rng(0)
    poses = np.column_stack(
        [rng.uniform(1.0, 1.5, 8), rng.uniform(-0.2, 0.2, 8), rng.uniform(0, 90, 8)]
    )
    fn = 10.0 - 3.0 * (poses[:, 0] - 1.0)
    r = f[None, :] / fn[:, None]
    h = 1.0 / (1e6 * (1 - r**2 + 0.3j * r))
    names = ("x_m", "y_m", "rz_deg")
    model = FRFPoseModel(f, kernel="ard", input_names=names, rng=0).fit(poses, h)
    model.save(tmp_path / "m.h5")
    args = ["hybrid", "predict", str(tmp_path / "m.h5"), "--x", "1250", "--y", "-40", "--rz", "30"]
    res = CliRunner().invoke(app, [*args, "--json"])
    assert res.exit_code == 0, res.output
    doc = json.loads(res.output)
    expect = np.abs(FRFPoseModel.load(tmp_path / "m.h5").predict([[1.25, -0.04, 30.0]]))[0]
    np.testing.assert_allclose(doc["compliance_abs_um_per_n"], 1e6 * expect, rtol=1e-9)
    assert doc["x_m"] == pytest.approx(1.25) and doc["y_m"] == pytest.approx(-0.04)
    res = CliRunner().invoke(app, args[:-2])  # no --rz
    assert res.exit_code != 0 and "give --x [mm], --y [mm], --rz [deg]" in res.output


def test_frf_compute_stores_a_workspace_pose_given_in_millimetres_in_metres(tmp_path):
    from typer.testing import CliRunner

    from robovib.cli import app
    from robovib.datasets import example_path
    from robovib.io import read_frfs

    out = tmp_path / "f.h5"
    args = ["frf", "compute", str(example_path("hammer.uff")), "-o", str(out)]
    res = CliRunner().invoke(app, [*args, "--x", "1250", "--y", "-40", "--rz", "30"])
    assert res.exit_code == 0, res.output
    pose = read_frfs(out)[0].pose
    np.testing.assert_allclose(np.take(pose, [0, 1, 5]), [1.25, -0.04, 30.0], rtol=1e-15)
    assert np.all(np.isnan(np.take(pose, [2, 3, 4])))
