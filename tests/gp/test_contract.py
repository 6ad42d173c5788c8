"""The pose-model contract (robovib.gp.contract): every model kind, every pose command.

References: the smooth fields and mode counts the synthetic multi-mode table was built from,
the compliance peak found by scanning each mode's FRF, and direct lobe computations.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from helpers import synthetic_modes_table
from typer.testing import CliRunner

from robovib.cli import app
from robovib.gp import PosePredictor, load_chapter3_model
from robovib.gp.contract import DOMINANT, MULTIMODE, PoseModel, pick_mode
from robovib.gp.loader import load_pose_model

POSE = (2350.0, 100.0, 60.0)


@pytest.fixture(scope="module")
def models(tmp_path_factory):
    """A multi-mode model (x1, x2, y1) of a synthetic table, and the chapter-3 model, saved."""
    from robovib.campaign import fit_multimode_pose_model, track_modes

    folder = tmp_path_factory.mktemp("models")
    table, _, fields = synthetic_modes_table(n=16)
    tracked, _ = track_modes(table)
    multi = fit_multimode_pose_model(tracked, n_folds=3, covariance="se").model
    paths = {"multi": multi.save(folder / "modes.h5"),
             "dominant": load_chapter3_model().save(folder / "ch3.h5")}  # fmt: skip
    return paths, table, fields


@pytest.mark.parametrize("kind", ["multi", "dominant"])
def test_both_readers_honour_the_contract_with_the_same_numbers(models, kind):
    paths, _, _ = models
    full = load_pose_model(paths[kind])
    fast = load_pose_model(paths[kind], predict_only=True)
    assert isinstance(fast, PosePredictor) and not isinstance(full, PosePredictor)
    for m in (full, fast):
        assert isinstance(m, PoseModel)
    assert full.kind == fast.kind == (MULTIMODE if kind == "multi" else DOMINANT)
    X = np.array([POSE, (2200.0, 400.0, 120.0)])
    np.testing.assert_allclose(full.predict(X), fast.predict(X), rtol=1e-9)
    np.testing.assert_allclose(full.samples(X, 50, rng=3), fast.samples(X, 50, rng=3), rtol=1e-6)
    assert full.calibrated == fast.calibrated
    a, b = full.mode_set(X)[0], fast.mode_set(X)[0]
    assert {d: [m.mode_id for m in v] for d, v in a.items()} == {
        d: [m.mode_id for m in v] for d, v in b.items()
    }
    bands = fast.bands(X, 0.95, "latent")
    mean = fast.predict(X)
    for r in range(2):
        for j in range(mean.shape[1]):
            assert any(lo <= mean[r, j] <= hi for lo, hi in bands[r][j])
    assert set(fast.input_range()) == set(fast.input_names)


def test_mode_set_gives_every_mode_with_presence(models):
    paths, table, _ = models
    model = load_pose_model(paths["multi"], predict_only=True)
    row = model.mode_set(np.array([POSE]))[0]
    assert [m.mode_id for m in row["x"]] == ["x1", "x2"] and [m.mode_id for m in row["y"]] == ["y1"]
    s = (POSE[0] - 2100) / 500  # the fields of synthetic_modes_table
    assert row["x"][0].parameters.natural_frequency_hz == pytest.approx(15 + 6 * s, rel=0.03)
    assert row["x"][1].parameters.natural_frequency_hz == pytest.approx(40 + 15 * s, rel=0.03)
    n_rec = table[table["direction"] == "x"]["row"].nunique()
    n_x2 = int((table["true_id"] == "x2").sum())
    assert row["x"][1].presence == pytest.approx(n_x2 / n_rec)
    assert row["x"][0].presence == 1.0 and row["x"][0].weights == (1.0, 0.0)
    assert model.provenance["multimode"] == 1


def test_pick_mode_takes_the_largest_compliance_peak_and_says_why(models):
    paths, _, _ = models
    model = load_pose_model(paths["multi"], predict_only=True)
    picked = pick_mode(model, POSE, "x")
    freq = np.linspace(1.0, 120.0, 200_001)
    peaks = {m.mode_id: np.max(np.abs(m.parameters.compliance(freq))) for m in picked.candidates}
    assert picked.mode.mode_id == max(peaks, key=peaks.get)
    for m in picked.candidates:  # the closed form agrees with the scanned FRF
        assert m.compliance_peak_m_per_n == pytest.approx(peaks[m.mode_id], rel=1e-4)
    assert "largest compliance peak" in picked.reason and "x2" in picked.reason
    assert pick_mode(model, POSE, "y").reason == ""  # one mode: nothing to explain
    with pytest.raises(ValueError, match=r"unknown direction .w."):
        pick_mode(model, POSE, "w")


def test_most_stable_speed_wants_margin_on_both_sides():
    from robovib.milling.envelope import LobeEnvelope

    rpm = np.linspace(1000, 3000, 201)  # 10 rpm apart
    a = 1e-3 + 2e-3 * np.exp(-(((rpm - 2500) / 150) ** 2))  # a broad lobe: 3 mm at 2500 rpm
    a[np.argmin(np.abs(rpm - 1500))] = 4e-3  # a one-speed spike, higher than the broad lobe
    env = LobeEnvelope(rpm, a, np.full(rpm.size, 20.0), np.array(["hopf"] * rpm.size), "sdm")
    best_rpm, depth = env.most_stable_speed()
    assert best_rpm == pytest.approx(2500.0)
    window = np.abs(rpm - 2500) <= 0.02 * 2500  # the depth is stable over ±2 % of the speed
    assert depth == pytest.approx(a[window].min(), rel=1e-9)


def _run(*args):
    res = CliRunner().invoke(app, [str(a) for a in args])
    assert res.exit_code == 0, f"{args}: {res.output}"
    return res.output


@pytest.mark.parametrize("kind", ["multi", "dominant"])
def test_every_pose_command_takes_either_model(models, kind, tmp_path):
    paths, _, _ = models
    m = paths[kind]
    pose = ("--x", POSE[0], "--y", POSE[1], "--rz", POSE[2])
    cand = tmp_path / "cand.csv"
    cand.write_text("x_mm,y_mm,rz_deg\n2300,100,40\n2400,0,90\n2200,300,120\n")
    _run("mill", "predict", *pose, "--samples", 3, "--model", m)
    out = _run("mill", "lobes", *pose, "--method", "zoa", "--rpm-range", "1000:3000:30",
               "--samples", 8, "--model", m)  # fmt: skip
    if kind == "multi":
        assert "x1, x2, y1" in out
    doc = json.loads(_run("mill", "map", "--rz", 60, "--nx", 3, "--ny", 2, "--rpm", 2000,
                          "--samples", 4, "--depth", 1.0, "--scheduler", "sync", "--model", m,
                          "--json"))  # fmt: skip
    lo, hi = doc["best_sure_depth_band_m"]
    assert 0 < lo <= hi
    p = np.asarray(doc["p_stable"], float)
    assert np.all((p[np.isfinite(p)] >= 0) & (p[np.isfinite(p)] <= 1))
    out = _run("control", "gains", *pose, "--direction", "x", "--model", m)
    assert ("largest compliance peak" in out) == (kind == "multi")
    _run("control", "schedule", "--start", "2250,0,60", "--end", "2450,300,60", "--points", 5,
         "--model", m)  # fmt: skip
    _run("model", "next-poses", "--candidates", cand, "--k", 2, "--model", m)
    _run("report", "lobes", *pose, "--method", "zoa", "--rpm-range", "1000:3000:30",
         "--samples", 4, "--model", m, "-o", tmp_path / "l.html")  # fmt: skip
    assert (
        "5 % quantile" in (tmp_path / "l.html").read_text()
        or "p05" in (tmp_path / "l.html").read_text()
    )
    _run("report", "model", m, "-o", tmp_path / "m.html")
    _run("report", "control", "--model", m, "--start", "2250,0,60", "--end", "2450,300,60",
         "-o", tmp_path / "c.html")  # fmt: skip


def test_map_of_a_multimode_model_uses_every_mode(models):
    """The map's deterministic limit at a pose = the ZOA envelope of all its mean modes."""
    from robovib.milling import ALUMINIUM_7075, CuttingConditions, MillingTool
    from robovib.milling.lobes import zoa_envelope
    from robovib.milling.maps import workspace_lobe_map
    from robovib.milling.stability import stability_lobes

    paths, _, _ = models
    model = load_pose_model(paths["multi"], predict_only=True)
    tool, cond = MillingTool(), CuttingConditions(1900.0, 0.058e-3, 1e-3, 6e-3)
    rpm = np.array([1500.0, 2500.0])
    ds = workspace_lobe_map(model, [2300.0], [100.0], [60.0], rpm, tool, cond, ALUMINIUM_7075,
                            method="zoa", scheduler="sync")  # fmt: skip
    row = model.mode_set(np.array([[2300.0, 100.0, 60.0]]))[0]
    direct = zoa_envelope(stability_lobes([m.parameters for m in row["x"]],
                                          [m.parameters for m in row["y"]], tool, cond,
                                          ALUMINIUM_7075), rpm)  # fmt: skip
    np.testing.assert_allclose(ds["a_lim_m"].values[0, 0, 0], direct.a_lim_m, rtol=1e-9)
    assert ds.attrs["feed_modes"] == "x1,x2"


def test_robot_stiffness_says_when_the_analytical_model_is_far_too_soft():
    from robovib.gp.chapter3_model import workspace_predictor

    out = _run("robot", "stiffness", "--x", 2400, "--y", 0, "--rz", 45)
    measured = workspace_predictor().modes(np.array([[2400.0, 0.0, 45.0]]))[0]["x"]
    k_mn = measured.parameters.stiffness_n_per_m / 1e6
    assert "X: the analytical model gives" in out and f"{k_mn:.2f} MN/m" in out
