"""mill-lobes library side: modes or measured FRFs, cuts, operating point, figure."""

import numpy as np
import pytest

from robovib.frf import FRF
from robovib.io import read_cuts_csv, read_frfs
from robovib.milling import ALUMINIUM_7075, CuttingConditions, MillingTool
from robovib.milling.chart import lobes_chart, plot_lobes_chart
from robovib.milling.lobes import LobeEnvelope
from robovib.milling.sdm import sdm_lobes
from robovib.modal import ModalParameters

TOOL = MillingTool(diameter_m=0.016, n_flutes=3, helix_deg=30.0)
COND = CuttingConditions(5000, 1e-4, 1e-3, 4e-3, down_milling=False)
MX, MY = ModalParameters(600.0, 6e6, 0.03), ModalParameters(700.0, 8e6, 0.025)
RPM = np.linspace(3000, 15000, 40)


def _write_frf_csv(path, unit_scale=1e6):
    f = np.linspace(100, 1500, 2801)
    gx, gy = MX.compliance(f) * unit_scale, MY.compliance(f) * unit_scale
    np.savetxt(path, np.column_stack([f, gx.real, gx.imag, gy.real, gy.imag]), delimiter=",",
               header="frequency_hz,x_real_um_per_n,x_imag_um_per_n,y_real_um_per_n,y_imag_um_per_n",
               comments="")  # fmt: skip


def test_chart_from_modes_and_from_a_measured_frf_csv(tmp_path):
    direct = sdm_lobes([MX], [MY], TOOL, COND, ALUMINIUM_7075, RPM)
    chart = lobes_chart(tool=TOOL, conditions=COND, coefficients=ALUMINIUM_7075, spindle_rpm=RPM,
                        modes_x=[MX], modes_y=[MY], pose_label="X 2400 Y 0 Rz 45",
                        material_label="Al 7075")  # fmt: skip
    np.testing.assert_allclose(chart.envelope.a_lim_m, direct.a_lim_m)
    path = tmp_path / "frf.csv"
    _write_frf_csv(path)
    from_frf = lobes_chart(tool=TOOL, conditions=COND, coefficients=ALUMINIUM_7075, spindle_rpm=RPM,
                           frfs=read_frfs(path))  # fmt: skip
    # Modes identified from the FRF (LSCF) give the same lobes within 2 %.
    np.testing.assert_allclose(from_frf.envelope.a_lim_m, direct.a_lim_m, rtol=0.02)
    zoa_modes = lobes_chart(tool=TOOL, conditions=COND, coefficients=ALUMINIUM_7075, spindle_rpm=RPM,
                            modes_x=[MX], modes_y=[MY], method="zoa")  # fmt: skip
    zoa_frf = lobes_chart(tool=TOOL, conditions=COND, coefficients=ALUMINIUM_7075, spindle_rpm=RPM,
                          frfs=read_frfs(path), method="zoa")  # fmt: skip
    np.testing.assert_allclose(zoa_frf.envelope.a_lim_m, zoa_modes.envelope.a_lim_m, rtol=0.02)
    # the same values made in memory (the file holds µm/N) give the same chart
    f = np.linspace(100, 1500, 2801)
    in_memory = lobes_chart(tool=TOOL, conditions=COND, coefficients=ALUMINIUM_7075, spindle_rpm=RPM,
                            frfs=[FRF(f, MX.compliance(f), direction="x"),
                                  FRF(f, MY.compliance(f), direction="y")])  # fmt: skip
    np.testing.assert_allclose(in_memory.envelope.a_lim_m, from_frf.envelope.a_lim_m, rtol=1e-6)
    doc = from_frf.to_dict()
    assert len(doc["rpm"]) == len(doc["a_lim_m"]) == RPM.size
    assert doc["tool"]["n_flutes"] == 3 and doc["cutting"]["milling"] == "up"


def test_chart_with_cuts_operating_point_and_figure(tmp_path):
    cuts = tmp_path / "cuts.csv"
    cuts.write_text(
        "spindle_rpm,depth_mm,result\n6000,0.5,stable\n6000,6,chatter\n9000,1.0,Stable\n"
    )
    a = sdm_lobes([MX], [MY], TOOL, COND, ALUMINIUM_7075, [9000.0]).a_lim_m[0]
    chart = lobes_chart(tool=TOOL, conditions=COND, coefficients=ALUMINIUM_7075, spindle_rpm=RPM,
                        modes_x=[MX], modes_y=[MY], cuts=read_cuts_csv(cuts),
                        operating_point=(9000.0, 1.3 * a),
                        pose_label="X 2400 Y 0 Rz 45", material_label="Al 7075")  # fmt: skip
    assert chart.operating_point_stable is False
    assert list(chart.cuts.chatter) == [False, True, False]
    fig = plot_lobes_chart(chart)
    ax = fig.axes[0]
    assert ax.get_xlabel() == "spindle speed [rpm]" and ax.get_ylabel() == "axial depth of cut [mm]"
    assert (
        "X 2400" in ax.get_title() and "Al 7075" in ax.get_title() and "3 teeth" in ax.get_title()
    )
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert any("operating point (chatter)" in t for t in labels) and any(
        "cut: chatter" in t for t in labels
    )
    with pytest.raises(ValueError, match="line 2"):
        bad = tmp_path / "bad.csv"
        bad.write_text("spindle_rpm,depth_mm,result\n6000,0.5,maybe\n")
        read_cuts_csv(bad)
    with pytest.raises(ValueError, match="depth_mm"):
        bad.write_text("spindle_rpm,depth,result\n6000,0.5,stable\n")
        read_cuts_csv(bad)


def test_most_stable_speed_is_an_interior_maximum():
    rpm = np.linspace(1000, 2000, 11)
    rising = LobeEnvelope(
        rpm, np.linspace(1e-3, 2e-3, 11), np.full(11, np.nan), np.full(11, "hopf"), "sdm"
    )
    assert rising.most_stable_speed() is None  # the edge of the range is not an answer
    bump = 1e-3 + 1e-3 * np.exp(-(((rpm - 1300) / 100) ** 2)) + 2e-3 * (rpm == 2000)
    env = LobeEnvelope(rpm, bump, np.full(11, np.nan), np.full(11, "hopf"), "sdm")
    assert env.most_stable_speed()[0] == 1300
    chart = sdm_lobes([MX], [MY], TOOL, COND, ALUMINIUM_7075, RPM)
    best = chart.most_stable_speed()
    assert best is not None and RPM[0] < best[0] < RPM[-1]


def test_cli_mill_lobes_with_explicit_modes_frf_cuts_and_operating_point(tmp_path):
    import json

    from typer.testing import CliRunner

    from robovib.cli import app

    cuts = tmp_path / "cuts.csv"
    cuts.write_text("spindle_rpm,depth_mm,result\n6000,0.5,stable\n")
    common = ["mill", "lobes", "--teeth", "3", "--diameter", "16", "--radial-immersion", "0.25",
              "--milling", "up", "--rpm-range", "3000:15000:40", "--json"]  # fmt: skip
    res = CliRunner().invoke(app, [*common, "--mode", "x:600,6e6,0.03", "--mode", "y:700,8e6,0.025",
                                   "--cuts", str(cuts), "--operating-point", "9000,50",
                                   "--plot", str(tmp_path / "l.png")])  # fmt: skip
    assert res.exit_code == 0, res.output
    doc = json.loads(res.output)
    np.testing.assert_allclose(
        doc["a_lim_m"], sdm_lobes([MX], [MY], TOOL, COND, ALUMINIUM_7075, RPM).a_lim_m
    )
    assert doc["operating_point"]["stable"] is False and doc["cuts"]["chatter"] == [False]
    assert doc["tool"]["diameter_m"] == pytest.approx(0.016) and (tmp_path / "l.png").stat().st_size
    path = tmp_path / "frf.csv"
    _write_frf_csv(path)
    res = CliRunner().invoke(app, [*common, "--frf", str(path), "--method", "zoa"])
    assert res.exit_code == 0, res.output
    assert json.loads(res.output)["method"] == "zoa"
    res = CliRunner().invoke(app, [*common, "--mode", "q:1,2,0.1"])
    assert res.exit_code == 1 and "direction" in res.output


def test_flip_count():
    """The chart counts the speeds whose limit is a flip (period-doubling) lobe."""
    import doctest
    from types import SimpleNamespace

    from robovib.milling import chart as ch

    mx, my = (ModalParameters(16.5, 3.4e6, 0.11),), (ModalParameters(8.2, 1e6, 0.18),)
    assert doctest.testmod(ch, verbose=False).failed == 0
    env = SimpleNamespace(kind=np.array(["hopf", "flip", "flip", "hopf", "flip"]))
    chart = ch.LobesChart(env, mx, my, None, None, None, "t")
    assert chart.n_flip_limited == 3
    assert ch.LobesChart(SimpleNamespace(kind=np.array(["hopf"])), mx, my, None, None, None,
                         "t").n_flip_limited == 0  # fmt: skip


def test_operating_point_p_stable_median_and_settings_actually_used():
    # P(stable) of the operating point is the fraction of sampled envelopes above it (counted
    # here from the samples themselves), the JSON has the median of the limit, and the settings
    # echo the radial depth and coefficients that were used, not the overridden defaults.
    import json

    from typer.testing import CliRunner

    from robovib.cli import app

    args = ["mill", "lobes", "--x", "2400", "--y", "0", "--rz", "45", "--samples", "6",
            "--rpm-range", "1500:2500:11", "--radial-immersion", "0.3", "--kt", "7e8",
            "--operating-point", "2000,0.9"]  # fmt: skip
    res = CliRunner().invoke(app, [*args, "--json"])
    assert res.exit_code == 0, res.output
    doc = json.loads(res.output)
    prob = doc["probability"]
    assert "a_lim_p50_m" in prob
    assert prob["a_lim_p05_m"] <= prob["a_lim_p50_m"] <= prob["a_lim_p95_m"]
    assert doc["settings"]["ae"] == pytest.approx(0.3 * 25.4)
    assert doc["material"] != "al7075" and "Kt" in doc["material"]
    assert doc["settings"]["material_name"] == doc["material"]
    from robovib.gp.chapter3_model import load_chapter3_predictor
    from robovib.milling.chart import cutting_setup
    from robovib.milling.uncertainty import mode_distribution_at_pose, stability_probability

    tool, cond, coef = cutting_setup(ALUMINIUM_7075, diameter_m=0.0254, n_flutes=2,
                                     helix_deg=30.0, radial_immersion=0.3, ktc_n_per_m2=7e8)  # fmt: skip
    dist = mode_distribution_at_pose(load_chapter3_predictor(), (2400, 0, 45))
    p = stability_probability(dist, tool, cond, coef, np.linspace(1500, 2500, 11), n_samples=6)
    expected = float(np.mean(p.a_lim_samples_m[:, 5] > 0.9e-3))  # 2000 rpm is a chart speed
    assert doc["operating_point"]["p_stable"] == pytest.approx(expected)
    res = CliRunner().invoke(app, args)
    assert res.exit_code == 0, res.output
    assert f"P(stable) = {expected:.2f} (6 samples)" in res.output


def test_chart_from_frf_values_built_in_memory():
    """FRFs made in memory (no file) give the chart the file gives; the label only names them."""
    f = np.linspace(100, 1500, 2801)
    # displacement per force from the closed-form SDOF; the chart converts mobility back.
    frfs = [FRF(f, 1j * 2 * np.pi * f * MX.compliance(f), quantity="mobility", direction="x"),
            FRF(f, MY.compliance(f), direction="y"), FRF(f, MX.compliance(f), direction="z")]  # fmt: skip
    kw = dict(tool=TOOL, conditions=COND, coefficients=ALUMINIUM_7075, spindle_rpm=RPM)
    direct = sdm_lobes([MX], [MY], TOOL, COND, ALUMINIUM_7075, RPM)
    chart = lobes_chart(frfs=frfs, frf_label="bench/tooltip.h5", **kw)
    np.testing.assert_allclose(chart.envelope.a_lim_m, direct.a_lim_m, rtol=0.02)
    assert (
        chart.frf_file == "bench/tooltip.h5" and chart.to_dict()["frf_file"] == "bench/tooltip.h5"
    )
    assert "SDM, FRF tooltip.h5" in chart.title
    unlabelled = lobes_chart(frfs=frfs, **kw)
    assert unlabelled.frf_file is None and "SDM, measured FRF" in unlabelled.title
    np.testing.assert_array_equal(unlabelled.envelope.a_lim_m, chart.envelope.a_lim_m)
    # errors begin with the label (the CLI's file path), or name the parameter
    with pytest.raises(ValueError, match=r"^bench/z\.h5: no FRF with direction x or y"):
        lobes_chart(frfs=frfs[2:], frf_label="bench/z.h5", **kw)
    with pytest.raises(ValueError, match=r"^frfs: the y FRF is zero at every frequency"):
        lobes_chart(frfs=[frfs[0], FRF(f, 0 * f + 0j, direction="y")], **kw)
    with pytest.raises(TypeError, match=r"robovib\.frf\.FRF"):
        lobes_chart(frfs=[f], **kw)
    with pytest.raises(TypeError, match="MeasuredCuts"):
        lobes_chart(modes_x=[MX], cuts="cuts.csv", **kw)
