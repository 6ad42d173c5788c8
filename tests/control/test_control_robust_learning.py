"""Per-harmonic learning gains kept stable over a delay/model band (issue 40).

The reference is :func:`repetitive_loop_radius` (the roots of the learning loop's characteristic
polynomial, ``numpy.roots``), evaluated on a fine grid of the band; ``robust_learning_scale``
uses the delayed-integrator margin in closed form.
"""

import numpy as np
import pytest

from robovib.control.adaptive import robust_learning_scale
from robovib.control.loop_analysis import repetitive_loop_radius


def _frf(fn, z, f):
    wn, w = 2 * np.pi * fn, 2 * np.pi * f
    return wn**2 / (wn**2 - w**2 + 2j * z * wn * w)


def _worst_radius(fn, z, f, gain, delay_cycles, window_cycles, band):
    d_tau, d_fn, d_gain = band
    worst = 0.0
    for tau in np.linspace(-d_tau, d_tau, 5):
        for s in np.linspace(1 - d_fn, 1 + d_fn, 3):
            for g in (1 - d_gain, 1 + d_gain):
                ratio = g * _frf(fn * s, z, f) / _frf(fn, z, f) * np.exp(-2j * np.pi * f * tau)
                r = repetitive_loop_radius(ratio, gain, delay_cycles, window_cycles)
                worst = max(worst, r)
    return worst


@pytest.mark.parametrize(("fn", "zeta", "rpm"), [(20.9, 0.12, 125.0), (17.4, 0.10, 250.0),
                                                 (10.6, 0.17, 125.0)])  # fmt: skip
def test_robust_gain_keeps_every_learnt_harmonic_stable_over_the_band(fn, zeta, rpm):
    period_s, delay_cycles, cycle = 60 / (rpm * 2), 8, 0.004
    window = round(period_s / cycle)
    gain = cycle / 0.4  # the nominal 0.4 s learning time
    h = np.arange(1, 9)
    f = h / period_s
    f = f[f <= 1.6 * fn]
    band = (0.008, 0.03, 0.1)
    scale = robust_learning_scale([[fn, zeta]], f, gain, delay_cycles + (window - 1) / 2,
                                  delay_uncertainty_s=band[0], fn_uncertainty_rel=band[1],
                                  gain_uncertainty_rel=band[2])  # fmt: skip
    assert np.all((scale >= 0) & (scale <= 1))
    for fi, sc in zip(f, scale, strict=True):
        if sc > 0:  # a learnt harmonic converges on every plant of the band
            assert _worst_radius(fn, zeta, fi, gain * sc, delay_cycles, window, band) < 1.0
    # the nominal gain is not robust everywhere: at least one harmonic near or above the
    # resonance diverges somewhere in the band with it (the reason for the scaling)
    nominal = [_worst_radius(fn, zeta, fi, gain, delay_cycles, window, band) for fi in f]
    if rpm == 125.0 and fn > 20:  # harmonics 5 and 6 straddle the 20.9 Hz mode
        assert max(nominal) > 1.0
        assert np.min(scale) < 1.0


def test_no_uncertainty_keeps_the_nominal_gain_off_resonance():
    scale = robust_learning_scale([[20.0, 0.1]], [2.0, 4.0], 0.01, 38.0,
                                  delay_uncertainty_s=0.0, gain_uncertainty_rel=0.0)  # fmt: skip
    np.testing.assert_allclose(scale, 1.0)


def test_a_harmonic_past_ninety_degrees_is_not_learnt():
    # 16 ms of unknown delay at 29 Hz is 167 degrees: no gain converges
    scale = robust_learning_scale([[20.0, 0.1]], [29.0], 0.01, 38.0, delay_uncertainty_s=0.016)
    assert scale[0] == 0.0


def test_robust_learning_scale_refuses_bad_bands():
    with pytest.raises(ValueError, match="uncertainties"):
        robust_learning_scale([[20.0, 0.1]], [4.0], 0.01, 38.0, delay_uncertainty_s=-0.001)
