"""Every figure behind a ``--plot`` option: axis labels carry units, FRF views show the data.

The library plot functions are called directly with small inputs (no CLI, no long studies).
"""

from __future__ import annotations

import re

import matplotlib
import numpy as np
import pytest

matplotlib.use("Agg")
import matplotlib.pyplot as plt

from robovib.frf import FRF, FRFCurve, plot_frf, unwrapped_phase_deg
from robovib.modal import ModalParameters

UNIT = re.compile(r"\[[^\]]+\]")


def assert_labelled(fig) -> None:
    """Every axes with data has a y label with a unit; its x axis (or a shared one) too."""
    checked = 0
    for ax in fig.axes:
        has_data = ax.lines or ax.collections or ax.images or ax.patches
        is_colorbar = hasattr(ax, "_colorbar")
        if not has_data and not is_colorbar:
            continue
        checked += 1
        assert UNIT.search(ax.get_ylabel()), f"y label without unit: {ax.get_ylabel()!r}"
        if is_colorbar:
            continue
        siblings = ax.get_shared_x_axes().get_siblings(ax)
        xlabels = [a.get_xlabel() for a in siblings] + [ax.get_xlabel()]
        assert any(UNIT.search(x) for x in xlabels), f"x label without unit: {xlabels!r}"
    assert checked > 0
    plt.close(fig)


@pytest.fixture
def sdof():
    """SDOF compliance (closed form) with coherence: fn 20 Hz, k 2 MN/m, zeta 5 %."""
    f = np.linspace(2, 60, 300)
    mode = ModalParameters(20.0, 2e6, 0.05)
    return mode, FRF(f, mode.compliance(f), coherence=np.full(f.size, 0.95))


def test_unwrapped_phase_has_no_jumps_and_matches_closed_form():
    f = np.linspace(1, 200, 2000)
    mode = ModalParameters(20.0, 2e6, 0.03)
    # SDOF: phase = -atan2(2 zeta r, 1 - r^2) in (-180, 0]
    r = f / 20.0
    ref = -np.degrees(np.arctan2(2 * 0.03 * r, 1 - r**2))
    np.testing.assert_allclose(unwrapped_phase_deg(mode.compliance(f)), ref, atol=1e-9)
    # with a 10 ms delay the phase falls by 360 f tau: wrapped it jumps, unwrapped it does not
    tau = 0.01
    h = mode.compliance(f) * np.exp(-2j * np.pi * f * tau)
    assert np.max(np.abs(np.diff(np.degrees(np.angle(h))))) > 300
    phase = unwrapped_phase_deg(h)
    assert np.max(np.abs(np.diff(phase))) < 30
    np.testing.assert_allclose(phase, ref - 360 * f * tau, atol=1e-6)


@pytest.mark.parametrize("view", ["bode", "real-imag", "both"])
def test_plot_frf_views(sdof, view):
    _, frf = sdof
    fig = plot_frf(frf, view=view, overlays=[FRFCurve("fit", frf.frequency_hz, frf.values)])
    n_panels = {"bode": 2, "real-imag": 2, "both": 4}[view] + 1  # + coherence
    assert len(fig.axes) == n_panels
    labels = [a.get_ylabel() for a in fig.axes]
    if view in ("real-imag", "both"):
        re_ax = fig.axes[labels.index("Re H [µm/N]")]
        np.testing.assert_allclose(re_ax.lines[0].get_ydata(), 1e6 * frf.values.real)
        im_ax = fig.axes[labels.index("Im H [µm/N]")]
        np.testing.assert_allclose(im_ax.lines[0].get_ydata(), 1e6 * frf.values.imag)
    if view in ("bode", "both"):
        mag = fig.axes[labels.index("|H| [µm/N]")]
        np.testing.assert_allclose(mag.lines[0].get_ydata(), 1e6 * np.abs(frf.values))
    assert_labelled(fig)


def test_plot_frf_rejects_bad_input(sdof):
    _, frf = sdof
    with pytest.raises(ValueError, match="view"):
        plot_frf(frf, view="nyquist")
    with pytest.raises(ValueError, match="axes"):
        _, ax = plt.subplots()
        plot_frf(frf, ax, view="both")
    plt.close("all")


def test_plot_frf_marks_flagged_bins(sdof):
    _, frf = sdof
    from dataclasses import replace

    flagged = np.zeros(frf.frequency_hz.size, bool)
    flagged[::50] = True
    fig = plot_frf(replace(frf, meta={"flagged": flagged}), view="bode")
    marks = [ln for ln in fig.axes[0].lines if ln.get_label() == "flagged bins"]
    assert len(marks) == 1 and len(marks[0].get_xdata()) == flagged.sum()
    assert_labelled(fig)


def test_modal_fit_figure_flags_poor_fit(sdof):
    from robovib.modal.plot import plot_frf_fit

    mode, frf = sdof
    wrong = ModalParameters(30.0, 2e6, 0.05)
    fig = plot_frf_fit(frf, [wrong], flags=("relative RMS error 80 % > 10 %",), title="t")
    assert "FLAGGED" in fig.axes[0].get_title()
    assert any("relative RMS error" in t.get_text() for t in fig.texts)
    assert_labelled(fig)
    fig = plot_frf_fit(frf, [mode], title="t")
    assert "FLAGGED" not in fig.axes[0].get_title() and not fig.texts
    assert_labelled(fig)


def test_hybrid_prediction_figure(sdof):
    from robovib.hybrid import FRFPrediction, plot_frf_prediction

    _, frf = sdof
    f, h = frf.frequency_hz, frf.values
    pred = FRFPrediction(0.5, f, h, 0.1 * np.abs(h), True, measured_m_per_n=1.1 * h)
    fig = plot_frf_prediction(pred)
    assert "EXTRAPOLATION" in fig.axes[0].get_title()
    assert_labelled(fig)


def test_lobes_and_map_figures():
    from robovib.gp import get_chapter3_model
    from robovib.milling import ALUMINIUM_7075, CuttingConditions, MillingTool
    from robovib.milling.chart import lobes_chart, plot_lobes_chart
    from robovib.milling.maps import plot_lobe_map, workspace_lobe_map
    from robovib.milling.stability import stability_lobes

    m = ModalParameters(20.0, 2e6, 0.05)
    cond = CuttingConditions(1000, 1e-4, 1e-3, 6e-3)
    lobes = stability_lobes([m], [m], MillingTool(), cond, ALUMINIUM_7075, n_lobes=5)
    assert_labelled(lobes.plot().figure)
    chart = lobes_chart(tool=MillingTool(), conditions=cond, coefficients=ALUMINIUM_7075,
                        spindle_rpm=np.linspace(500, 3000, 40), method="zoa", modes_x=[m],
                        modes_y=[m])  # fmt: skip
    assert_labelled(plot_lobes_chart(chart))
    ds = workspace_lobe_map(get_chapter3_model(), [2100, 2700], [0, 300], [0.0], [1750.0],
                            MillingTool(), cond, ALUMINIUM_7075, method="zoa", scheduler="sync")  # fmt: skip
    assert_labelled(plot_lobe_map(ds))


def test_robot_compare_figure():
    from robovib.studies.analytical import compare_with_table_a1, plot_comparison

    assert_labelled(plot_comparison(compare_with_table_a1()))


def test_control_figures():
    from robovib.control.schedule import schedule_gains
    from robovib.studies.control import plot_offset_mass

    s = np.linspace(0.335, 1.235, 6)
    sched = schedule_gains(s, [ModalParameters(f, 2e6, 0.05) for f in 14 + 4 * s])
    assert_labelled(sched.plot())
    t = np.arange(500) / 1000.0
    rows = [{"speed_rpm": 480.0, "controller": c, "trace_x_m": a * 1e-4 * np.sin(50 * t)}
            for c, a in (("none", 1.0), ("LQR", 0.5))]  # fmt: skip
    assert_labelled(plot_offset_mass(rows))


def test_next_poses_figure():
    from robovib.campaign import NextPoses, plot_next_poses

    cand = np.linspace(0, 1.235, 50)[:, None]
    var = ((cand * (1.235 - cand)) ** 2)[:, 0]
    tested = np.array([[0.0], [1.235]])
    res = NextPoses(cand[[24]], np.array([24]), np.array([1.0]), var.sum(), cand, var, tested,
                    ("s_m",))  # fmt: skip
    assert_labelled(plot_next_poses(res))  # one input: variance along the path
    pose = np.column_stack([cand[:, 0], cand[::-1, 0]])
    res = NextPoses(pose[[24]], np.array([24]), np.array([1.0]), var.sum(), pose, var,
                    pose[[0, -1]], ("x_m", "y_m"))  # fmt: skip
    assert_labelled(plot_next_poses(res))  # two inputs: candidates coloured by the variance


def test_stabilization_diagram_figure(sdof):
    from robovib.modal.lscf import stabilization_diagram

    _, frf = sdof
    diagram = stabilization_diagram(frf.frequency_hz, frf.values, max_order=8)
    assert_labelled(diagram.plot(frf=frf).figure)


def test_lobes_legend_sits_outside_the_data_and_the_best_speed_is_in_view():
    """Issue 22: the legend covered the low-speed lobes; the most-stable marker sat off the top."""
    import matplotlib

    matplotlib.use("Agg")
    from robovib.milling.lobes import LobeEnvelope, plot_lobes

    rpm = np.linspace(100, 3000, 300)
    a = 1e-3 * (1.0 + 4.0 * np.exp(-(((rpm - 2200) / 60) ** 2)))  # a tall lobe: best speed 2200
    env = LobeEnvelope(rpm, a, np.full(rpm.size, 20.0), np.array(["hopf"] * rpm.size), "sdm")
    fig = plot_lobes(env)
    ax = fig.axes[0]
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    legend = ax.get_legend().get_window_extent(renderer)
    axes_box = ax.get_window_extent(renderer)
    assert legend.x0 >= axes_box.x1 - 1  # entirely right of the plotting area
    _, best_depth = env.most_stable_speed()
    assert best_depth * 1e3 < ax.get_ylim()[1]
