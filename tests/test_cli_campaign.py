"""CLI of the own-robot workflow: sim campaign -> campaign process -> model fit -> next-poses ->
gpr predict --model (thin commands over robovib.campaign; numbers checked in test_campaign)."""

import json

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from robovib.cli import app

pytest.importorskip("pyuff")


def run(*args):
    res = CliRunner().invoke(app, [str(a) for a in args])
    return res


def test_campaign_cli_flow(tmp_path):
    rng = np.random.default_rng(0)
    n = 8
    poses = pd.DataFrame({"x_mm": np.linspace(2150, 2500, n), "y_mm": rng.uniform(-300, 600, n),
                          "rz_deg": rng.uniform(0, 180, n)})  # fmt: skip
    poses.to_csv(tmp_path / "poses.csv", index=False)
    camp = tmp_path / "camp"
    res = run("sim", "campaign", "--poses", tmp_path / "poses.csv", "-o", camp, "--hits", "2",
              "--truth", "3", "--json")  # fmt: skip
    assert res.exit_code == 0, res.output
    assert json.loads(res.output)["recordings"] == 3 * n
    out = camp / "out"
    res = run("campaign", "process", camp / "campaign.csv", "-o", out, "--workers", "1", "--json")
    assert res.exit_code == 0, res.output
    doc = json.loads(res.output)
    assert doc["n_rows"] == 3 * n and not doc["skipped"]
    assert {"fn_hz", "stiffness_n_per_m", "damping_ns_per_m", "n_hits_used"} <= set(doc["rows"][0])
    res = run("campaign", "process", camp / "campaign.csv", "-o", out, "--workers", "1")
    assert res.exit_code == 0 and "wrote" in res.output
    model = tmp_path / "model.h5"
    res = run("model", "fit", out / "modal.csv", "--inputs", "x_mm,y_mm,rz_deg", "-o", model,
              "--folds", "3", "--json")  # fmt: skip
    assert res.exit_code == 0, res.output
    doc = json.loads(res.output)
    assert doc["n_poses"] == n and len(doc["cv"]) == 9 and model.exists()
    res = run("model", "next-poses", "--model", model, "--candidates", tmp_path / "poses.csv",
              "--k", "2", "--plot", tmp_path / "next.png", "--json")  # fmt: skip
    assert res.exit_code == 0, res.output
    assert len(json.loads(res.output)["next_poses"]) == 2 and (tmp_path / "next.png").exists()
    res = run("gpr", "predict", "--model", model, "--x", 9999, "--y", 0, "--rz", 30, "--json")
    assert res.exit_code == 0, res.output
    doc = json.loads(res.output)
    assert doc["extrapolating"] and "x_mm" in doc["outside_inputs"]
    assert doc["predictions"][0]["output"] == "x_fn_hz"
    res = run("gpr", "predict", "--model", model, "--x", 2300, "--a1", 3)
    assert res.exit_code == 1 and "missing y_mm, rz_deg; not an input: a1_deg" in res.output


def test_campaign_process_bad_row(tmp_path):
    (tmp_path / "m.csv").write_text("file,direction,x_mm,y_mm,z_mm,rz_deg\nnone.uff,x,1,2,3,4\n")
    res = run("campaign", "process", tmp_path / "m.csv", "-o", tmp_path / "o", "--workers", "1")
    assert res.exit_code == 1
    assert "line 2: none.uff" in res.output and "no such file" in res.output
    assert not (tmp_path / "o").exists()
    res = run("campaign", "process", tmp_path / "m.csv", "-o", tmp_path / "o", "--skip-bad")
    assert res.exit_code == 1 and "every row failed" in res.output
