"""Synthetic truth for tests: exact responses of known modal systems to known forces.

Each mode is the transfer function response/force of ``m x'' + c x' + k x = F``, discretised
with a first-order hold (:func:`scipy.signal.cont2discrete`), which is exact for a force that is
linear between samples, and run with :func:`scipy.signal.lfilter`. Everything here is
independent of robovib's own code.
"""

import numpy as np
from scipy import signal


def mode_response(force, fs, fn, k, zeta, quantity="acceleration"):
    wn = 2 * np.pi * fn
    m = k / wn**2
    c = 2 * zeta * m * wn
    num = {"displacement": [1.0], "velocity": [1.0, 0.0], "acceleration": [1.0, 0.0, 0.0]}[quantity]
    bd, ad, _ = signal.cont2discrete((num, [m, c, k]), 1.0 / fs, method="foh")
    return signal.lfilter(np.ravel(bd), ad, force)


def system_response(force, fs, modes, quantity="acceleration"):
    return sum(mode_response(force, fs, fn, k, z, quantity) for fn, k, z in modes)


def half_sine_pulse(n, fs, t0, width_s, peak):
    t = np.arange(n) / fs
    pulse = np.where((t >= t0) & (t <= t0 + width_s), np.sin(np.pi * (t - t0) / width_s), 0.0)
    return peak * np.clip(pulse, 0, None)


def hammer_hits(
    modes,
    fs=2048.0,
    duration_s=8.0,
    n_hits=5,
    snr_db=40.0,
    rng=0,
    width_s=1e-3,
    quantity="acceleration",
    force_noise_rel=0.0,
    double_hit=False,
):
    """(forces, responses) of ``n_hits`` hits; response noise at ``snr_db`` (power ratio)."""
    rng = np.random.default_rng(rng)
    n = int(duration_s * fs)
    forces, responses = [], []
    for _ in range(n_hits):
        t0 = 0.05 + rng.uniform(0, 0.02)
        f = half_sine_pulse(n, fs, t0, width_s, rng.uniform(300, 600))
        if double_hit:
            f = f + half_sine_pulse(n, fs, t0 + 0.08, width_s, 0.5 * f.max())
        r = system_response(f, fs, modes, quantity)
        noise = rng.normal(size=n) * np.sqrt(np.mean(r**2) / 10 ** (snr_db / 10))
        forces.append(f + force_noise_rel * f.max() * rng.normal(size=n))
        responses.append(r + noise)
    return np.array(forces), np.array(responses)
