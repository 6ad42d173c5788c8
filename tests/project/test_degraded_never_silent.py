"""Degraded is never silent (issue 38 item 4): an uncalibrated model, a phase-free FRF, a cut
beyond the chatter limit, absurd cutting inputs and too few samples are all said."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from robovib.cli import app
from robovib.datasets import example_path
from robovib.frf import FRF
from robovib.io import read_frf_csv, read_frfs, write_frfs
from robovib.milling import CuttingConditions, MillingTool
from robovib.milling.cut_checks import implausible_cut_warnings, quantile_sample_warning

runner = CliRunner()
POSE = ["--x", "2400", "--y", "0", "--rz", "45"]


def _invoke(*args):
    res = runner.invoke(app, [str(a) for a in args])
    return res.exit_code, res.stdout + (res.stderr or "")


def _json(*args):
    code, out = _invoke(*args, "--json")
    assert code == 0, out
    return json.loads(out)


# ------------------------------------------------------------------------ uncalibrated model
@pytest.fixture(scope="module")
def uncalibrated(tmp_path_factory):
    """The shipped chapter-3 model saved, and a copy whose /calibration group is deleted."""
    import h5py

    from robovib.gp import load_chapter3_model

    folder = tmp_path_factory.mktemp("models")
    full = load_chapter3_model().save(folder / "full.h5")
    bare = load_chapter3_model().save(folder / "bare.h5")
    from robovib.files.h5safe import seal, seal_file

    with h5py.File(bare, "a") as h5:
        assert "calibration" in h5
        del h5["calibration"]
        seal(h5)  # a file written without calibration, not a damaged one
    seal_file(bare)
    return full, bare


def test_gpr_predict_says_uncalibrated_in_text_and_json(uncalibrated):
    full, bare = uncalibrated
    doc = _json("gpr", "predict", "--model", bare, *POSE)
    assert doc["calibrated"] is False and doc["bands"].startswith("uncalibrated")
    cal = _json("gpr", "predict", "--model", full, *POSE)
    assert cal["calibrated"] is True and "calibrated on a" in cal["bands"]
    # The bands of the bare file are narrower: the reason the word matters.
    w = {d["predictions"]["x_fn_hz"]["std"] for d in (doc, cal)}
    assert doc["predictions"]["x_fn_hz"]["std"] < cal["predictions"]["x_fn_hz"]["std"], w
    code, text = _invoke("gpr", "predict", "--model", bare, *POSE)
    assert code == 0 and "bands uncalibrated" in " ".join(text.split())
    code, text = _invoke("gpr", "predict", "--model", full, *POSE)
    assert "uncalibrated" not in text


def test_mill_commands_and_the_report_say_uncalibrated(uncalibrated):
    from robovib.report.kinds import model_report

    full, bare = uncalibrated
    doc = _json("mill", "predict", "--model", bare, *POSE, "--samples", "40")
    assert doc["calibrated"] is False
    assert any(w.startswith("bands uncalibrated") for w in doc["warnings"])
    lob = _json("mill", "lobes", "--model", bare, *POSE, "--rpm-range", "1500:2000:3")
    assert lob["calibrated"] is False and any("uncalibrated" in w for w in lob["warnings"])
    assert _json("mill", "lobes", "--model", full, *POSE, "--rpm-range", "1500:2000:3")[
        "calibrated"
    ]
    text = " ".join(p for s in model_report(bare).sections for p in s.paragraphs)
    assert "uncalibrated" in text and "Bands calibrated" not in text


# --------------------------------------------------------------------------- phase-free FRFs
def test_a_magnitude_only_csv_frf_is_refused(tmp_path):
    table = pd.read_csv(example_path("frf.csv"))
    (frf,) = read_frf_csv(example_path("frf.csv"))
    assert np.max(np.abs(frf.values.imag)) > 0.5 * np.max(np.abs(frf.values))  # a real FRF
    mag = np.hypot(table["x_real_um_per_n"], table["x_imag_um_per_n"])
    table["x_real_um_per_n"], table["x_imag_um_per_n"] = mag, 0.0
    path = tmp_path / "magnitude.csv"
    table.to_csv(path, index=False)
    with pytest.raises(ValueError, match=r"magnitude\.csv.*has no phase"):
        read_frf_csv(path)
    code, out = _invoke("mill", "lobes", "--frf", path, "--method", "zoa")
    assert code == 1 and "has no phase" in out and "magnitude.csv" in out


def test_real_valued_hdf5_and_uff_frfs_are_refused(tmp_path):
    import h5py

    f = 5.0 + 0.25 * np.arange(300)
    h = 1e-7 / (1 - (f / 20) ** 2 + 2j * 0.05 * f / 20)
    h5 = tmp_path / "frf.h5"
    write_frfs(h5, [FRF(f, h, direction="x")])
    assert np.allclose(read_frfs(h5)[0].values, h)  # the complex file reads
    from robovib.files.h5safe import seal, seal_file

    with h5py.File(h5, "a") as fh:
        (name,) = list(fh["frf"])
        del fh["frf"][name]["values"]
        fh["frf"][name]["values"] = np.abs(h)  # magnitude only, real dtype
        seal(fh)  # written so by another tool, not damaged
    seal_file(h5)
    with pytest.raises(
        ValueError, match=rf"frf\.h5: '?/?frf/{name}/values'?: .*(no phase|complex)"
    ):
        read_frfs(h5)
    with h5py.File(h5, "a") as fh:
        del fh["frf"][name]["values"]
        fh["frf"][name]["values"] = np.abs(h) + 0j  # magnitude only, complex dtype
        seal(fh)
    seal_file(h5)
    with pytest.raises(ValueError, match=rf"frf\.h5: /frf/{name}/values: FRF x has no phase"):
        read_frfs(h5)
    uff = tmp_path / "frf.uff"
    write_frfs(uff, [FRF(f, np.abs(h) + 0j, direction="x")])
    with pytest.raises(ValueError, match=r"frf\.uff: FRF record 0: FRF x has no phase"):
        read_frfs(uff)


# ------------------------------------------------------------------- mill predict vs lobes
def test_mill_predict_says_chatter_where_mill_lobes_does():
    lob = _json("mill", "lobes", *POSE, "--ae", "25.4", "--rpm-range", "1700:1800:3")
    limit_mm = 1e3 * lob["a_lim_m"][lob["rpm"].index(1750.0)]
    for factor, chatter in ((0.9, False), (1.1, True)):
        ap = f"{factor * limit_mm:.4f}"
        verdict = _json("mill", "lobes", *POSE, "--ae", "25.4", "--rpm-range", "1700:1800:3",
                        "--operating-point", f"1750,{ap}")["operating_point"]["stable"]  # fmt: skip
        assert verdict is (not chatter)
        doc = _json("mill", "predict", *POSE, "--ap", ap, "--rpm", "1750")
        st = doc["stability"]
        assert st["chatter_predicted"] is chatter and st["stable"] is (not chatter)
        assert st["critical_depth_m"] == pytest.approx(limit_mm / 1e3, rel=1e-9)
        code, text = _invoke("mill", "predict", *POSE, "--ap", ap, "--rpm", "1750")
        assert code == 0 and ("CHATTER predicted" in text) is chatter


# ------------------------------------------------------------ absurd inputs, too few samples
def test_absurd_depth_and_too_few_samples_are_warned():
    doc = _json("mill", "predict", *POSE, "--ap", "1e6", "--samples", "2")
    text = " ".join(doc["warnings"])
    assert "axial depth 1e+06 mm" in text and "no end mill" in text
    assert "exceeds the tool diameter" in text  # the 43 m deflection
    assert "--samples 2: too few draws" in text
    assert doc["stability"]["chatter_predicted"] is True
    assert _json("mill", "predict", *POSE)["warnings"] == []  # an ordinary cut: silent
    lob = _json("mill", "lobes", *POSE, "--rpm-range", "1500:2000:3", "--samples", "5")
    assert any("--samples 5: too few draws for a 5-95 % band" in w for w in lob["warnings"])


def test_plausibility_rules():
    tool = MillingTool(diameter_m=0.01)
    ok = CuttingConditions(1e4, 5e-5, 0.02, 0.005)
    assert implausible_cut_warnings(tool, ok, deflection_m=1e-4) == []
    deep = CuttingConditions(1e4, 5e-5, 0.0501, 0.005)  # just over 5 diameters
    assert "5 tool diameters" in implausible_cut_warnings(tool, deep)[0]
    fast = CuttingConditions(2e5, 6e-4, 0.02, 0.005)
    assert len(implausible_cut_warnings(tool, fast)) == 2  # feed 0.06 D, 200 000 rpm
    assert "exceeds the tool diameter" in implausible_cut_warnings(tool, ok, deflection_m=0.02)[0]
    # 2.5 % needs 40 draws to have one below it, 5 % needs 20.
    assert quantile_sample_warning(39, 0.025) and quantile_sample_warning(40, 0.025) is None
    assert quantile_sample_warning(19, 0.05) and quantile_sample_warning(20, 0.05) is None
    assert quantile_sample_warning(0, 0.05) is None
