"""LQR design against SciPy and python-control, delay analysis against time-domain simulation."""

import numpy as np
import pytest
from scipy import signal

from robovib.control import (
    THESIS_Q,
    THESIS_R,
    closed_loop_with_delay,
    continuous_model,
    delay_analysis,
    design_delay_aware_lqr,
    design_lqr,
    discretize,
)
from robovib.control.schedule import schedule_gains
from robovib.modal import ModalParameters
from robovib.studies.table9 import table_9_comparison

MODE = ModalParameters(8.5, 0.775e6, 0.179)  # §4.3.2 offset-mass pose, Y direction


@pytest.mark.parametrize("inp", ["displacement", "force"])
def test_discretisation_matches_scipy(inp):
    a, b = continuous_model(MODE, input=inp)
    ad, bd = discretize(a, b, 0.004)
    ref = signal.cont2discrete((a, b, np.eye(2), np.zeros((2, 1))), 0.004, method="zoh")
    np.testing.assert_allclose(ad, ref[0], rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(bd, ref[1], rtol=1e-10, atol=1e-14)


def test_riccati_solution_and_python_control():
    d = design_lqr(MODE)
    a, b, p, q, r = d.ad, d.bd, d.p, THESIS_Q, THESIS_R
    residual = a.T @ p @ a - (a.T @ p @ b) @ np.linalg.solve(r + b.T @ p @ b, b.T @ p @ a) + q - p
    assert np.max(np.abs(residual)) < 1e-9 * np.max(np.abs(p))  # Eq. 26
    control = pytest.importorskip("control")
    w_ref, _, _ = control.dlqr(a, b, q, r)
    np.testing.assert_allclose(d.gains, np.ravel(w_ref), rtol=1e-8)
    assert d.spectral_radius < 1  # without delay the loop is stable


def test_table_9_trends_with_displacement_input():
    rows = [
        r
        for r in table_9_comparison().rows
        if r["formulation"] == "physical" and r["input"] == "displacement"
    ]
    g = {(r["position"], r["direction"]): (r["w1"], r["w2"]) for r in rows}
    for d in ("x", "z"):
        assert g[(2, d)][0] > g[(1, d)][0]  # more compliant Position 2 needs larger w1
        assert g[(2, d)][1] > g[(1, d)][1]  # and larger w2
    for pos in (1, 2):
        assert g[(pos, "x")][0] > g[(pos, "z")][0]  # X more compliant than Z


def _simulate_delayed(design, steps, n=3000):
    x = np.array([1e-3, 0.0])
    queue = [0.0] * steps
    peak = 0.0
    for _ in range(n):
        u = -design.gains @ x
        queue.append(u)
        x = design.ad @ x + design.bd[:, 0] * queue.pop(0)
        peak = max(peak, abs(x[0]))
    return abs(x[0]), peak


def test_delay_analysis_agrees_with_time_domain_simulation():
    aggressive = design_lqr(MODE)  # thesis weights: too aggressive for 32 ms
    gentle = design_lqr(MODE, r=[[100.0]])
    a, g = delay_analysis(aggressive, 0.032), delay_analysis(gentle, 0.032)
    assert not a.stable and g.stable
    final_a, _ = _simulate_delayed(aggressive, a.delay_steps)
    final_g, _ = _simulate_delayed(gentle, g.delay_steps)
    assert final_a > 1e-3  # diverges
    assert final_g < 1e-5  # decays
    assert np.max(np.abs(np.linalg.eigvals(closed_loop_with_delay(gentle, 0)))) == pytest.approx(
        gentle.spectral_radius
    )


def test_delay_aware_design_is_stable_and_better_damped():
    aware = design_delay_aware_lqr(MODE, r=[[1.0]])
    open_loop = np.max(np.abs(np.linalg.eigvals(design_lqr(MODE).ad)))
    assert aware.delay_steps == 8
    assert aware.spectral_radius < open_loop < 1


def test_schedule_interpolates_designed_points():
    s = np.linspace(0, 1.2, 8)
    modes = [ModalParameters(10.4 - 3 * si, (1.45 - 0.6 * si) * 1e6, 0.15) for si in s]
    sched = schedule_gains(s, modes, r=100.0)
    for si, w1, w2 in zip(s, sched.w1, sched.w2, strict=True):
        assert sched.gains_at(si) == pytest.approx((w1, w2))
    assert sched.gains_at(0.6, "poly")[0] == pytest.approx(
        np.interp(0.6, s, sched.w1), rel=0.05, abs=1e-3
    )


def test_bad_input():
    with pytest.raises(ValueError, match="positive"):
        ModalParameters(8.5, -1.0, 0.1)
    with pytest.raises(ValueError, match="positive semi-definite"):
        design_lqr(MODE, q=np.diag([1.0, -1.0]))
    with pytest.raises(ValueError, match="R must be positive"):
        design_lqr(MODE, r=[[0.0]])
    with pytest.raises(ValueError, match="period must be positive"):
        design_lqr(MODE, period_s=0.0)
    with pytest.raises(ValueError, match="not a multiple"):
        delay_analysis(design_lqr(MODE), 0.030)
    assert delay_analysis(design_lqr(MODE), 0.030, rounding="round").delay_steps == 8


def test_offset_mass_study_short_path():
    from robovib.control.studies import offset_mass_study, path_modal_model
    from robovib.sim import VirtualRobot

    robot = VirtualRobot()
    model = path_modal_model(robot, directions=("x",), n_points=8, n_hits=2)
    rows = offset_mass_study(robot, model, speeds_rpm=(480.0,), s_start=1.235, s_end=0.935)
    by = {r["controller"]: r for r in rows}
    assert by["delay_aware"]["unstable"] is None
    assert by["delay_aware"]["start_mm"] < 0.8 * by["no_feedback"]["start_mm"]


def test_schedule_cli_from_a_path_file(tmp_path):
    import json

    from typer.testing import CliRunner

    from robovib.cli import app

    s = np.linspace(0.0, 0.9, 8)
    lines = ["s_m,fn_hz,stiffness_n_per_m,damping_ratio"] + [
        f"{si},{10 - 3 * si},{(1.4 - 0.6 * si) * 1e6},0.15" for si in s
    ]
    csv = tmp_path / "path.csv"
    csv.write_text("\n".join(lines))
    res = CliRunner().invoke(app, ["control", "schedule", "--path-file", str(csv), "--json"])
    assert res.exit_code == 0, res.output
    doc = json.loads(res.output)
    assert len(doc["w1"]) == 8 and all(doc["stable_with_delay"])
    bad = tmp_path / "bad.csv"
    bad.write_text("s_m,fn_hz\n0,10\n")
    res = CliRunner().invoke(app, ["control", "schedule", "--path-file", str(bad)])
    assert res.exit_code == 1 and "missing columns" in res.output


@pytest.mark.parametrize(("r", "delay"), [(100.0, 8), (1.0, 0), (1.0, 8)])
def test_loop_margins_match_python_control(r, delay):
    control = pytest.importorskip("control")
    import warnings

    from robovib.control import loop_margins

    design = design_lqr(MODE, r=[[r]])
    ours = loop_margins(design, delay)
    sys = control.ss(design.ad, design.bd, design.gains[None, :], 0, design.period_s)
    if delay:
        sys = sys * control.tf([1], [1] + [0] * delay, design.period_s)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        gm, pm, _, wp, wc, _ = control.stability_margins(sys, returnall=True)
    np.testing.assert_allclose(ours.gain_margins, gm, rtol=1e-4)
    np.testing.assert_allclose(ours.phase_margins_deg, pm, atol=0.05)
    np.testing.assert_allclose(ours.gain_crossovers_hz, np.asarray(wc) / (2 * np.pi), rtol=1e-3)
    np.testing.assert_allclose(ours.phase_crossovers_hz, np.asarray(wp) / (2 * np.pi), rtol=1e-3)
