"""Issue 25: period estimation, tracking controllers, the fade guard and the cut disturbances.

References are independent: synthetic signals of known period, white noise, the closed-form
steady-state response of a single mode, and exact relations of the simulator's channel.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from typer.testing import CliRunner

from robovib.control.adaptive import PeriodTracker, TrackingRepetitive, estimate_period
from robovib.control.controllers import RepetitiveFeedback, ScheduledTable
from robovib.control.guard import FadeGuard
from robovib.milling.forces import ACETAL, CuttingConditions, MillingTool
from robovib.modal.parameters import ModalParameters
from robovib.sim import (
    REALISTIC_LEVELS,
    CommandChannel,
    ConstantModesRobot,
    CutDisturbances,
    LinearMove,
    ModeSet,
    run_closed_loop,
)

FS = 1000.0


def _periodic(t, period):
    ph = 2 * np.pi * t / period
    return np.sin(ph) + 0.5 * np.sin(2 * ph + 0.3) + 0.2 * np.sin(3 * ph + 1.0)


def test_period_estimate_of_a_known_period_is_sub_sample():
    rng = np.random.default_rng(1)
    true = 0.11537  # not a whole number of samples
    t = np.arange(2000) / FS
    x = _periodic(t, true) + 0.1 * rng.normal(size=t.size)
    p, r = estimate_period(x, FS, nominal_s=0.12, rel_range=0.1)
    assert abs(p - true) < 0.3e-3  # better than a third of a sample
    assert r > 0.9


def test_period_estimate_of_white_noise_reports_no_periodicity():
    x = np.random.default_rng(2).normal(size=(3000, 3))
    _, r = estimate_period(x, FS, nominal_s=0.1)
    assert r < 0.3


def test_period_estimate_rejects_short_records():
    with pytest.raises(ValueError, match="samples"):
        estimate_period(np.zeros(50), FS, nominal_s=0.1)


def test_period_tracker_follows_a_spindle_off_its_nominal_speed():
    nominal, true = 0.24, 0.24 / 1.04  # 4 % fast
    t = np.arange(6000) / FS
    f = np.column_stack([_periodic(t, true), 0.5 * _periodic(t, true), np.zeros_like(t)])
    tr = PeriodTracker(nominal)
    tr.reset(t.size, FS)
    for k in range(t.size // 4):
        tr.update(k, f[4 * k : 4 * k + 4])
    assert abs(tr.period_s - true) < 0.5e-3


def test_milling_force_with_a_speed_error_has_the_faster_tooth_period():
    tool, cond = MillingTool(), CuttingConditions(250.0, 0.3e-3, 3e-3, 6e-3)
    t = np.arange(3000) / FS
    f = CutDisturbances(speed_error_pct=5.0).cutting_force(t, tool, cond, ACETAL)
    nominal = 1 / cond.tooth_passing_hz(tool)
    p, _ = estimate_period(f, FS, nominal)
    assert p == pytest.approx(nominal / 1.05, abs=0.5e-3)


def test_runout_adds_the_once_per_revolution_component():
    tool, cond = MillingTool(), CuttingConditions(250.0, 0.3e-3, 3e-3, 6e-3)
    t = np.arange(4800) / FS  # 20 revolutions
    rev_hz = 250.0 / 60.0

    def once_per_rev(f):
        return abs(np.exp(-2j * np.pi * rev_hz * t) @ (f[:, 1] - f[:, 1].mean())) / t.size

    plain = CutDisturbances().cutting_force(t, tool, cond, ACETAL)
    run = CutDisturbances(runout_um=20.0).cutting_force(t, tool, cond, ACETAL)
    assert once_per_rev(plain) < 0.02 * np.std(plain[:, 1])
    assert once_per_rev(run) > 5 * once_per_rev(plain)


def test_disturbances_parse_and_scale():
    d = CutDisturbances.parse(["runout_um=12", "delay-error-ms=8"])
    assert d.active() == {"runout_um": 12.0, "delay_error_ms": 8.0}
    assert CutDisturbances.parse(["all=2"]) == REALISTIC_LEVELS.scaled(2.0)
    with pytest.raises(ValueError, match="unknown disturbance"):
        CutDisturbances.parse(["warp=1"])
    with pytest.raises(ValueError, match="not a number"):
        CutDisturbances.parse(["runout_um=a"])
    ch = CutDisturbances(actuator_gain_pct=-10, delay_error_ms=8).channel(CommandChannel())
    assert ch.gain == pytest.approx(0.9) and ch.delay_s == pytest.approx(0.040)


class _Constant:
    def __init__(self, u):
        self.u = np.asarray(u, float)

    def reset(self, coords, period_s, sample_rate_hz):
        pass

    def command(self, k, tracker_m, force_n):
        return self.u


def _robot(mode):
    fn, k, z = (
        np.array([[v]])
        for v in (mode.natural_frequency_hz, mode.stiffness_n_per_m, mode.damping_ratio)
    )
    return ConstantModesRobot({"x": ModeSet(fn, k, z)})


def test_channel_gain_scales_the_applied_correction_exactly():
    mode = ModalParameters(10.0, 1e6, 0.05)
    move = LinearMove("path", (0.5,), (0.5,))
    force = np.zeros((400, 3))
    rec = run_closed_loop(_robot(mode), move, force, FS, _Constant([1e-4, 0, 0]),
                          channel=CommandChannel(gain=1.2), rng=0)  # fmt: skip
    applied = rec.meta["commands_m"][:, 0]
    assert applied[:32] == pytest.approx(0.0)
    assert applied[32:] == pytest.approx(1.2e-4)


def test_force_bias_reaches_the_controller():
    seen = []

    class Spy(_Constant):
        def command(self, k, tracker_m, force_n):
            seen.append(force_n.copy())
            return self.u

    move = LinearMove("path", (0.5,), (0.5,))
    run_closed_loop(_robot(ModalParameters(10.0, 1e6, 0.05)), move, np.zeros((400, 3)), FS,
                    Spy([0, 0, 0]), force_noise_n=0.0, force_bias_n=5.0, rng=0)  # fmt: skip
    assert np.concatenate(seen) == pytest.approx(5.0)


def test_guard_fades_out_on_white_noise_and_logs_why():
    n_cmd = 500
    guard = FadeGuard(_Constant([1e-4, 0, 0]), PeriodTracker(0.1), {0: (10.0, 0.05)})
    guard.reset(np.full(n_cmd, 0.5), 0.004, FS)
    rng = np.random.default_rng(3)
    for k in range(n_cmd):
        guard.command(k, np.zeros((4, 3)), rng.normal(size=(4, 3)) * 50)
    assert guard.scale == 0.0
    assert guard.events and "not periodic" in guard.events[0].reason


def test_guard_keeps_a_harmless_correction_on_a_periodic_force():
    n_cmd = 500
    guard = FadeGuard(_Constant([0, 0, 0]), PeriodTracker(0.1), {0: (10.0, 0.05)})
    guard.reset(np.full(n_cmd, 0.5), 0.004, FS)
    t = np.arange(4 * n_cmd) / FS
    f = np.column_stack([_periodic(t, 0.1)] * 3) * 50
    y = np.column_stack([_periodic(t, 0.1)] * 3) * 1e-5
    for k in range(n_cmd):
        guard.command(k, y[4 * k : 4 * k + 4], f[4 * k : 4 * k + 4])
    assert guard.scale == 1.0 and not guard.events


def test_tracking_repetitive_cancels_an_off_nominal_periodic_force_on_a_known_mode():
    """A single mode driven by a force 4 % faster than nominal: the steady open-loop response
    is the closed-form |H| F; the tracking repetitive controller must remove >= 80 % of it and
    stay bounded, the nominal-period one much less."""
    mode = ModalParameters(10.0, 1e6, 0.05)
    nominal = 1 / 6.0  # 6 Hz nominal excitation
    true = nominal / 1.04
    n = 12000
    t = np.arange(n) / FS
    force = np.zeros((n, 3))
    force[:, 0] = 200 * np.sin(2 * np.pi * t / true)
    move = LinearMove("path", (0.5,), (0.5,))
    table = {0: ScheduledTable.constant([mode.natural_frequency_hz, mode.damping_ratio])}
    w = 2 * np.pi / true
    wn = mode.omega_n
    h = 1 / mode.stiffness_n_per_m / abs(1 - (w / wn) ** 2 + 2j * mode.damping_ratio * w / wn)
    open_rms = 200 * h / math.sqrt(2)  # closed form
    res = {}
    for name, ctrl in (
        ("tracking", TrackingRepetitive(table, PeriodTracker(nominal), n_harmonics=1)),
        ("nominal", RepetitiveFeedback(table, nominal, n_harmonics=1)),
    ):
        rec = run_closed_loop(_robot(mode), move, force, FS, ctrl, rng=0)
        res[name] = np.std(rec.true_displacement_m[n // 2 :, 0])
    assert res["tracking"] < 0.2 * open_rms
    assert res["tracking"] < 0.5 * res["nominal"]


def test_cli_rejects_unknown_disturbance_and_the_withdrawn_calibrated_channel():
    from robovib.cli import app

    r = CliRunner().invoke(app, ["control", "simulate", "milling", "--disturbance", "warp=1"])
    assert r.exit_code == 1 and "unknown disturbance" in r.output
    r = CliRunner().invoke(app, ["control", "simulate", "milling", "--actuator", "calibrated"])
    assert r.exit_code == 1 and "unknown actuator" in r.output


def test_adaptive_controller_survives_an_off_speed_cut_where_the_feedforward_degrades():
    """A short Table 10 cut with the spindle 4 % fast and 8 ms of unknown delay: the adaptive
    controller keeps most of its reduction; both controllers are compared on the same cut."""
    from robovib.sim import POSITION_2_S_M, VirtualRobot, path_modal_model
    from robovib.studies.control import TABLE_10_CONDITIONS, milling_study

    robot = VirtualRobot()
    model = path_modal_model(robot, n_points=8, n_hits=2)
    dist = CutDisturbances(speed_error_pct=4.0, delay_error_ms=8.0)
    rows = milling_study(robot, model, TABLE_10_CONDITIONS[4:5], (("Position 2", POSITION_2_S_M),),
                         controllers=("feedforward+robust", "adaptive"), cut_length_m=0.02,
                         disturbances=dist)  # fmt: skip
    by = {r["controller"]: r for r in rows}
    assert by["adaptive"]["unstable"] is None
    for d in ("x", "z"):
        assert by["adaptive"][f"{d}_reduction_pct"] > 60
        assert (
            by["adaptive"][f"{d}_reduction_pct"]
            > by["feedforward+robust"][f"{d}_reduction_pct"] + 20
        )
