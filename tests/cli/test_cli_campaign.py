"""CLI of the own-robot workflow: sim campaign -> campaign process -> model fit -> next-poses ->
gpr predict --model (thin commands over robovib.campaign; numbers checked in test_campaign)."""

import json

import numpy as np
import pandas as pd
from typer.testing import CliRunner

from robovib.cli import app


def run(*args):
    from helpers import assert_self_describing

    argv = [str(a) for a in args]
    res = CliRunner().invoke(app, argv)
    if "--json" in argv and res.exit_code == 0:
        assert_self_describing(json.loads(res.stdout), argv)
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
    assert next(iter(doc["predictions"])) == "x_fn_hz"
    assert doc["predictions"]["x_fn_hz"]["unit"] == "Hz"
    for cmd in (("mill", "lobes"), ("control", "gains")):
        res = run(*cmd, "--x", 2300, "--y", 100, "--rz", 40, "--model", model, "--json")
        assert res.exit_code == 0, (cmd, res.output)
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


def test_frf_compute_reports_what_the_reader_did(tmp_path):
    """A continuous UFF record written by pyuff with 3 hits: cut, reported in --json."""
    import pyuff

    fs, n = 1024.0, 3 * 1024
    t = np.arange(n) / fs
    force = sum(np.where((t >= t0) & (t <= t0 + 0.004), 400 * np.sin(np.pi * (t - t0) / 0.004), 0)
                for t0 in (0.1, 1.1, 2.1))  # fmt: skip
    resp = sum(np.where(t >= t0, np.exp(-4 * (t - t0)) * np.sin(2 * np.pi * 20 * (t - t0)), 0)
               for t0 in (0.1, 1.1, 2.1))  # fmt: skip
    sets = [pyuff.prepare_58(binary=0, func_type=1, rsp_node=1, rsp_dir=d, ref_node=1, ref_dir=2,
                             ordinate_spec_data_type=spec, ordinate_axis_units_lab=lab,
                             orddenom_spec_data_type=0, abscissa_spacing=1, data=v, x=t)
            for d, spec, lab, v in ((2, 13, "N", force), (2, 12, "m/s^2", resp))]  # fmt: skip
    pyuff.UFF(str(tmp_path / "cont.uff")).write_sets(sets, mode="add")
    res = run(
        "frf", "compute", tmp_path / "cont.uff", "-o", tmp_path / "f.h5", "--fmax", "100", "--json"
    )
    assert res.exit_code == 0, res.output
    doc = json.loads(res.output)
    assert doc["direction"] == "y" and doc["n_hits"] == 3
    assert doc["reader"]["layout"] == "continuous" and doc["reader"]["hits_formed"] == 3
    res = run("frf", "compute", tmp_path / "cont.uff", "-o", tmp_path / "f.h5", "--direction", "x")
    assert res.exit_code == 1 and "contradicts the file" in res.output
