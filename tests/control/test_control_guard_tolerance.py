"""The guard's "not reduced" test against signals whose answer is known (issue 40)."""

import math

import numpy as np
import pytest
from scipy import signal

from robovib.control.adaptive import PeriodTracker
from robovib.control.guard import FadeGuard, amplification_test


def _ar1(rng, n, phi):
    return signal.lfilter([1.0], [1.0, -phi], rng.standard_normal(n + 200))[200:]


@pytest.mark.parametrize("phi", [0.0, 0.8])
def test_resolution_is_the_sampling_noise_of_a_windows_rms(phi):
    # The window's RMS over n samples of an AR(1) process: its relative std is
    # 1 / sqrt(2 n_eff) with n_eff = n (1 - phi^2) / (1 + phi^2) (x^2 has autocorrelation
    # phi^(2k)); the test's resolution at z = 1 must match the spread of RMS estimates.
    rng = np.random.default_rng(0)
    n = 500
    rms, res, n_eff = [], [], []
    for _ in range(400):
        x = _ar1(rng, n, phi)
        t = amplification_test(x, x)
        rms.append(np.std(x))
        res.append(t.resolution)
        n_eff.append(t.n_effective)
    rel_std = np.std(rms) / np.mean(rms)
    closed = n * (1 - phi**2) / (1 + phi**2)
    assert np.median(n_eff) == pytest.approx(closed, rel=0.15)
    assert np.median(res) == pytest.approx(rel_std, rel=0.2)
    assert np.median(res) == pytest.approx(1 / np.sqrt(2 * closed), rel=0.1)


def test_a_real_amplification_is_found_and_equal_signals_are_not():
    rng = np.random.default_rng(2)
    y_open = _ar1(rng, 500, 0.8)
    found = amplification_test(1.1 * y_open + 0.01 * rng.standard_normal(500), y_open)
    assert found.amplified
    assert found.ratio == pytest.approx(1.1, rel=0.01)
    assert found.effect == pytest.approx(0.1, rel=0.1)
    same = amplification_test(y_open.copy(), y_open)
    assert not same.amplified and same.ratio == pytest.approx(1.0) and same.effect == 0.0


def test_an_uncorrelated_correction_as_large_as_the_noise_is_amplification():
    # d independent of y_open with RMS 0.5 x: the true RMS ratio is sqrt(1.25) = 1.118
    rng = np.random.default_rng(3)
    y_open = rng.standard_normal((500, 3))
    t = amplification_test(y_open + 0.5 * rng.standard_normal((500, 3)), y_open)
    assert t.amplified and t.ratio == pytest.approx(np.sqrt(1.25), rel=0.05)


def test_noise_dominated_window_with_a_tiny_correction_is_not_amplified():
    # The README's 2 mm test cut: the tracker is sensor noise; the correction's response d is
    # a thousandth of it. The true RMS ratio sqrt(1 + var d / var y_open) is 1.000 000 5:
    # within the window's noise, so the guard must keep the correction. The old test
    # (ratio > 1.0 exactly) faded it out about half the time.
    rng = np.random.default_rng(3)
    old_trips = 0
    for _ in range(200):
        y_open = rng.standard_normal((500, 3))
        d = np.zeros((500, 3))
        d[:, 0] = 1e-3 * np.sin(2 * np.pi * 29.2 * np.arange(500) / 1000 + rng.uniform(0, 6))
        y = y_open + d
        assert not amplification_test(y, y_open).amplified
        old_trips += np.sqrt(np.sum(np.var(y, 0))) > np.sqrt(np.sum(np.var(y_open, 0)))
    assert old_trips > 40


def test_amplification_test_refuses_bad_input():
    with pytest.raises(ValueError, match="same shape"):
        amplification_test(np.zeros(10), np.zeros(11))
    with pytest.raises(ValueError, match="finite"):
        amplification_test(np.full(10, np.nan), np.zeros(10))
    with pytest.raises(ValueError, match="n >= 8"):
        amplification_test(np.zeros(4), np.zeros(4))
    with pytest.raises(ValueError, match="z_score"):
        amplification_test(np.ones(10), np.ones(10), z_score=0.0)


class _Dither:
    """A controller that sends a fixed dither ``a sin(0.7 k)`` in X (its effect known)."""

    def __init__(self, amplitude_m):
        self.amplitude_m = amplitude_m

    def reset(self, coords, period_s, sample_rate_hz):
        pass

    def command(self, k, tracker_m, force_n):
        return np.array([self.amplitude_m * math.sin(0.7 * k), 0.0, 0.0])


def _guard_events(amplitude_m, seed):
    """A noise-only cut (5 µm tracker noise) plus the dither's response through a 20 Hz mode."""
    rng = np.random.default_rng(seed)
    n, every, fs, delay = 4000, 4, 1000.0, 32
    t = np.arange(n) / fs
    force = 100 * np.sin(2 * np.pi * 5 * t)[:, None] + rng.standard_normal((n, 3))
    noise = 5e-6 * rng.standard_normal((n, 3))
    k = np.arange(n) // every
    u = np.zeros(n)  # the command of cycle k is held from its last sample, delay samples late
    u[delay + every - 1 :] = amplitude_m * np.sin(0.7 * k[: n - delay - every + 1])
    wn = 2 * np.pi * 20.0
    b, a, _ = signal.cont2discrete(([wn**2], [1, 0.2 * wn, wn**2]), 1 / fs, "zoh")
    y = noise.copy()
    y[:, 0] += signal.lfilter(np.squeeze(b), a, u)
    guard = FadeGuard(_Dither(amplitude_m), PeriodTracker(0.2), {0: (20.0, 0.1)}, 0.032)
    guard.reset(np.zeros(n // every), every / fs, fs)
    for j in range(n // every - 2):
        seg = slice(j * every, (j + 1) * every)
        guard.command(j, y[seg], force[seg])
    return [e for e in guard.events if "not reduced" in e.reason]


@pytest.mark.parametrize("seed", [5, 6, 7])
def test_guard_keeps_a_harmless_correction_and_fades_a_harmful_one(seed):
    # 1 nm of dither on 5 µm of noise: RMS ratio 1 + 1e-8, within noise -> kept
    assert not _guard_events(1e-9, seed)
    # 20 µm of dither through the mode: the tip moves far more than the noise -> faded
    events = _guard_events(2e-5, seed)
    assert events and "independent samples" in events[0].reason and "resolution" in events[0].reason
