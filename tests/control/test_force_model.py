"""The force-model feedforward (control.force_model), runout-line learning and ``sim mill
--disturbance``, against independent references: closed-form impulse responses integrated by
SciPy, the SciPy simulation of a mode under a known force, Monte Carlo against the Lyapunov
analysis, and exact sensor-bias offsets."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import integrate, signal
from typer.testing import CliRunner

from robovib.control.adaptive import PeriodTracker, TrackingRepetitive
from robovib.control.controllers import ScheduledTable
from robovib.control.force_model import (
    ForceModelFeedforward,
    force_model_r,
    force_model_variance_ratio,
    unpredictable_fraction,
)
from robovib.modal.parameters import ModalParameters
from robovib.sim import ConstantModesRobot, LinearMove, ModeSet, run_closed_loop

FS = 1000.0
MODE = ModalParameters(10.0, 1e6, 0.1)


def _robot(modes):
    fn, k, z = (np.array([[getattr(m, a) for m in modes]])
                for a in ("natural_frequency_hz", "stiffness_n_per_m", "damping_ratio"))  # fmt: skip
    return ConstantModesRobot({"x": ModeSet(fn, k, z)})


def _table(mode):
    return {0: ScheduledTable.constant([mode.natural_frequency_hz, mode.damping_ratio,
                                        mode.stiffness_n_per_m])}  # fmt: skip


def test_unpredictable_fraction_matches_the_closed_form_impulse_response():
    """sqrt(int_0^tau h^2 / int_0^inf h^2) with h = e^{-zeta wn t} sin(wd t), by quad."""
    wn, z = MODE.omega_n, MODE.damping_ratio
    wd = wn * math.sqrt(1 - z**2)

    def h2(t):
        return (math.exp(-z * wn * t) * math.sin(wd * t)) ** 2

    total = integrate.quad(h2, 0, 40 / (z * wn), limit=400)[0]
    for tau in (0.02, 0.04, 0.08):
        ref = math.sqrt(integrate.quad(h2, 0, tau, limit=200)[0] / total)
        assert unpredictable_fraction(MODE, tau) == pytest.approx(ref, abs=0.02)
    assert unpredictable_fraction(MODE, 0.0) < 0.01


def test_variance_ratio_respects_the_delay_bound_and_vanishes_with_a_large_weight():
    """No causal correction beats the minimum-variance bound; with r -> inf it does nothing."""
    bound = unpredictable_fraction(MODE, 0.032, sample_rate_hz=250.0)
    for r in (1e-3, 1e-1, 10.0):
        assert force_model_variance_ratio(MODE, MODE, r) >= bound - 0.01
    assert force_model_variance_ratio(MODE, MODE, 1e-3) < bound + 0.1  # and comes close
    assert force_model_variance_ratio(MODE, MODE, 1e6) == pytest.approx(1.0, abs=0.01)


def test_observer_state_follows_the_mode_under_a_known_force():
    """With a negligible correction (huge r) the model state is the open-loop response of the
    mode to the measured force: compared with scipy.signal.lsim of the same mode."""
    n = 4000
    t = np.arange(n) / FS
    force = np.zeros((n, 3))
    force[:, 0] = 300 * np.sin(2 * np.pi * 7.0 * t) * np.exp(-t) + 100 * np.sin(2 * np.pi * 13 * t)
    ctrl = ForceModelFeedforward(_table(MODE), r=1e12, highpass_hz=1e-6)
    ctrl.reset(np.zeros(n // 4), 0.004, FS)
    est = []
    for k in range(n // 4):
        lo, hi = max(0, 4 * k - 3), 4 * k + 1
        ctrl.command(k, np.zeros((hi - lo, 3)), force[lo:hi])
        est.append(ctrl._x[0][0])
    wn, z = MODE.omega_n, MODE.damping_ratio
    sys = signal.lti([wn**2 / MODE.stiffness_n_per_m], [1, 2 * z * wn, wn**2])
    _, y, _ = signal.lsim(sys, force[:, 0], t, interp=False)
    ref = y[: 4 * (n // 4) : 4]
    est = np.array(est)
    assert np.max(np.abs(est[250:] - ref[250:])) < 0.02 * np.max(np.abs(ref))


def test_simulated_reduction_matches_the_lyapunov_analysis():
    """Monte Carlo of the feedforward on a single-mode robot under white force (nominal delay
    and 8 ms more) against force_model_variance_ratio; the true robot sees a second mode too."""
    gen = np.random.default_rng(3)
    n = 60000
    force = np.zeros((n, 3))
    force[:, 0] = signal.lfilter(*signal.butter(2, 0.08), gen.normal(size=n)) * 200.0
    move = LinearMove("path", (0.5,), (0.5,))
    robot = _robot([MODE])
    open_rms = np.std(
        run_closed_loop(robot, move, force, FS, None, rng=0).true_displacement_m[:, 0]
    )
    for true_delay in (0.032, 0.040):
        ctrl = ForceModelFeedforward(_table(MODE), 0.032, r=0.3)
        rec = run_closed_loop(robot, move, force, FS, ctrl, delay_s=true_delay, rng=0)
        sim = np.std(rec.true_displacement_m[2000:, 0]) / open_rms
        ana = force_model_variance_ratio(MODE, MODE, 0.3, true_delay_s=true_delay)
        assert sim == pytest.approx(ana, abs=0.06)
        assert sim < 0.95


def test_robust_weight_avoids_amplification_on_a_second_mode():
    """The weight picked over a set with a light second mode never amplifies on that set,
    where the most aggressive weight does."""
    second = [MODE, ModalParameters(20.0, 5e6, 0.03)]
    assert force_model_variance_ratio(second, MODE, 1e-3, true_delay_s=0.024) > 1.0
    r, worst = force_model_r([MODE, second], MODE)
    assert worst < 1.0
    for td in (0.024, 0.032, 0.040):
        assert force_model_variance_ratio(second, MODE, r, true_delay_s=td) <= worst + 1e-12


def test_force_model_rejects_bad_settings():
    with pytest.raises(ValueError):
        ForceModelFeedforward(_table(MODE), r=0.0)
    with pytest.raises(ValueError):
        ForceModelFeedforward(_table(MODE), highpass_hz=-1.0)
    ctrl = ForceModelFeedforward(_table(MODE), delay_s=0.030)
    with pytest.raises(ValueError, match="whole number"):
        ctrl.reset(np.zeros(10), 0.004, FS)


def test_runout_line_learnt_over_a_revolution_on_a_known_mode():
    """A once-per-revolution line (2 teeth: half the tooth frequency) on a known mode: the
    repetitive on twice the tracked period removes >= 80 % of its closed-form steady response;
    the tooth-harmonic line is left to others (untouched)."""
    mode = ModalParameters(10.0, 1e6, 0.05)
    tooth = 1 / 6.0
    n = 20000
    t = np.arange(n) / FS
    force = np.zeros((n, 3))
    force[:, 0] = 200 * np.sin(np.pi * t / tooth)  # the revolution line, 3 Hz
    move = LinearMove("path", (0.5,), (0.5,))
    w, wn = np.pi / tooth, mode.omega_n
    h = 1 / mode.stiffness_n_per_m / abs(1 - (w / wn) ** 2 + 2j * mode.damping_ratio * w / wn)
    open_rms = 200 * h / math.sqrt(2)
    table = {0: ScheduledTable.constant([mode.natural_frequency_hz, mode.damping_ratio])}
    tracker = PeriodTracker(tooth)
    ctrl = TrackingRepetitive(table, tracker, period_multiple=2, n_harmonics=4, learning_time_s=1.3)
    rec = run_closed_loop(_robot([mode]), move, force, FS, ctrl, rng=0)
    assert np.std(rec.true_displacement_m[n // 2 :, 0]) < 0.2 * open_rms
    # a pure tooth-frequency line is left alone by the revolution learner (window leakage
    # only: a learner of that line would command about its full amplitude)
    m = 8000
    force = force[:m].copy()
    force[:, 0] = 200 * np.sin(2 * np.pi * t[:m] / tooth)
    ctrl = TrackingRepetitive(table, PeriodTracker(tooth), period_multiple=2, n_harmonics=4)
    rec = run_closed_loop(_robot([mode]), move, force, FS, ctrl, rng=0)
    amp = np.max(np.abs(rec.true_displacement_m[m // 2 :, 0]))
    assert np.max(np.abs(rec.meta["commands_m"][:, 0])) < 0.05 * amp


def test_sim_mill_cli_takes_disturbances(tmp_path):
    """``sim mill --disturbance force_bias_n=5`` shifts the measured force by exactly 5 N
    (same seed, nothing else changed); an unknown name exits 1."""
    import pandas as pd

    from robovib.cli import app

    base = ["sim", "mill", "--path-s-from", "0.33", "--path-s-to", "0.34", "--rpm", "250",
            "--fz", "0.5", "--ap", "6", "--ae", "6", "--material", "acetal"]  # fmt: skip
    runner = CliRunner()
    r0 = runner.invoke(app, [*base, "-o", str(tmp_path / "a.csv")])
    r1 = runner.invoke(
        app, [*base, "-o", str(tmp_path / "b.csv"), "--disturbance", "force_bias_n=5"]
    )
    assert r0.exit_code == 0 and r1.exit_code == 0, r0.output + r1.output
    a, b = pd.read_csv(tmp_path / "a.csv"), pd.read_csv(tmp_path / "b.csv")
    cols = [c for c in a.columns if c.startswith("force")]
    assert cols
    np.testing.assert_allclose(b[cols].to_numpy() - a[cols].to_numpy(), 5.0, atol=1e-6)
    bad = runner.invoke(app, [*base, "-o", str(tmp_path / "c.csv"), "--disturbance", "warp=1"])
    assert bad.exit_code == 1 and "unknown disturbance" in bad.output
