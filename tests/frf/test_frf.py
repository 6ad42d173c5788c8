"""FRF estimation against exact synthetic systems and against H1/H2 theory."""

import numpy as np
import pytest
from synthetic import hammer_hits, system_response

from robovib.frf import FRF, estimate_frf, impact_frf, to_compliance
from robovib.modal import ModalParameters

MODE = (18.0, 1.5e6, 0.04)  # fn [Hz], k [N/m], zeta


def exact_compliance(f, modes):
    return sum(ModalParameters(*m).compliance(f) for m in modes)


def test_impact_frf_matches_exact_compliance():
    forces, responses = hammer_hits([MODE], snr_db=60)
    res = impact_frf(forces, responses, 2048.0, f_max_hz=100)
    frf = res.frf.to_compliance(2.0)
    assert res.n_rejected == 0 and frf.n_averages == 5
    band = (frf.frequency_hz > 5) & (frf.frequency_hz < 60)
    truth = exact_compliance(frf.frequency_hz[band], [MODE])
    rel = np.abs(frf.values[band] - truth) / np.abs(truth)
    assert np.median(rel) < 0.01
    assert np.min(frf.coherence[band]) > 0.98


def test_accelerance_to_compliance():
    f = np.array([0.5, 1.0, 10.0])
    comp = np.array([1e-6, 2e-6, 3e-6 + 1e-6j])
    w = 2 * np.pi * f
    fk, back = to_compliance(f, -(w**2) * comp, "accelerance", 1.0)
    np.testing.assert_allclose(fk, [1.0, 10.0])
    np.testing.assert_allclose(back, comp[1:])
    _, back = to_compliance(f, 1j * w * comp, "mobility", 0.1)
    np.testing.assert_allclose(back, comp)
    with pytest.raises(ValueError, match="unknown FRF quantity"):
        to_compliance(f, comp, "inertance", 1.0)


def _random_test(noise_on, rng=1):
    rng = np.random.default_rng(rng)
    fs, n = 512.0, 2**17
    force = rng.normal(size=n) * 100
    resp = system_response(force, fs, [MODE], "displacement")
    f_meas, r_meas = force.copy(), resp.copy()
    if noise_on == "output":
        r_meas += rng.normal(size=n) * resp.std()
    else:
        f_meas += rng.normal(size=n) * 0.5 * force.std()
    return f_meas, r_meas, fs


@pytest.mark.parametrize("noise_on", ["output", "input"])
def test_h1_h2_bias_follows_theory(noise_on):
    """Output noise: H1 unbiased, |H2| too high; input noise: |H1| low by 1/(1+Gnn/Gxx), H2 unbiased."""
    force, resp, fs = _random_test(noise_on)
    h1 = estimate_frf(
        force, resp, fs, response_quantity="displacement", nperseg=2048, estimator="H1"
    )
    h2 = estimate_frf(
        force, resp, fs, response_quantity="displacement", nperseg=2048, estimator="H2"
    )
    band = (h1.frequency_hz > 5) & (h1.frequency_hz < 60)
    truth = exact_compliance(h1.frequency_hz[band], [MODE])
    r1 = np.median(np.abs(h1.values[band]) / np.abs(truth))
    r2 = np.median(np.abs(h2.values[band]) / np.abs(truth))
    if noise_on == "output":
        assert r1 == pytest.approx(1.0, abs=0.03)
        assert r2 > 1.1  # |H2| = |H| / coherence where the response is noise-dominated
    else:
        # Input noise of a quarter of the force power: Gnn / Gxx = 0.25 -> |H1| = |H| / 1.25.
        assert r1 == pytest.approx(0.8, abs=0.03)
        assert r2 == pytest.approx(1.0, abs=0.03)
    # Coherence = H1 / H2 (both are estimates of the same densities).
    np.testing.assert_allclose(h1.coherence, np.abs(h1.values / h2.values), rtol=1e-9)


def test_double_hit_and_overload_are_flagged_and_rejected():
    forces, responses = hammer_hits([MODE], n_hits=3)
    bad_f, bad_r = hammer_hits([MODE], n_hits=1, double_hit=True, rng=5)
    clipped = responses[1].copy()
    level = 0.05 * np.max(clipped)  # below the oscillation peaks, not just the impact spike
    clipped = np.clip(clipped, None, level)
    forces_all = np.vstack([forces, bad_f])
    responses_all = np.vstack([responses[:1], clipped[None], responses[2:], bad_r])
    res = impact_frf(forces_all, responses_all, 2048.0)
    flags = {h.index: h.reasons for h in res.hits}
    assert not flags[0] and not flags[2]
    assert any("overload" in r for r in flags[1])
    assert any("double hit" in r for r in flags[3])
    assert res.frf.n_averages == 2
    kept = impact_frf(forces_all, responses_all, 2048.0, reject=False)
    assert kept.frf.n_averages == 4


def test_impact_bad_input():
    forces, responses = hammer_hits([MODE], n_hits=2)
    with pytest.raises(ValueError, match="identically zero"):
        impact_frf(np.zeros_like(forces), responses, 2048.0)
    bad = responses.copy()
    bad[0, 10] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        impact_frf(forces, bad, 2048.0)
    with pytest.raises(ValueError, match="equal shape"):
        impact_frf(forces, responses[:, :-5], 2048.0)
    with pytest.raises(ValueError, match="Nyquist"):
        impact_frf(forces, responses, 2048.0, f_max_hz=2000)
    with pytest.raises(ValueError, match="unknown response quantity"):
        impact_frf(forces, responses, 2048.0, response_quantity="jerk")
    df, dr = hammer_hits([MODE], n_hits=2, double_hit=True)
    with pytest.raises(ValueError, match="all 2 hits were rejected"):
        impact_frf(df, dr, 2048.0)


def test_estimate_frf_bad_input():
    x = np.ones(100)
    with pytest.raises(ValueError, match="mismatched lengths"):
        estimate_frf(x, np.ones(99), 100.0)
    with pytest.raises(ValueError, match="identically zero"):
        estimate_frf(np.zeros(100), x, 100.0)
    with pytest.raises(ValueError, match="unknown estimator"):
        estimate_frf(x, x, 100.0, estimator="H3")


def test_frf_object_validation():
    f = np.linspace(1, 10, 10)
    with pytest.raises(ValueError, match="strictly increasing"):
        FRF(f[::-1], np.ones(10))
    with pytest.raises(ValueError, match="unknown direction"):
        FRF(f, np.ones(10), direction="w")
    with pytest.raises(ValueError, match="NaN"):
        FRF(f, np.full(10, np.nan))
    with pytest.raises(ValueError, match="fewer than 2 bins"):
        FRF(f, np.ones(10)).band(100, 200)
    # Coherence is a fraction in [0, 1]: out of range or NaN is an error, never clipped later.
    with pytest.raises(ValueError, match=r"coherence must lie in \[0, 1\].*1.5 at 4 Hz"):
        FRF(f, np.ones(10), coherence=np.r_[np.ones(3), 1.5, np.ones(6)])
    with pytest.raises(ValueError, match="coherence contains NaN"):
        FRF(f, np.ones(10), coherence=np.full(10, np.nan))
    assert FRF(f, np.ones(10), coherence=np.ones(10)).coherence.max() == 1.0


def test_impact_compliance_frf_is_the_one_pipeline():
    """frf compute and campaign processing share impact_compliance_frf: compliance against
    the exact mode, and a response in g read as m/s^2 is refused as an implausible FRF."""
    from robovib.frf import PlausibleRanges, impact_compliance_frf

    forces, responses = hammer_hits([MODE], snr_db=60)
    res = impact_compliance_frf(forces, responses, 2048.0, f_min_hz=2.0, f_max_hz=100,
                                plausible=PlausibleRanges(), direction="x")  # fmt: skip
    frf = res.frf
    assert frf.quantity == "compliance" and frf.direction == "x" and frf.frequency_hz[0] >= 2.0
    assert res.n_rejected == 0 and frf.n_averages == 5 and len(res.hits) == 5
    band = (frf.frequency_hz > 5) & (frf.frequency_hz < 60)
    truth = exact_compliance(frf.frequency_hz[band], [MODE])
    assert np.median(np.abs(frf.values[band] - truth) / np.abs(truth)) < 0.01
    in_g = responses / 9.80665  # 9.81x too small: the robot would look 9.81x stiffer
    with pytest.raises(ValueError, match=r"implausible FRF: .*g labelled m/s"):
        impact_compliance_frf(forces, in_g, 2048.0, f_min_hz=2.0, f_max_hz=100,
                              plausible=PlausibleRanges(peak_force_n=(1.0, 1e5),
                                                        peak_compliance_m_per_n=(1e-6, 1e-3)))  # fmt: skip
    unchecked = impact_compliance_frf(forces, in_g, 2048.0, f_min_hz=2.0, f_max_hz=100)
    np.testing.assert_allclose(unchecked.frf.values, frf.values / 9.80665, rtol=1e-9)
