"""End-to-end CLI runs on the shipped data."""

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from robovib.cli import app

runner = CliRunner()


def test_gpr_predict_json_interpolates_a_measured_pose():
    result = runner.invoke(
        app, ["gpr", "predict", "--x", "2400", "--y", "0", "--rz", "45", "--json"]
    )
    assert result.exit_code == 0, result.output
    doc = json.loads(result.output)
    preds = {p["output"]: p for p in doc["predictions"]}
    assert len(preds) == 9
    # Test 27 of Table A1 (2400, 0, 45): X fn 16.51 Hz in all three replicates.
    assert preds["X fn [Hz]"]["mean"] == pytest.approx(16.51, abs=0.3)
    assert (
        preds["X fn [Hz]"]["lower_2sigma"]
        < preds["X fn [Hz]"]["mean"]
        < preds["X fn [Hz]"]["upper_2sigma"]
    )
    assert doc["extrapolation"] == []


def test_gpr_predict_flags_extrapolation_and_bad_kernel():
    result = runner.invoke(app, ["gpr", "predict", "--x", "3000", "--y", "0", "--rz", "45"])
    assert result.exit_code == 0
    assert "extrapolation" in result.output
    result = runner.invoke(
        app, ["gpr", "predict", "--x", "2400", "--y", "0", "--rz", "45", "--kernel", "rbf"]
    )
    assert result.exit_code != 0
    assert "unknown kernel" in result.output


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
