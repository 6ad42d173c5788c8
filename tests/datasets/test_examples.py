"""Example recordings shipped for each workflow: present, small, readable, and physically right."""

from __future__ import annotations

import csv

import numpy as np
import pytest

from robovib.datasets import EXAMPLES, copy_examples, example_path


def test_every_example_is_shipped_and_small():
    for name in EXAMPLES:
        p = example_path(name)
        assert p.is_file(), name
        assert p.stat().st_size < 300_000, f"{name}: {p.stat().st_size} bytes"
    with pytest.raises(ValueError, match=r"hammer\.uff"):
        example_path("nope.csv")


def test_hammer_examples_give_the_virtual_robots_mode():
    """FRF of each hammer example -> dominant X mode = the virtual robot's true mode (< 3 %)."""
    from robovib.frf import impact_frf
    from robovib.io import read_frf_csv, read_recording
    from robovib.modal import fit_dominant_mode
    from robovib.sim import VirtualRobot

    robot = VirtualRobot()
    poses = {"hammer.uff": (2.4, 0.0, 45.0), "hammer.csv": (2.1, 0.3, 90.0)}
    for name, pose in poses.items():
        rec = read_recording(example_path(name), "x")
        assert rec.n_hits == 3
        res = impact_frf(rec.forces, rec.responses, rec.sample_rate_hz,
                         response_quantity=rec.response_quantity, f_max_hz=60.0)  # fmt: skip
        fit = fit_dominant_mode(res.frf.to_compliance(5.0))
        true = robot.workspace.modes(np.array([pose]), "x").dominant()
        true_fn = float(np.ravel(true.fn_hz)[0])
        assert fit.parameters.natural_frequency_hz == pytest.approx(true_fn, rel=0.03), name
    (frf,) = read_frf_csv(example_path("frf.csv"))
    assert frf.direction == "x" and frf.quantity == "compliance"
    fit = fit_dominant_mode(frf)
    true = robot.workspace.modes(np.array([poses["hammer.uff"]]), "x").dominant()
    assert fit.parameters.natural_frequency_hz == pytest.approx(
        float(np.ravel(true.fn_hz)[0]), rel=0.03
    )


def test_milling_cuts_and_campaign_examples(tmp_path):
    from robovib.campaign.manifest import read_manifest
    from robovib.io import read_milling_record_csv

    rec = read_milling_record_csv(example_path("milling_record.csv"))
    assert rec["force_n"].shape[1] == 3
    assert rec["path_s_m"][0] == pytest.approx(0.635) and rec["path_s_m"][-1] == pytest.approx(
        0.735, abs=1e-3
    )
    with open(example_path("cuts.csv")) as fh:
        rows = list(csv.DictReader(line for line in fh if not line.startswith("#")))
    assert {r["result"] for r in rows} == {"stable", "chatter"}
    assert all(float(r["depth_mm"]) > 0 and float(r["spindle_rpm"]) > 0 for r in rows)
    copy_examples(tmp_path)
    manifest = read_manifest(tmp_path / "campaign.csv")
    assert [r.file.name for r in manifest] == ["hammer.uff", "hammer.csv"]
