"""Modal identification on synthetic hammer tests with known modes (40 dB SNR)."""

import math

import numpy as np
import pytest
from synthetic import hammer_hits

from robovib.frf import FRF, impact_frf
from robovib.modal import (
    ModalParameters,
    fit_dominant_mode,
    fit_modes,
    lscf_poles,
    remove_exponential_window_damping,
)

ONE_MODE = [(18.0, 1.5e6, 0.04)]
THREE_MODES = [(9.5, 1.2e6, 0.05), (25.0, 4.0e6, 0.03), (63.0, 4.5e6, 0.02)]


def _rel(a, b):
    return abs(a - b) / abs(b)


def test_modal_parameter_conversions():
    m, k, c = 2500.0, 1.2e6, 3000.0
    p = ModalParameters.from_mkc(m, k, c)
    wn = math.sqrt(k / m)
    assert p.natural_frequency_hz == pytest.approx(wn / (2 * math.pi))
    assert p.damping_ratio == pytest.approx(c / (2 * math.sqrt(k * m)))
    assert p.mass_kg == pytest.approx(m)
    assert p.damping_ns_per_m == pytest.approx(c)  # c = 2 zeta m wn (not the printed 2 m wn / zeta)
    q = ModalParameters.from_fn_k_c(p.natural_frequency_hz, k, c)
    assert q.damping_ratio == pytest.approx(p.damping_ratio)
    # Static compliance 1/k, peak compliance 1/(2 zeta k) at r = 1.
    assert abs(p.compliance(0.0)) == pytest.approx(1 / k)
    assert abs(p.compliance(p.natural_frequency_hz)) == pytest.approx(1 / (2 * p.damping_ratio * k))
    with pytest.raises(ValueError, match="positive"):
        ModalParameters(-1.0, 1e6, 0.1)
    with pytest.raises(ValueError, match="damping_ratio"):
        ModalParameters(10.0, 1e6, float("nan"))


@pytest.mark.parametrize("fs", [2048.0, 17066.0])
def test_dominant_mode_recovered_at_40db(fs):
    forces, responses = hammer_hits(
        ONE_MODE, fs=fs, duration_s=8.0 if fs < 4000 else 4.0, snr_db=40.0
    )
    frf = impact_frf(forces, responses, fs, f_max_hz=100).frf
    fit = fit_dominant_mode(frf)
    fn, k, zeta = ONE_MODE[0]
    p = fit.parameters
    assert _rel(p.natural_frequency_hz, fn) < 0.005
    assert _rel(p.stiffness_n_per_m, k) < 0.03
    assert _rel(p.damping_ratio, zeta) < 0.03
    # The stated standard errors are consistent with the actual error (within 5 sigma).
    assert abs(p.natural_frequency_hz - fn) < 5 * fit.std["natural_frequency_hz"] + 1e-3


def test_three_modes_recovered_at_40db():
    forces, responses = hammer_hits(THREE_MODES, snr_db=40.0, duration_s=16.0)
    frf = impact_frf(forces, responses, 2048.0, f_max_hz=100).frf
    fit = fit_modes(frf, (3.0, 90.0), max_order=30)
    assert len(fit.modes) == 3
    for mode, (fn, k, zeta) in zip(fit.modes, THREE_MODES, strict=True):
        assert _rel(mode.natural_frequency_hz, fn) < 0.005
        assert _rel(mode.stiffness_n_per_m, k) < 0.03
        assert _rel(mode.damping_ratio, zeta) < 0.03


def test_exponential_window_damping_removed():
    fn, k, zeta = 18.0, 1.5e6, 0.01  # light damping: rings past the record without a window
    forces, responses = hammer_hits([(fn, k, zeta)], duration_s=2.0, snr_db=40.0)
    tau = 0.5
    frf = impact_frf(forces, responses, 2048.0, exp_window_tau_s=tau, f_max_hz=100).frf
    assert frf.exp_window_tau_s == tau
    raw = fit_dominant_mode(frf, correct_exp_window=False).parameters
    fixed = fit_dominant_mode(frf).parameters
    # Without correction the window's 1/tau shows up as extra damping.
    assert raw.damping_ratio > 1.5 * zeta
    assert _rel(fixed.damping_ratio, zeta) < 0.03
    assert _rel(fixed.natural_frequency_hz, fn) < 0.005
    assert _rel(fixed.stiffness_n_per_m, k) < 0.03


def test_exponential_window_correction_closed_form():
    true = ModalParameters(20.0, 1e6, 0.02)
    tau = 0.25
    sigma_w = true.damping_ratio * true.omega_n + 1 / tau
    wd = true.omega_n * math.sqrt(1 - true.damping_ratio**2)
    wn_w = math.hypot(wd, sigma_w)
    windowed = ModalParameters(wn_w / (2 * math.pi), true.mass_kg * wn_w**2, sigma_w / wn_w)
    back = remove_exponential_window_damping(windowed, tau)
    assert back.natural_frequency_hz == pytest.approx(true.natural_frequency_hz, rel=1e-12)
    assert back.stiffness_n_per_m == pytest.approx(true.stiffness_n_per_m, rel=1e-12)
    assert back.damping_ratio == pytest.approx(true.damping_ratio, rel=1e-12)
    with pytest.raises(ValueError, match="adds more damping"):
        remove_exponential_window_damping(true, 0.001)


@pytest.mark.oracle
def test_lscf_poles_agree_with_sdypy_ema():
    from sdypy import EMA as sdypy

    f = np.arange(1.0, 100.0, 0.25)
    h = sum(ModalParameters(*m).compliance(f) for m in THREE_MODES)
    rng = np.random.default_rng(0)
    h = h * (1 + 0.01 * (rng.normal(size=f.size) + 1j * rng.normal(size=f.size)))
    model = sdypy.Model(
        frf=h[None], freq=f, lower=1, upper=99, pol_order_high=12, frf_form="receptance"
    )
    model.get_poles(show_progress=False)
    theirs = np.asarray(model.all_poles[-1])
    ours = lscf_poles(f, h, 12)
    for fn, _, zeta in THREE_MODES:
        wn = 2 * np.pi * fn
        pole = -zeta * wn + 1j * wn * np.sqrt(1 - zeta**2)
        o = ours[np.argmin(np.abs(ours - pole))]
        t = theirs[np.argmin(np.abs(theirs - pole))]
        assert abs(o.imag - t.imag) / t.imag < 2e-3
        assert abs(o.real - t.real) / abs(t.real) < 0.05
        assert abs(o - pole) / abs(pole) < 2e-3


def test_fit_rejects_tiny_band():
    f = np.arange(1.0, 50.0, 0.5)
    frf = FRF(f, ModalParameters(10.0, 1e6, 0.05).compliance(f))
    with pytest.raises(ValueError, match="bins"):
        fit_dominant_mode(frf, band_hz=(9.9, 10.6))


def test_fit_frfs_fits_every_frf_and_names_a_failing_one():
    """modal.fit_frfs (what ``modal fit`` runs): known modes recovered, flags combined, a
    failing FRF named by its position."""
    from robovib.frf import FRF
    from robovib.modal import ModalParameters, fit_frfs
    from robovib.modal.plot import plot_frf_fits

    f = np.linspace(5.0, 60.0, 551)
    truth = [ModalParameters(15.0, 3e6, 0.05), ModalParameters(32.0, 8e6, 0.03)]
    frfs = [FRF(f, m.compliance(f), direction=d) for m, d in zip(truth, "xy", strict=True)]
    fits = fit_frfs(frfs)
    for fit, m in zip(fits, truth, strict=True):
        p = fit.dominant.parameters
        assert p.natural_frequency_hz == pytest.approx(m.natural_frequency_hz, rel=1e-3)
        assert p.stiffness_n_per_m == pytest.approx(m.stiffness_n_per_m, rel=1e-2)
        assert fit.modes is None and fit.flags == fit.dominant.flags
    doc = fits[1].to_dict(1)
    assert doc["index"] == 1 and doc["direction"] == "y" and "modes" not in doc
    two = FRF(f, truth[0].compliance(f) + truth[1].compliance(f), direction="x")
    (both,) = fit_frfs([two], (8.0, 45.0), all_modes=True)
    fns = sorted(m.natural_frequency_hz for m in both.modes.modes)
    np.testing.assert_allclose(fns, [15.0, 32.0], rtol=1e-3)
    assert both.flags == (*both.dominant.flags, *both.modes.flags)
    assert both.flagged == (both.dominant.flagged or both.modes.flagged)
    assert len(both.to_dict(0)["modes"]) == 2
    with pytest.raises(ValueError, match=r"^FRF 1: band 10.0-20.0 Hz"):
        fit_frfs([frfs[0], FRF(f[f > 40], frfs[1].values[f > 40])], (10.0, 20.0))
    fig = plot_frf_fits(both, title="t")
    assert fig.axes and "t" in fig.axes[0].get_title()
