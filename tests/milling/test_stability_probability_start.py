"""The warm-started P(stable) route against the dense per-sample scan on a coarse speed grid."""

import numpy as np

from robovib.milling import ALUMINIUM_7075, CuttingConditions, MillingTool
from robovib.milling.uncertainty import ModeDistribution, _scan_start, stability_probability


def test_scan_start_counts_the_neighbouring_speeds_on_a_coarse_grid():
    rpm = np.array([900.0, 300.0, 600.0, 1200.0])  # any order; +-15 % holds no other speed
    a = np.array([4.0, 8.0, 2.0, 6.0])
    # neighbours in speed order: 300-600, 600-900, 900-1200
    np.testing.assert_allclose(_scan_start(rpm, a), 0.7 * np.array([2.0, 2.0, 2.0, 4.0]))


def test_warm_route_finds_the_windows_of_the_dense_scan_on_20_speeds():
    # Chapter-3-like 2-DOF structure with a few % spread: flip windows at 550-900 rpm whose
    # start moves with each sample's natural frequencies.
    dist = {
        "x": ModeDistribution(16.4, 4.19e6, 9270.0, 0.04 * 16.4, 0.07 * 4.19e6, 0.03 * 9270.0),
        "y": ModeDistribution(8.49, 9.38e5, 6730.0, 0.04 * 8.49, 0.08 * 9.38e5, 0.05 * 6730.0),
    }
    tool = MillingTool(diameter_m=0.0254, n_flutes=2, helix_deg=30.0)
    cond = CuttingConditions(2000.0, 1e-4, 1e-3, 6e-3, down_milling=True)
    rpm = np.linspace(100.0, 3000.0, 20)
    kw = dict(n_samples=8, rng=3, method_error=False, fit_bias=0.0)
    dense = stability_probability(
        dist, tool, cond, ALUMINIUM_7075, rpm, warm_start=False, warm_from_mean=False, **kw
    )
    warm = stability_probability(dist, tool, cond, ALUMINIUM_7075, rpm, **kw)
    ratio = warm.a_lim_samples_m / dense.a_lim_samples_m
    assert np.nanmax(np.abs(ratio - 1)) < 1e-2
    # the case is one with windows: some sample's limit is far below the mean's at its speed
    assert np.min(dense.a_lim_samples_m / dense.mean.a_lim_m[None, :]) < 0.5
