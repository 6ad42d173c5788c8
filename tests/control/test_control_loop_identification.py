"""Online identification of each learnt harmonic's loop phase (issue 40).

References: a synthetic residual with a known loop factor ``lambda`` (the identifier must
recover its phase), and a closed loop simulated here from the mode's own ODE (exact
zero-order-hold discretisation by SciPy) with a delay 16 ms longer than the learner assumes.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from scipy import signal

from robovib.control.adaptive import LoopIdentifier, PeriodTracker, TrackingRepetitive
from robovib.control.controller_file import (
    design_controller,
    load_controller,
    write_controller_file,
)
from robovib.control.controllers import ScheduledTable
from robovib.control.path_design import ControlPath
from robovib.gp.dominant_modes import PoseMode
from robovib.modal.parameters import ModalParameters


def test_identifier_recovers_a_known_loop_phase_from_moving_phasors():
    rng = np.random.default_rng(3)
    every, delay, window = 4, 32, 240
    ident = LoopIdentifier((3, 1), every, delay, window, forget_cycles=5000.0,
                           max_rel_error=0.2, cycles_per_window=window / every)  # fmt: skip
    lam = np.array([1.1 * np.exp(-1j * np.deg2rad(a)) for a in (15.0, 60.0, 100.0)])
    dist = np.array([2.0 + 1j, -1.0, 0.5j])
    q0 = delay // every + 1
    q1 = math.ceil((window + delay) / every)
    sent = []
    u = np.zeros(3, complex)
    for k in range(3000):
        old = [sent[j] if j >= 0 else np.zeros(3) for j in range(k - q1, k - q0 + 1)]
        x = np.mean(old, axis=0)
        z = dist + lam * x + 0.05 * (rng.normal(size=3) + 1j * rng.normal(size=3))
        ident.observe(z[:, None], window)
        u = u + 0.05 * (rng.normal(size=3) + 1j * rng.normal(size=3))  # a random walk
        sent.append(u.copy())
        ident.sent(u[:, None])
    np.testing.assert_allclose(np.angle(ident.factor[:, 0]), np.angle(lam), atol=np.deg2rad(5))
    np.testing.assert_allclose(np.abs(ident.factor[:, 0]), 1.0)  # the phase only
    assert np.all(ident.rel_error[:, 0] < 0.2)


def test_identifier_keeps_the_nominal_factor_without_excitation():
    ident = LoopIdentifier((2, 1), 4, 32, 240, forget_cycles=5000.0, max_rel_error=0.2,
                           cycles_per_window=60.0)  # fmt: skip
    rng = np.random.default_rng(0)
    for _ in range(2000):  # constant phasors: nothing to learn the loop from
        ident.observe((rng.normal(size=2) + 1j * rng.normal(size=2))[:, None], 240)
        ident.sent(np.ones((2, 1), complex))
    np.testing.assert_array_equal(ident.factor, 1.0)


def test_identifier_refuses_bad_settings():
    with pytest.raises(ValueError, match="forget_cycles"):
        LoopIdentifier((2, 1), 4, 32, 240, forget_cycles=0.5, max_rel_error=0.2,
                       cycles_per_window=60.0)  # fmt: skip


def _closed_loop(identify: bool, delay_error_s: float, seconds: float = 30.0):
    """A 17.5 Hz mode (zeta 0.1), a 16.7 Hz disturbance line (harmonic 4 of 125 rpm x 2 teeth):
    the learner's residual amplitude at that line, first and last 2 s, in mm."""
    fs, every, delay_s = 1000.0, 4, 0.032
    fn, zeta, period = 17.5, 0.1, 0.24
    wn = 2 * np.pi * fn
    a = np.array([[0.0, 1.0], [-(wn**2), -2 * zeta * wn]])
    b = np.array([[0.0], [wn**2]])
    ad, bd, *_ = signal.cont2discrete((a, b, np.array([[1.0, 0.0]]), np.zeros((1, 1))), 1 / fs)
    tracker = PeriodTracker(period)
    learner = TrackingRepetitive({0: ScheduledTable.constant([fn, zeta])}, tracker, delay_s,
                                 n_harmonics=4, divergence_ratio=1e6,
                                 delay_uncertainty_s=0.008, identify_loop=identify)  # fmt: skip
    n = round(seconds * fs)
    n_cmd = n // every
    learner.reset(np.zeros(n_cmd), every / fs, fs)
    t = np.arange(n) / fs
    dist = 2e-5 * np.sin(2 * np.pi * 4 * t / period + 0.3)
    force = np.zeros((n, 3))
    force[:, 0] = 100 * np.sin(2 * np.pi * t / period) + 30 * np.sin(4 * np.pi * t / period)
    lag = round((delay_s + delay_error_s) * fs)
    applied = np.zeros(n + lag + every)
    state = np.zeros(2)
    y = np.zeros((n, 3))
    for k in range(n_cmd):
        for i in range(k * every, (k + 1) * every):
            state = ad @ state + bd[:, 0] * applied[i]
            y[i, 0] = dist[i] + state[0]
        blk = slice(k * every, (k + 1) * every)
        u = learner.command(k, y[blk], force[blk])[0]
        start = (k + 1) * every + lag
        applied[start : start + every] = u

    def line(seg):
        ts = t[seg]
        return 2 * abs(np.mean(y[seg, 0] * np.exp(-2j * np.pi * 4 * ts / period))) * 1e3

    last = slice(n - round(2 * fs), n)
    return line(slice(0, round(2 * fs))), line(last)


def test_identified_phase_makes_a_learner_converge_with_16_ms_of_unknown_delay():
    # 16 ms at 16.7 Hz is 96 degrees: the fixed learner's loop turns past 90 and grows
    open_amp = 0.02  # the disturbance line's amplitude [mm]
    _, fixed = _closed_loop(False, 0.016)
    _, identified = _closed_loop(True, 0.016)
    assert fixed > 0.5 * open_amp  # not removed (grows, or at best stalls)
    assert identified < 0.2 * open_amp
    # with the delay it was designed for, identification costs nothing
    _, nominal = _closed_loop(True, 0.0)
    assert nominal < 0.2 * open_amp


class _Flat:
    input_names = ("x_mm", "y_mm", "rz_deg")

    def modes(self, X):
        m = ModalParameters(18.0, 1.0e6, 0.1)
        pm = PoseMode(m, 0.2, 2e4, 0.05 * m.damping_ns_per_m, False, None)
        return [{"x": pm, "z": pm} for _ in np.atleast_2d(X)]


def test_new_files_identify_the_loop_and_version_1_files_run_as_before(tmp_path):
    path = ControlPath.through(_Flat.input_names, [[2350, 500, 30], [2350, -200, 100]])
    doc = design_controller(_Flat(), path, "adaptive+force", spindle_rpm=125.0)
    assert doc["format_version"] == 3 and doc["learner"]["identify_loop"] is True
    old = json.loads(json.dumps(doc))
    old["format_version"] = 1
    for key in ("identify_loop", "identify_rel_error", "learning_time_s"):
        del old["learner"][key]
    f = tmp_path / "v1.json"
    f.write_text(json.dumps(old))
    rt = load_controller(f)
    assert rt.learner_settings["identify_loop"] is False
    assert rt.learner_settings["learning_time_s"] == 0.4


def test_new_files_pool_the_loop_phase_and_version_2_files_run_as_before(tmp_path):
    path = ControlPath.through(_Flat.input_names, [[2350, 500, 30], [2350, -200, 100]])
    doc = design_controller(_Flat(), path, "adaptive+force", spindle_rpm=125.0)
    assert doc["learner"]["pool_loop_phase"] is True
    old = json.loads(json.dumps(doc))
    old["format_version"] = 2
    del old["learner"]["pool_loop_phase"]
    f = tmp_path / "v2.json"
    f.write_text(json.dumps(old))
    rt = load_controller(f)
    assert rt.learner_settings["pool_loop_phase"] is False
    assert rt.learner_settings["identify_loop"] is True
    learners = [p for p in rt._inner.inner.parts if isinstance(p, TrackingRepetitive)]
    assert learners and all(p._ident._h is None for p in learners)
    rt_new = load_controller(write_controller_file(tmp_path / "v3.json", doc))
    learners = [p for p in rt_new._inner.inner.parts if isinstance(p, TrackingRepetitive)]
    assert learners and all(p._ident._h is not None for p in learners)


def _pooled_identification(pool: bool, truth_deg=None):
    """Six harmonics whose loop phase is ``a + b h`` (a delay and an offset): 1-3 measured
    with little noise, 4-6 with 20x more (a line near a resonance, in non-periodic response).
    The identified phases [deg], the truth [deg] and where the pooled phase was taken."""
    rng = np.random.default_rng(3)
    every, delay, window = 4, 32, 240
    h = np.arange(1, 7)
    truth = np.deg2rad(-20.0 - 12.0 * h if truth_deg is None else np.asarray(truth_deg, float))
    lam = np.exp(1j * truth)
    noise = np.array([0.05, 0.05, 0.05, 1.0, 1.0, 1.0])
    ident = LoopIdentifier((6, 1), every, delay, window, forget_cycles=5000.0, max_rel_error=0.2,
                           cycles_per_window=window / every,
                           harmonic_numbers=h if pool else None)  # fmt: skip
    q0 = delay // every + 1
    q1 = math.ceil((window + delay) / every)
    sent = []
    u = np.zeros(6, complex)
    dist = np.full(6, 1 + 0.5j)
    for k in range(3000):
        old = [sent[j] if j >= 0 else np.zeros(6) for j in range(k - q1, k - q0 + 1)]
        z = dist + lam * np.mean(old, axis=0) + noise * (rng.normal(size=6)
                                                         + 1j * rng.normal(size=6))  # fmt: skip
        ident.observe(z[:, None], window)
        u = u + 0.05 * (rng.normal(size=6) + 1j * rng.normal(size=6))
        sent.append(u.copy())
        ident.sent(u[:, None])
    return np.rad2deg(np.angle(ident.factor[:, 0])), np.rad2deg(truth), ident.pooled[:, 0]


def test_pooled_phases_give_the_noisy_harmonics_the_line_through_the_others():
    alone, truth, _ = _pooled_identification(False)
    pooled, _, took = _pooled_identification(True)
    np.testing.assert_allclose(alone[:3], truth[:3], atol=2.0)
    np.testing.assert_allclose(pooled[:3], truth[:3], atol=2.0)  # own estimates kept
    assert not took[:3].any()
    # some noisy harmonic has no usable estimate of its own; pooled, every one has the line's
    assert np.any(np.abs(alone[3:] - truth[3:]) > 30.0)
    assert took[3:].any()
    np.testing.assert_allclose(pooled, truth, atol=4.0)


def test_phases_off_any_line_are_not_pooled():
    """Well-measured phases that no ``a + b h`` fits (a reduced chi-square far above 1):
    the line's inflated standard error is above the trust threshold, so the noisy
    harmonics keep the nominal phase instead of an extrapolation of a wrong line."""
    truth = [-20.0, 60.0, -100.0, -40.0, 30.0, -120.0]
    pooled, _, took = _pooled_identification(True, truth)
    assert not took.any()
    alone, _, _ = _pooled_identification(False, truth)
    np.testing.assert_array_equal(pooled, alone)


def test_pooling_refuses_harmonic_numbers_of_the_wrong_shape():
    with pytest.raises(ValueError, match="harmonic_numbers"):
        LoopIdentifier((3, 1), 4, 32, 240, forget_cycles=5000.0, max_rel_error=0.2,
                       cycles_per_window=60.0, harmonic_numbers=[1, 2])  # fmt: skip


@pytest.mark.parametrize("pause", [True, False])
def test_a_paused_learner_does_not_wind_up_while_its_correction_is_faded_out(pause):
    fs, every, period = 1000.0, 4, 0.24
    learner = TrackingRepetitive({0: ScheduledTable.constant([17.5, 0.1])}, PeriodTracker(period),
                                 0.032, n_harmonics=4, pause_when_faded=pause)  # fmt: skip
    n_cmd = 1000
    learner.reset(np.zeros(n_cmd), every / fs, fs)
    learner.learning_scale = 0.0  # what a guard that faded the correction out sets
    t = np.arange(n_cmd * every) / fs
    y = np.zeros((t.size, 3))
    y[:, 0] = 2e-5 * np.sin(2 * np.pi * 4 * t / period)  # the open-loop residual
    force = np.zeros((t.size, 3))
    force[:, 0] = 100 * np.sin(2 * np.pi * t / period)
    for k in range(n_cmd):
        blk = slice(k * every, (k + 1) * every)
        learner.command(k, y[blk], force[blk])
    if pause:
        np.testing.assert_array_equal(learner._u, 0.0)
    else:  # the old behaviour: it integrates the open-loop residual regardless
        assert np.abs(learner._u).max() > 0


def _tracker_errors(lag: int, seed: int = 5) -> np.ndarray:
    """Relative errors of a tracker's period on a known periodic force (4 % fast) in
    low-pass random force of half the periodic part's std, after its first 2 s."""
    nominal, true = 0.24, 0.24 / 1.04
    n = 30000
    t = np.arange(n) / 1000.0
    ph = 2 * np.pi * t / true
    periodic = np.sin(ph) + 0.5 * np.sin(2 * ph + 0.3) + 0.3 * np.sin(5 * ph + 1.0)
    b, a = signal.butter(2, 40.0 / 500.0)
    noise = signal.lfilter(b, a, np.random.default_rng(seed).normal(size=n))
    noise *= 0.5 * periodic.std() / noise.std()
    f = np.column_stack([periodic + noise, np.zeros(n), np.zeros(n)])
    tr = PeriodTracker(nominal, lag_periods=lag)
    tr.reset(n, 1000.0)
    err = []
    for k in range(n // 4):
        tr.update(k, f[4 * k : 4 * k + 4])
        if k * 4 >= 2000:
            err.append(tr.period_s / true - 1)
    return np.asarray(err)


def test_a_tracker_over_two_periods_has_less_period_error_in_non_periodic_force():
    one, two = _tracker_errors(1), _tracker_errors(2)
    assert abs(np.mean(one)) < 2e-3 and abs(np.mean(two)) < 2e-3  # both lock on the true period
    rms1, rms2 = np.sqrt(np.mean(one**2)), np.sqrt(np.mean(two**2))
    assert rms2 < 0.8 * rms1


def test_tracker_lag_refuses_a_range_that_reaches_the_next_multiple():
    with pytest.raises(ValueError, match="lag_periods"):
        PeriodTracker(0.24, rel_range=0.3, lag_periods=2)
    with pytest.raises(ValueError, match="lag_periods"):
        PeriodTracker(0.24, lag_periods=1.5)


def test_new_files_track_over_two_periods_and_older_files_over_one(tmp_path):
    path = ControlPath.through(_Flat.input_names, [[2350, 500, 30], [2350, -200, 100]])
    doc = design_controller(_Flat(), path, "adaptive+force", spindle_rpm=125.0)
    assert doc["tracker"]["lag_periods"] == 2
    old = json.loads(json.dumps(doc))
    old["format_version"] = 2
    del old["tracker"]["lag_periods"]
    f = tmp_path / "v2.json"
    f.write_text(json.dumps(old))
    assert load_controller(f)._inner.tracker.lag_periods == 1
