"""``mill lobes`` reads the FRF and cuts files itself and hands their values to the library."""

import json

import numpy as np
from typer.testing import CliRunner

from robovib.cli import app
from robovib.frf import FRF
from robovib.io import read_cuts_csv, read_frfs, write_frfs
from robovib.milling import ALUMINIUM_7075, CuttingConditions, MillingTool
from robovib.milling.chart import lobes_chart
from robovib.milling.sdm import sdm_lobes
from robovib.modal import ModalParameters

TOOL = MillingTool(diameter_m=0.016, n_flutes=3, helix_deg=30.0)
COND = CuttingConditions(5000, 1e-4, 1e-3, 4e-3, down_milling=False)
MX, MY = ModalParameters(600.0, 6e6, 0.03), ModalParameters(700.0, 8e6, 0.025)
RPM = np.linspace(3000, 15000, 40)
ARGS = ["mill", "lobes", "--teeth", "3", "--diameter", "16", "--radial-immersion", "0.25",
        "--milling", "up", "--rpm-range", "3000:15000:40"]  # fmt: skip


def test_cli_chart_from_an_frf_file_is_the_library_chart_of_its_values(tmp_path):
    f = np.linspace(100, 1500, 1401)
    path = tmp_path / "tooltip.h5"
    write_frfs(path, [FRF(f, MX.compliance(f), direction="x"),
                      FRF(f, MY.compliance(f), direction="y")])  # fmt: skip
    cuts = tmp_path / "cuts.csv"
    cuts.write_text("spindle_rpm,depth_mm,result\n6000,0.5,stable\n9000,40,chatter\n")
    res = CliRunner().invoke(app, [*ARGS, "--frf", str(path), "--cuts", str(cuts), "--json"])
    assert res.exit_code == 0, res.output
    doc = json.loads(res.output)
    # independent: the closed-form modes the FRFs were made from (LSCF refit within 2 %)
    direct = sdm_lobes([MX], [MY], TOOL, COND, ALUMINIUM_7075, RPM)
    np.testing.assert_allclose(doc["a_lim_m"], direct.a_lim_m, rtol=0.02)
    # the library called with the file's values gives the same chart
    chart = lobes_chart(tool=TOOL, conditions=COND, coefficients=ALUMINIUM_7075, spindle_rpm=RPM,
                        frfs=read_frfs(path), frf_label=str(path), cuts=read_cuts_csv(cuts),
                        material_label="al7075")  # fmt: skip
    np.testing.assert_allclose(doc["a_lim_m"], chart.envelope.a_lim_m, rtol=1e-12)
    assert doc["frf_file"] == str(path) and doc["title"] == chart.title
    assert "FRF tooltip.h5" in doc["title"] and doc["cuts"]["chatter"] == [False, True]


def test_cli_frf_errors_name_the_file(tmp_path):
    f = np.linspace(100, 1500, 701)
    path = tmp_path / "z.h5"
    write_frfs(path, [FRF(f, MX.compliance(f), direction="z")])
    res = CliRunner().invoke(app, [*ARGS, "--frf", str(path)])
    assert res.exit_code == 1
    assert f"error: {path}: no FRF with direction x or y" in res.output
    noisy = tmp_path / "noise.h5"
    rng = np.random.default_rng(0)
    write_frfs(noisy, [FRF(f, 1e-9 * (rng.normal(size=f.size) + 1j * rng.normal(size=f.size)),
                           direction="x")])  # fmt: skip
    res = CliRunner().invoke(app, [*ARGS, "--frf", str(noisy)])
    assert res.exit_code == 1
    assert f"error: {noisy}: the modes of the x FRF cannot be identified for SDM" in res.output
