"""Stability probability from a predictive distribution against a closed form (normal CDF)."""

import math

import numpy as np
import pytest
from scipy.stats import norm

from robovib.milling import ALUMINIUM_7075, CuttingConditions, MillingTool
from robovib.milling.stability import directional_coefficients
from robovib.milling.uncertainty import (
    ModeDistribution,
    mode_distribution_at_pose,
    plot_stability_probability,
    stability_probability,
)

TOOL = MillingTool(diameter_m=0.02, n_flutes=2, helix_deg=0.0)
SLOT = CuttingConditions(3000, 1e-4, 1e-3, 0.02)


def test_probability_of_unconditional_stability_matches_normal_cdf():
    # Rigid feed direction; normal mode with uncertain damping only. Zero-order slotting:
    # a_min = 2 pi / (N K_t |a_yy| max|Re G|),  max|Re G| = 1 / (4 k zeta (1 + zeta)).
    fn, k, c_mean, c_std = (
        40.0,
        5e6,
        2 * 0.05 * 5e6 / (2 * math.pi * 40),
        2 * 0.01 * 5e6 / (2 * math.pi * 40),
    )
    dist = {
        "x": ModeDistribution(40.0, 1e13, 4e10),
        "y": ModeDistribution(fn, k, c_mean, 0.0, 0.0, c_std),
    }
    res = stability_probability(dist, TOOL, SLOT, ALUMINIUM_7075, np.linspace(500, 5000, 30),
                                n_samples=300, method="zoa", rng=1, method_error=False,
                                fit_bias=0.0)  # fmt: skip
    ayy = directional_coefficients(0.0, math.pi, ALUMINIUM_7075.krc / ALUMINIUM_7075.ktc)[3]
    big_b = 8 * math.pi * k / (TOOL.n_flutes * ALUMINIUM_7075.ktc * abs(ayy))  # a_min = B z (1 + z)
    zeta_mu, zeta_sd = 0.05, 0.01
    depths = np.array([0.85, 1.0, 1.2]) * big_b * zeta_mu * (1 + zeta_mu)
    zstar = (-1 + np.sqrt(1 + 4 * depths / big_b)) / 2
    expected = 1 - norm.cdf((zstar - zeta_mu) / zeta_sd)
    got = res.p_unconditionally_stable(depths)
    np.testing.assert_allclose(got, expected, atol=0.1)
    assert got[0] > got[1] > got[2]
    # p_stable falls with depth at every speed and is 0/1 consistent with the sampled envelopes.
    assert np.all(np.diff(res.p_stable, axis=1) <= 0)
    fig = plot_stability_probability(res)
    assert "[rpm]" in fig.axes[0].get_xlabel() and "[mm]" in fig.axes[0].get_ylabel()


def test_zero_spread_gives_the_deterministic_envelope():
    dist = {"x": ModeDistribution(600.0, 5e6, 1131.0), "y": ModeDistribution(660.0, 6e6, 1500.0)}
    rpm = np.linspace(4000, 12000, 12)
    res = stability_probability(dist, TOOL, SLOT, ALUMINIUM_7075, rpm, n_samples=3, method="sdm",
                                method_error=False, fit_bias=0.0)  # fmt: skip
    # Every sample is the mean structure: its limits are the mean's (to the rounding of a root
    # found from another scan start), and P(stable) is 0 or 1 by the mean's envelope; the
    # default depth grid ends at 3x the mean's minimum, so one of its depths is that limit
    # itself, where rounding decides (left out).
    np.testing.assert_allclose(res.a_lim_samples_m, np.tile(res.mean.a_lim_m, (3, 1)), rtol=1e-9)
    expected = res.mean.a_lim_m[:, None] > res.depth_m[None, :]
    tie = np.isclose(res.mean.a_lim_m[:, None], res.depth_m[None, :], rtol=1e-9, atol=0.0)
    np.testing.assert_array_equal(res.p_stable[~tie], expected.astype(float)[~tie])
    assert tie.sum() <= 1


def test_band_of_a_sharp_distribution_holds_the_converged_limit_and_the_fit_bias():
    # Zero spread: the band is the method's own error and the fit's bias floor alone. The
    # method error estimated from half the steps must cover the distance of the 40-step chart
    # from an independently converged one (320 steps, tolerance 1e-6), speed by speed.
    from robovib.milling.sdm import sdm_lobes

    dist = {"x": ModeDistribution(600.0, 5e6, 1131.0), "y": ModeDistribution(660.0, 6e6, 1500.0)}
    cond = CuttingConditions(3000, 1e-4, 1e-3, 0.004)  # a/D = 0.2: the SDM error is visible
    rpm = np.linspace(4000, 12000, 12)
    res = stability_probability(dist, TOOL, cond, ALUMINIUM_7075, rpm, n_samples=40,
                                method="sdm", fit_bias=0.0)  # fmt: skip
    conv = sdm_lobes([dist["x"].mean], [dist["y"].mean], TOOL, cond, ALUMINIUM_7075, rpm,
                     steps_per_period=320, rtol=1e-6).a_lim_m  # fmt: skip
    lo, hi = res.a_lim_samples_m.min(axis=0), res.a_lim_samples_m.max(axis=0)
    assert np.all((lo <= conv) & (conv <= hi)), np.c_[lo / conv, hi / conv]
    err = np.asarray(res.settings["method_error"])
    assert np.all(err < 0.05) and np.all(err >= 1e-3)  # rtol is the floor
    # The fit bias alone: every sample within +-fit_bias of the mean, both ends reached.
    res = stability_probability(dist, TOOL, cond, ALUMINIUM_7075, rpm, n_samples=40,
                                method="sdm", method_error=False, fit_bias=0.02)  # fmt: skip
    ratio = res.a_lim_samples_m / res.mean.a_lim_m[None, :]
    assert np.all(np.abs(ratio - 1) <= 0.02 + 1e-12)
    assert ratio.min() < 0.985 and ratio.max() > 1.015
    with pytest.raises(ValueError, match="fit_bias"):
        stability_probability(dist, TOOL, cond, ALUMINIUM_7075, rpm, n_samples=3, fit_bias=-1)


class _PoseModel:
    """Stands for a fitted PoseModalModel: modes(X) in SI with predictive stds."""

    output_names_ = ("x_fn_hz",)

    def modes(self, x):
        from robovib.gp import PoseMode
        from robovib.modal import ModalParameters

        m = {d: ModalParameters.from_fn_k_c(fn, k, c) for d, fn, k, c in
             (("x", 20.0, 4e6, 3e3), ("y", 10.0, 2e6, 1.5e3), ("z", 30.0, 8e6, 2e3))}  # fmt: skip
        return [{d: PoseMode(p, 0.1 * p.natural_frequency_hz, 0.1 * p.stiffness_n_per_m,
                             0.1 * p.damping_ns_per_m, False, None) for d, p in m.items()}] * len(x)  # fmt: skip


class _ThesisUnitsModel:
    def predict(self, x, return_std=False):
        mean = np.tile([20.0, 4.0, 3.0, 10.0, 2.0, 1.5, 30.0, 8.0, 2.0], (len(x), 1))
        return (mean, 0.1 * mean) if return_std else mean


def test_distribution_from_a_pose_model_and_errors():
    d = mode_distribution_at_pose(_PoseModel(), [2400, 0, 45])
    assert d["x"].stiffness_n_per_m == pytest.approx(4e6) and d[
        "y"
    ].damping_ns_per_m == pytest.approx(1.5e3)
    assert d["x"].stiffness_std_n_per_m == pytest.approx(4e5)
    # A bare regressor's units cannot be told (thesis MN/m or SI N/m): refused, never guessed.
    with pytest.raises(TypeError, match="not a pose model"):
        mode_distribution_at_pose(_ThesisUnitsModel(), [2400, 0, 45])
    with pytest.raises(ValueError, match="method"):
        stability_probability(d, TOOL, SLOT, ALUMINIUM_7075, [3000.0], method="fdm")
    with pytest.raises(ValueError, match="std"):
        ModeDistribution(1.0, 1.0, 1.0, -1.0)


@pytest.mark.parametrize("radial_m", [0.02, 0.002])  # slotting, and 10 % immersion (flip lobes)
def test_quantile_targeted_route_matches_per_sample_sdm(radial_m):
    # Reference: every sample's envelope by its own dense SDM scan from the bottom of the range.
    def md(fn, k, zeta):
        c = 2 * zeta * k / (2 * math.pi * fn)
        return ModeDistribution(fn, k, c, 0.04 * fn, 0.06 * k, 0.1 * c)

    dist = {"x": md(600.0, 5e6, 0.03), "y": md(660.0, 6e6, 0.04)}
    cond = CuttingConditions(3000, 1e-4, 1e-3, radial_m)
    rpm = np.linspace(6000, 16000, 14)
    kw = dict(n_samples=12, rng=3, method_error=False, fit_bias=0.0, steps_per_period=20)
    ref = stability_probability(dist, TOOL, cond, ALUMINIUM_7075, rpm, warm_start=False,
                                warm_from_mean=False, **kw)  # fmt: skip
    assert ref.settings["route"] == "exact"
    for estimator in ("coarse-sdm", "zoa"):
        fast = stability_probability(dist, TOOL, cond, ALUMINIUM_7075, rpm, exact=False,
                                     fast_estimator=estimator, **kw)  # fmt: skip
        assert fast.settings["route"] == "fast"
        for q in (0.05, 0.5, 0.95):
            np.testing.assert_allclose(fast.depth_quantile_m(q), ref.depth_quantile_m(q), rtol=0.01)
    # The mean envelope is the SDM one (to the depth search's rtol; the reference scans densely).
    np.testing.assert_allclose(fast.mean.a_lim_m, ref.mean.a_lim_m, rtol=2e-3)
    with pytest.raises(ValueError, match="quantile_band"):
        stability_probability(dist, TOOL, cond, ALUMINIUM_7075, rpm, exact=False,
                              quantile_band=0.0, **kw)  # fmt: skip
    with pytest.raises(ValueError, match="estimator"):
        stability_probability(dist, TOOL, cond, ALUMINIUM_7075, rpm, exact=False,
                              fast_estimator="fft", **kw)  # fmt: skip
