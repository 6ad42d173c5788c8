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
from robovib.gp.contract import PosePredictionSide
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
    import control

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
    # Outside the designed path the gains were never checked: an error, unless asked to hold.
    with pytest.raises(ValueError, match=r"outside the designed range \[0, 1.2\] m"):
        sched.gains_at(1.3)
    with pytest.raises(ValueError, match="finite"):
        sched.gains_at(float("nan"))
    assert sched.gains_at(1.3, outside="hold") == pytest.approx((sched.w1[-1], sched.w2[-1]))
    assert sched.gains_at(-0.1, "poly", outside="hold") == pytest.approx(
        sched.gains_at(0.0, "poly")
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


@pytest.fixture(scope="module")
def path_model():
    from robovib.sim import VirtualRobot, path_modal_model

    robot = VirtualRobot()
    return robot, path_modal_model(robot, n_points=8, n_hits=2)


def test_offset_mass_study_short_path(path_model):
    from robovib.studies.control import offset_mass_study

    robot, model = path_model
    rows = offset_mass_study(
        robot, model, speeds_rpm=(480.0,), s_start=1.235, s_end=1.085, window_s=0.5,
        controllers=("robust", "feedforward"),
    )  # fmt: skip
    by = {r["controller"]: r for r in rows}
    assert all(r["unstable"] is None for r in rows)
    # Feedforward of the (periodic, measured) unbalance force removes most of the vibration.
    assert by["feedforward"]["start_mm"] < 0.3 * by["no-feedback"]["start_mm"]
    assert by["robust"]["start_mm"] < 1.05 * by["no-feedback"]["start_mm"]


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
    import warnings

    import control

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


def test_kalman_design_matches_python_control_dlqe():
    import control

    from robovib.control.controllers import design_kalman
    from robovib.control.lqr import continuous_model, discretize

    ours = design_kalman(MODE, 1e-3, force_std_n=20.0)
    a, bu = continuous_model(MODE)
    _, bf = continuous_model(MODE, input="force")
    phi, _ = discretize(a, bu, 1e-3)
    _, gf = discretize(a, bf, 1e-3)
    rn = 2e-6**2 + 1e-5**2 / 12
    gain, p, _ = control.dlqe(
        phi, gf, np.array([[1.0, 0.0]]), np.array([[20.0**2]]), np.array([[rn]])
    )
    # python-control's dlqe returns the predictor gain A P C' (C P C' + R)^-1.
    np.testing.assert_allclose(ours.p, p, rtol=1e-6)
    np.testing.assert_allclose(phi @ ours.gain, np.asarray(gain)[:, 0], rtol=1e-6)


def test_implemented_loop_matrix_matches_delay_analysis_and_time_domain():
    from robovib.control.controllers import implemented_loop_matrix, spectral_radius
    from robovib.control.lqr import closed_loop_with_delay

    design = design_lqr(MODE, r=[[1.0]])
    for d in (0, 3, 8):
        ref = np.abs(np.linalg.eigvals(closed_loop_with_delay(design, d))).max()
        ours = spectral_radius(
            implemented_loop_matrix(MODE, design.gains, delay_steps=d, velocity="exact")
        )
        assert ours == pytest.approx(ref, rel=1e-10)
    # Backward-difference velocity, 8 periods late, on a two-mode plant: the matrix's decay
    # rate is the time-domain one (free response of the simulated loop).
    from robovib.modal import ModalParameters
    from robovib.sim import ConstantModesRobot, LinearMove, ModeSet, run_closed_loop

    modes = [
        MODE,
        ModalParameters(2.6 * MODE.natural_frequency_hz, 10 * MODE.stiffness_n_per_m, 0.05),
    ]
    gains = (0.02, 0.0015)
    rho = spectral_radius(implemented_loop_matrix(modes, gains, 0.004, 8))
    robot = ConstantModesRobot({"x": ModeSet(*(np.array([[getattr(m, a) for m in modes]]) for a in
                                              ("natural_frequency_hz", "stiffness_n_per_m", "damping_ratio")))})  # fmt: skip
    force = np.zeros((6000, 3))
    force[:20, 0] = 2000.0
    from robovib.control.controllers import StateFeedback

    rec = run_closed_loop(robot, LinearMove("path", (0.0,), (0.1,)), force, 1000.0,
                          StateFeedback({0: gains}), tracker_noise_m=0.0, tracker_resolution_m=0.0,
                          force_noise_n=0.0)  # fmt: skip
    x = np.abs(rec.true_displacement_m[:, 0])
    env = [x[i : i + 400].max() for i in (2000, 5000)]
    assert (env[1] / env[0]) ** (1 / 750) == pytest.approx(
        rho, abs=3e-3
    )  # 3000 samples = 750 periods


def test_force_feedforward_cancels_a_periodic_force_and_checks_its_horizon():
    from robovib.control.controllers import ForceFeedforward
    from robovib.sim import ConstantModesRobot, LinearMove, ModeSet, run_closed_loop

    robot = ConstantModesRobot(
        {"x": ModeSet(np.array([[8.0]]), np.array([[1e6]]), np.array([[0.15]]))}
    )
    t = np.arange(4000) / 1000.0
    force = np.zeros((4000, 3))
    force[:, 0] = 300 * np.sin(2 * np.pi * 5 * t) + 100 * np.sin(2 * np.pi * 15 * t + 1)
    move = LinearMove("path", (0.0,), (0.1,))
    open_ = run_closed_loop(robot, move, force, 1000.0, None, rng=0)
    ff = run_closed_loop(robot, move, force, 1000.0, ForceFeedforward({0: 1e6}, 0.2, 0.032), rng=0)
    tail = slice(2000, None)
    ratio = ff.true_displacement_m[tail, 0].std() / open_.true_displacement_m[tail, 0].std()
    assert ratio < 0.15  # residual: the 4 ms hold of a 15 Hz harmonic and 0.5 N sensor noise
    with pytest.raises(ValueError, match="cannot be predicted"):
        run_closed_loop(robot, move, force, 1000.0, ForceFeedforward({0: 1e6}, 0.02, 0.032))
    with pytest.raises(ValueError, match="excitation_period_s"):
        ForceFeedforward({0: 1e6}, -1.0)


def test_thesis_gains_sensitivity_bound_and_fixed_pose_run():
    """§4.3.2: what any non-amplifying channel allows the thesis' gains, and the pure delay."""
    from robovib.control.channel import sensitivity_bound
    from robovib.studies.control import fixed_pose_offset_mass

    bound = sensitivity_bound([8.0, 16.0])
    rows = fixed_pose_offset_mass(speeds_rpm=(480.0, 960.0), duration_s=1.5, settle_s=0.8)
    for row, b in zip(rows, bound, strict=True):
        assert row["ratio"] >= b - 0.02  # the simulated 32 ms loop respects the bound
    # Open loop: m L w^2 through the measured mode, peak to peak.
    r = 480.0 / 60 / 8.5
    amp = 0.0508 * (2 * np.pi * 8.0) ** 2 / 0.775e6 / np.hypot(1 - r**2, 2 * 0.179 * r)
    assert rows[0]["open_ptp_mm"] == pytest.approx(2e3 * amp, rel=0.02)


def test_operating_mode_recovers_a_mode_from_simulated_open_loop_amplitudes():
    """Open-loop offset-mass runs of a known mode on the virtual robot give that mode back."""
    from robovib.control.channel import operating_mode
    from robovib.studies.control import fixed_pose_offset_mass

    truth = ModalParameters(8.5, 1.3e6, 0.12)
    rows = fixed_pose_offset_mass(speeds_rpm=(480.0, 960.0, 1440.0), mode=truth,
                                  duration_s=3.0, settle_s=2.0)  # fmt: skip
    fitted = operating_mode({r["speed_rpm"]: r["open_ptp_mm"] for r in rows})
    assert fitted.stiffness_n_per_m == pytest.approx(truth.stiffness_n_per_m, rel=0.02)
    assert fitted.damping_ratio == pytest.approx(truth.damping_ratio, rel=0.03)
    with pytest.raises(ValueError, match="two or more speeds"):
        operating_mode({480.0: 0.93})
    with pytest.raises(ValueError, match="finite and > 0"):
        operating_mode({480.0: 0.93, 960.0: float("nan")})
    with pytest.raises(ValueError, match="mass_kg"):
        operating_mode({480.0: 0.93, 960.0: 0.36}, mass_kg=-1.0)
    with pytest.raises(ValueError, match="cannot separate"):  # r1 r2 = 1 at 8.5 Hz
        operating_mode({255.0: 0.5, 1020.0: 0.2})


def test_required_channel_gain_ties_to_the_simulated_sensitivity():
    """The gain a channel needs is 1 exactly at the non-amplifying floor, whose loop
    (P, C) the time-domain simulator confirms (``test_simulated_closed_loop_ratio_...``), and
    0 for no reduction; §4.3.2's ratios need more than unit gain at 8 and 16 Hz."""
    from robovib.control.channel import required_channel_gain, sensitivity_bound

    f = [8.0, 16.0, 24.0]
    floor = sensitivity_bound(f)
    np.testing.assert_allclose(required_channel_gain(f, floor), 1.0, rtol=1e-12)
    np.testing.assert_allclose(required_channel_gain(f, [1.0, 1.0, 1.0]), 0.0, atol=1e-15)
    thesis = np.array([0.39 / 0.93, 0.15 / 0.36])
    assert np.all(thesis < floor[:2])  # below what a non-amplifying channel allows
    assert np.all(required_channel_gain([8.0, 16.0], thesis) > 1.0)
    for bad in ([1.5], [0.0], [float("nan")]):
        with pytest.raises(ValueError, match="target ratios"):
            required_channel_gain([8.0], bad)


@pytest.mark.parametrize(
    "channel_kw",
    [
        {},
        {"delay_s": 0.016, "servo_hz": 16.5, "servo_damping": 0.3},
        {"delay_s": 0.008, "lag_s": 0.01},
    ],
)
def test_simulated_closed_loop_ratio_matches_the_loop_frequency_response(channel_kw):
    """Steady-state closed/open ratio of the sampled loop vs 1 / |1 + P G_a C| (frequency domain)."""
    from robovib.control.channel import sensitivity_bound
    from robovib.sim import CommandChannel
    from robovib.studies.control import fixed_pose_offset_mass

    ch = CommandChannel(**channel_kw)
    rows = fixed_pose_offset_mass(ch, duration_s=5.0, settle_s=3.5)
    expected = sensitivity_bound([8.0, 16.0, 24.0], channel=ch)
    np.testing.assert_allclose([r["ratio"] for r in rows], expected, rtol=0.04)


def test_short_milling_study_and_plots(path_model):
    """One short Table 10 cut: the force feedforward with robust feedback, and the figures."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from robovib.control.band_stability import stability_over_band
    from robovib.control.design import build_controllers
    from robovib.sim import POSITION_2_S_M
    from robovib.studies.control import TABLE_10_CONDITIONS, milling_study, plot_milling

    robot, model = path_model
    rows = milling_study(robot, model, TABLE_10_CONDITIONS[4:5], (("Position 2", POSITION_2_S_M),),
                         controllers=("feedforward+robust",), cut_length_m=0.008)  # fmt: skip
    (row,) = rows
    assert row["unstable"] is None
    assert row["x_reduction_pct"] > 40 and row["z_reduction_pct"] > 40
    fig = plot_milling(rows, "z")
    ax = fig.axes[0]
    assert "[mm]" in ax.get_ylabel() and ax.get_xlabel()
    plt.close(fig)
    import json

    from robovib.studies.control import ControlSimulation, simulate_control

    doc = json.loads(json.dumps(ControlSimulation("milling", tuple(rows), {"seed": 0}).to_dict()))
    assert doc["rows"][0]["controller"] == "feedforward+robust" and "x_rms_mm" in doc["units"]
    with pytest.raises(ValueError, match="unknown actuator"):
        simulate_control("milling", actuator="magic")
    with pytest.raises(ValueError, match="unknown controllers"):
        simulate_control("milling", ["pid"])
    with pytest.raises(ValueError, match="unknown experiment"):
        simulate_control("drilling")
    grid = np.linspace(POSITION_2_S_M - 0.004, POSITION_2_S_M + 0.004, 3)
    ctrls = build_controllers(model, {0: "x"}, grid, names=("robust",))
    assert stability_over_band(model, ctrls, {0: "x"}, grid, second_modes=True)["robust"] < 1


def test_repetitive_loop_radius_matches_the_phasor_iteration():
    from robovib.control.controllers import repetitive_loop_radius

    g, m, L = 0.01, 8, 30
    for r in (1.0, 0.8 * np.exp(1j * 1.0), 1.2 * np.exp(-1j * 1.4)):
        u = np.zeros(3000, complex)
        u[: m + L] = 1.0
        for n in range(m + L - 1, 2999):
            u[n + 1] = u[n] - g * r * u[n - m - L + 1 : n - m + 1].mean()
        decay = (abs(u[2999]) / abs(u[1999])) ** (1 / 1000)
        assert repetitive_loop_radius(r, g, m, L) == pytest.approx(decay, rel=1e-9)


def test_repetitive_feedback_learns_a_periodic_disturbance_with_a_wrong_model():
    """Tracker-only feedback removes a tooth-periodic vibration despite the 32 ms delay."""
    from robovib.control.controllers import RepetitiveFeedback, ScheduledTable
    from robovib.modal import ModalParameters
    from robovib.sim import ConstantModesRobot, LinearMove, ModeSet, run_closed_loop

    robot = ConstantModesRobot(
        {"x": ModeSet(np.array([[8.0]]), np.array([[1e6]]), np.array([[0.15]]))}
    )
    t = np.arange(6000) / 1000.0
    force = np.zeros((6000, 3))
    force[:, 0] = 300 * np.sin(2 * np.pi * 6 * t) + 100 * np.sin(2 * np.pi * 12 * t + 1)
    force[:, 0] += np.random.default_rng(1).normal(size=6000) * 30
    move = LinearMove("path", (0.0,), (0.1,))
    wrong = ModalParameters(8.8, 1e6, 0.12)  # 10 % off in fn, 20 % in damping
    ctrl = RepetitiveFeedback({0: ScheduledTable.constant([8.8, 0.12])}, 1 / 6.0, 0.032)
    assert ctrl.loop_radius([ModalParameters(8.0, 1e6, 0.15)], wrong) < 1
    open_ = run_closed_loop(robot, move, force, 1000.0, None, rng=0)
    rec = run_closed_loop(robot, move, force, 1000.0, ctrl, rng=0)
    tail = slice(4000, None)
    ratio = rec.true_displacement_m[tail, 0].std() / open_.true_displacement_m[tail, 0].std()
    assert ratio < 0.3


def test_lqg_loop_matrix_matches_the_simulated_loop():
    """The period map of the Kalman-filter loop grows at the rate the simulated loop grows."""
    from robovib.control.controllers import (
        DelayAwareFeedback,
        ScheduledTable,
        design_kalman,
        lqg_loop_matrix,
        spectral_radius,
    )
    from robovib.control.lqr import design_delay_aware_lqr
    from robovib.modal import ModalParameters
    from robovib.sim import ConstantModesRobot, LinearMove, ModeSet, run_closed_loop

    nominal = ModalParameters(9.5, 1.2e6, 0.15)
    plant = [nominal, ModalParameters(24.7, 12e6, 0.05)]  # an unmodelled second mode
    gains = design_delay_aware_lqr(nominal, r=[[0.1]]).gains
    kf = design_kalman(nominal)
    rho = spectral_radius(lqg_loop_matrix(plant, gains, kf))
    robot = ConstantModesRobot({"x": ModeSet(*(np.array([[getattr(m, a) for m in plant]]) for a in
                                              ("natural_frequency_hz", "stiffness_n_per_m", "damping_ratio")))})  # fmt: skip
    force = np.zeros((6000, 3))
    force[:20, 0] = 2000.0
    ctrl = DelayAwareFeedback({0: ScheduledTable.constant(gains)}, {0: (np.array([0.0]), [kf])}, 32)
    rec = run_closed_loop(robot, LinearMove("path", (0.0,), (0.1,)), force, 1000.0, ctrl,
                          tracker_noise_m=0.0, tracker_resolution_m=0.0, force_noise_n=0.0,
                          max_command_m=1e9)  # fmt: skip
    x = np.abs(rec.true_displacement_m[:, 0])
    env = [x[i : i + 400].max() for i in (2000, 5000)]
    assert rho > 1  # this plant destabilises the nominal LQG ...
    assert (env[1] / env[0]) ** (1 / 750) == pytest.approx(rho, abs=1e-3)  # ... as simulated


def test_state_feedback_sensitivity_matches_simulation_and_tuning_is_stable():
    from robovib.control.controllers import (
        StateFeedback,
        design_tuned_state_feedback,
        implemented_loop_matrix,
        spectral_radius,
        state_feedback_sensitivity,
    )
    from robovib.modal import ModalParameters
    from robovib.sim import ConstantModesRobot, LinearMove, ModeSet, run_closed_loop

    mode = ModalParameters(8.0, 1e6, 0.15)
    robot = ConstantModesRobot(
        {"x": ModeSet(np.array([[8.0]]), np.array([[1e6]]), np.array([[0.15]]))}
    )
    gains, sens, rho = design_tuned_state_feedback([[mode]], mode, 8.0, n_grid=15)
    assert rho < 1 and sens < 0.8
    assert spectral_radius(implemented_loop_matrix(mode, gains)) == pytest.approx(rho)
    t = np.arange(5000) / 1000.0
    force = np.zeros((5000, 3))
    force[:, 0] = 200 * np.sin(2 * np.pi * 8.0 * t)
    move = LinearMove("path", (0.0,), (0.1,))
    kw = {"tracker_noise_m": 0.0, "tracker_resolution_m": 0.0, "rng": 0}
    open_ = run_closed_loop(robot, move, force, 1000.0, None, **kw).true_displacement_m[3000:, 0]
    closed = run_closed_loop(robot, move, force, 1000.0, StateFeedback({0: gains}), **kw)
    ratio = np.ptp(closed.true_displacement_m[3000:, 0]) / np.ptp(open_)
    assert ratio == pytest.approx(state_feedback_sensitivity(mode, gains, 8.0), rel=0.05)


def test_plot_offset_mass_envelopes():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from robovib.studies.control import plot_offset_mass

    t = np.arange(2000) / 1000.0
    rows = [{"speed_rpm": 480.0, "controller": c, "trace_x_m": a * 1e-4 * np.sin(2 * np.pi * 8 * t)}
            for c, a in (("no-feedback", 3.0), ("feedforward", 0.3))]  # fmt: skip
    fig = plot_offset_mass(rows)
    ax = fig.axes[0]
    assert "[mm]" in ax.get_ylabel() and "[s]" in ax.get_xlabel()
    peak = max(line.get_ydata().max() for line in ax.get_lines())
    assert peak == pytest.approx(0.3, rel=0.01)  # envelope of the 0.3 mm sine
    plt.close(fig)
    with pytest.raises(ValueError, match="keep_traces"):
        plot_offset_mass([{"speed_rpm": 480.0, "controller": "x"}])


def test_cli_control_simulate_offset_mass_feedforward(tmp_path):
    import json

    from typer.testing import CliRunner

    from robovib.cli import app

    png = tmp_path / "om.png"
    res = CliRunner().invoke(app, ["control", "simulate", "offset-mass", "--controller", "feedforward",
                                   "--json", "--plot", str(png)])  # fmt: skip
    assert res.exit_code == 0, res.output
    doc = json.loads(res.output)
    by = {(r["speed_rpm"], r["controller"]): r for r in doc["rows"]}
    assert set(by) == {(480.0, "no-feedback"), (480.0, "feedforward"), (960.0, "no-feedback"), (960.0, "feedforward")}  # fmt: skip
    assert by[(480.0, "feedforward")]["start_mm"] < 0.3 * by[(480.0, "no-feedback")]["start_mm"]
    assert doc["result_settings"]["channel"]["delay_s"] == 0.032 and "start_mm" in doc["units"]
    assert png.stat().st_size > 0
    res = CliRunner().invoke(app, ["control", "simulate", "milling", "--actuator", "magic"])
    assert res.exit_code == 1 and "unknown actuator" in res.output


class _LineModel(PosePredictionSide):
    """A stand-in pose model: fn rises 2 Hz per 100 mm of y, extrapolating beyond y = 300 mm
    (its own ``modes``; the rest of the pose-model contract, e.g. ``mode_set``, inherited)."""

    input_names = ("x_mm", "y_mm", "rz_deg")
    directions_ = ("x", "y", "z")

    def modes(self, X):
        from robovib.gp import PoseMode

        out = []
        for _x_mm, y_mm, _rz in np.asarray(X, float):
            m = ModalParameters(12.0 + 0.02 * y_mm, 1.5e6, 0.12)
            pm = PoseMode(m, 0.1, 1e4, 10.0, bool(y_mm > 300.0), None)
            out.append(dict.fromkeys(self.directions_, pm))
        return out


def test_schedule_along_line_designs_at_the_model_modes_along_the_travel():
    from robovib.control.schedule import schedule_along_line

    res = schedule_along_line(_LineModel(), (2400.0, -200.0, 0.0), (2400.0, 400.0, 30.0), "x", 7)
    np.testing.assert_allclose(res.schedule.s_m, np.linspace(0.0, 0.6, 7))  # 600 mm of travel
    np.testing.assert_allclose(res.poses[:, 1], np.linspace(-200.0, 400.0, 7))
    np.testing.assert_allclose(res.poses[:, 2], np.linspace(0.0, 30.0, 7))
    assert res.extrapolating.tolist() == [False] * 6 + [True]
    modes = [ModalParameters(12.0 + 0.02 * y, 1.5e6, 0.12) for y in res.poses[:, 1]]
    direct = schedule_gains(np.linspace(0.0, 0.6, 7), modes)
    np.testing.assert_allclose(res.schedule.w1, direct.w1)
    np.testing.assert_allclose(res.schedule.w2, direct.w2)
    for bad, match in (
        (dict(start=(1.0, 2.0), end=(1.0, 2.0, 3.0)), "3 coordinates"),
        (dict(start=(1.0, 2.0, 3.0), end=(1.0, 2.0, 9.0)), "same position"),
        (dict(start=(1.0, np.nan, 3.0), end=(1.0, 2.0, 3.0)), "finite"),
        (dict(start=(1.0, 2.0, 3.0), end=(1.0, 9.0, 3.0), direction="w"), "unknown direction"),
        (dict(start=(1.0, 2.0, 3.0), end=(1.0, 9.0, 3.0), n_points=3), "n_points"),
    ):
        kw = {"direction": "x", **bad}
        with pytest.raises(ValueError, match=match):
            schedule_along_line(_LineModel(), **kw)


class _PathModel(_LineModel):
    """A path model: one input, the path coordinate s [m]."""

    input_names = ("s_m",)

    def modes(self, X):
        return super().modes(
            np.column_stack([np.zeros(len(X)), 100.0 * np.ravel(X), np.zeros(len(X))])
        )


def test_schedule_along_line_on_a_path_model_uses_its_path_coordinate():
    from robovib.control.schedule import schedule_along_line

    for a, b in ((0.335, 1.235), (1.235, 0.335)):  # either direction: increasing s_m
        res = schedule_along_line(_PathModel(), (a,), (b,), "x", 10)
        np.testing.assert_allclose(res.schedule.s_m, np.linspace(0.335, 1.235, 10))
        np.testing.assert_allclose(res.poses[:, 0], res.schedule.s_m)
        assert res.modes[0].natural_frequency_hz == pytest.approx(12.0 + 0.02 * 33.5)
    assert res.schedule.gains_at(1.0) is not None  # inside the designed path coordinates

    class NoPosition(_LineModel):
        input_names = ("a1_deg", "a2_deg")

    with pytest.raises(ValueError, match="no position"):
        schedule_along_line(NoPosition(), (0.0, 0.0), (1.0, 1.0), "x")


def test_the_study_composes_the_library_design_and_path_model():
    """Issue 23: controller design lives in ``robovib.control.design`` and the virtual EMA's path
    model in ``robovib.sim``; the closed-loop studies use them and hold no copy. Issue 41: the
    study package re-exports no library name (import those from the library)."""
    import robovib.control as control
    import robovib.sim as sim
    import robovib.studies.control as study
    from robovib.control import design
    from robovib.studies.control import offset_mass, simulate

    for name in ("CONTROLLERS", "DEFAULT_CONTROLLER", "build_controllers"):
        assert getattr(design, name) is getattr(control, name)
    assert simulate.CONTROLLERS is design.CONTROLLERS
    assert offset_mass.build_controllers is design.build_controllers
    assert simulate.path_modal_model is sim.path_modal_model
    library = set(control.__all__) | set(sim.__all__)
    assert not library & set(study.__all__), library & set(study.__all__)
    assert design.DEFAULT_CONTROLLER in design.CONTROLLERS
    with pytest.raises(ValueError, match="unknown controllers"):
        design.build_controllers(None, {}, [0.0, 1.0], names=("no-such-controller",))


def test_thesis_printed_schedule_is_eq_28_29_in_millimetres_from_the_start():
    """Thesis Eq. 28-29 (d in mm from the path start) evaluated with numpy.polyval."""
    from robovib.control.design import thesis_printed_gains

    s_start = 1.235
    s = np.array([s_start, s_start - 0.45, s_start - 0.9])
    d_mm = np.array([0.0, 450.0, 900.0])
    got = thesis_printed_gains(s, s_start)
    np.testing.assert_allclose(got[:, 0], np.polyval([-4.3e-5, 0.12], d_mm), rtol=1e-12)
    np.testing.assert_allclose(
        got[:, 1], np.polyval([-3e-14, 7e-11, -6e-8, 1e-5, 0.006], d_mm), rtol=1e-9
    )
    assert got[2, 0] == pytest.approx(0.0813)  # 0.12 - 4.3e-5 * 900
