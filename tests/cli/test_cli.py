"""End-to-end CLI runs on the shipped data."""

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from robovib.cli import app

runner = CliRunner()


def test_gpr_predict_json_interpolates_a_measured_pose():
    from robovib.datasets import load_table_a1

    result = runner.invoke(
        app, ["gpr", "predict", "--x", "2400", "--y", "0", "--rz", "45", "--json"]
    )
    assert result.exit_code == 0, result.output
    doc = json.loads(result.output)
    preds = doc["predictions"]
    assert len(preds) == 9 and doc["pose"] == {"x_mm": 2400.0, "y_mm": 0.0, "rz_deg": 45.0}
    # Test 27 of Table A1 (2400, 0, 45), SI: X fn 16.51 Hz in all three replicates.
    t27 = load_table_a1(units="si").query("test == 27")
    for out, col, rel in (
        ("x_fn_hz", "fn_x_hz", 0.02),
        ("y_fn_hz", "fn_y_hz", 0.03),
        ("z_fn_hz", "fn_z_hz", 0.03),
        ("x_stiffness_n_per_m", "stiffness_x_n_per_m", 0.1),
    ):
        assert preds[out]["mean"] == pytest.approx(t27[col].mean(), rel=rel), out
    x_fn = preds["x_fn_hz"]
    assert x_fn["unit"] == "Hz" and preds["x_stiffness_n_per_m"]["unit"] == "N/m"
    assert x_fn["lower_2sigma"] < x_fn["mean"] < x_fn["upper_2sigma"]
    assert doc["extrapolating"] is False and doc["outside_inputs"] == []
    assert 0 <= doc["high_mode_probability"]["x"] < 0.5


def test_gpr_predict_default_is_the_shipped_model_through_the_model_path():
    from robovib.gp.chapter3_model import chapter3_model_path

    args = ["gpr", "predict", "--x", "2300", "--y", "100", "--rz", "40", "--json"]
    a = json.loads(runner.invoke(app, args).output)
    b = json.loads(runner.invoke(app, [*args, "--model", str(chapter3_model_path())]).output)
    assert a["predictions"] == b["predictions"] and a["notes"] == b["notes"]
    res = runner.invoke(app, [*args, "--model", str(chapter3_model_path()), "--seed", "3"])
    assert res.exit_code == 1 and "do not apply to --model" in res.output


def test_gpr_predict_refit_options(monkeypatch, chapter3_factory):
    monkeypatch.setattr("robovib.gp.chapter3_model.fit_chapter3_model", chapter3_factory)
    args = ["gpr", "predict", "--x", "2400", "--y", "0", "--rz", "45", "--json"]
    res = runner.invoke(app, [*args, "--no-mode-switch"])
    assert res.exit_code == 0, res.output
    doc = json.loads(res.output)
    assert "refitted" in doc["model"] and doc["high_mode_probability"] == {}
    assert doc["predictions"]["x_fn_hz"]["mean"] == pytest.approx(16.51, rel=0.03)


def test_gpr_predict_flags_extrapolation_and_bad_kernel():
    result = runner.invoke(app, ["gpr", "predict", "--x", "3000", "--y", "0", "--rz", "45"])
    assert result.exit_code == 0
    assert "extrapolation" in result.output
    result = runner.invoke(
        app, ["gpr", "predict", "--x", "2400", "--y", "0", "--rz", "45", "--kernel", "rbf"]
    )
    assert result.exit_code != 0
    assert "unknown kernel" in result.output
    result = runner.invoke(app, ["gpr", "predict", "--x", "2400", "--y", "0"])
    assert result.exit_code == 1 and "missing rz_deg" in result.output


def test_demo_json():
    result = runner.invoke(app, ["demo", "--json"])
    assert result.exit_code == 0, result.output
    doc = json.loads(result.output)
    rows = doc["outputs"]
    assert len(rows) == 9
    plain = np.array([r["gpr_plain_rmse"] for r in rows])
    grouped = np.array([r["gpr_grouped_rmse"] for r in rows])
    # Replicate leakage: held-out replicates are easier than held-out poses (thesis notes).
    assert np.sum(grouped > plain) >= 8
    # The GP beats the cross-validated quadratic baseline in plain CV on every output.
    assert np.all(plain < np.array([r["mlr_cv_rmse"] for r in rows]))
