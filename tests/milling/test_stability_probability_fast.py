"""The quantile-targeted P(stable) route (``exact=False``) on the compiled kernel.

References: per-sample dense NumPy SDM (``solver="numpy"``, every speed scanned from the bottom
of the range) and, for the subset entry of the kernel, the kernel solving every pair.
"""

import numpy as np
import pytest

from robovib.milling import ALUMINIUM_7075, CuttingConditions, MillingTool
from robovib.milling.sdm_kernel import sdm_limits
from robovib.milling.uncertainty import (
    FAST_MAX_ESTIMATE_ERROR,
    ModeDistribution,
    _refine_at_ranks,
    _scan_start,
    stability_probability,
)
from robovib.modal import ModalParameters

TOOL = MillingTool(diameter_m=0.0254, n_flutes=2, helix_deg=30.0)
COND = CuttingConditions(2000.0, 1e-4, 1e-3, 6e-3, down_milling=True)
DIST = {
    "x": ModeDistribution(16.4, 4.19e6, 9270.0, 0.04 * 16.4, 0.07 * 4.19e6, 0.03 * 9270.0),
    "y": ModeDistribution(8.49, 9.38e5, 6730.0, 0.04 * 8.49, 0.08 * 9.38e5, 0.05 * 6730.0),
}


def _structures(n, seed):
    gen = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        sx = gen.normal(1.0, 0.04, 3)
        sy = gen.normal(1.0, 0.05, 3)
        out.append(
            (
                [ModalParameters(16.4 * sx[0], 4.19e6 * sx[1], 0.11 * sx[2])],
                [ModalParameters(8.49 * sy[0], 9.38e5 * sy[1], 0.19 * sy[2])],
            )
        )
    return out


def test_sdm_limits_solves_only_the_requested_pairs():
    structs = _structures(4, 0)
    rpm = np.linspace(400.0, 2400.0, 6)
    start = np.full((4, 6), np.nan)
    full, _, n_full = sdm_limits(structs, TOOL, COND, ALUMINIUM_7075, rpm, start_m=start)
    mask = np.zeros((4, 6), bool)
    mask[0, [1, 4]] = mask[2, :] = mask[3, 5] = True
    part, _, n_part = sdm_limits(structs, TOOL, COND, ALUMINIUM_7075, rpm, start_m=start,
                                 solve=mask)  # fmt: skip
    np.testing.assert_array_equal(part[mask], full[mask])  # each pair is solved on its own
    assert np.all(np.isnan(part[~mask]))
    assert np.all(n_part[~mask] == 0) and np.all(n_part[mask] == n_full[mask])
    with pytest.raises(ValueError, match="start_m"):
        sdm_limits(structs, TOOL, COND, ALUMINIUM_7075, rpm, solve=mask)


@pytest.mark.parametrize("estimator", ["coarse-sdm", "zoa"])
def test_compiled_fast_route_quantiles_match_per_sample_dense_sdm(estimator):
    rpm = np.linspace(100.0, 3000.0, 20)  # low speeds: flip windows, heavily damped y mode
    kw = dict(n_samples=20, rng=3, method_error=False, fit_bias=0.0)
    ref = stability_probability(DIST, TOOL, COND, ALUMINIUM_7075, rpm, solver="numpy",
                                warm_start=False, warm_from_mean=False, **kw)  # fmt: skip
    fast = stability_probability(DIST, TOOL, COND, ALUMINIUM_7075, rpm, exact=False,
                                 fast_estimator=estimator, **kw)  # fmt: skip
    assert fast.settings["route"] == "fast" and fast.settings["solver"] == "compiled"
    info = fast.settings["estimate_error"]
    assert info["evaluations_per_solved_pair"] > 1 and info["rounds"] >= 1
    for q in (0.05, 0.5, 0.95):
        np.testing.assert_allclose(fast.depth_quantile_m(q), ref.depth_quantile_m(q), rtol=0.01)
    # The NumPy fast route gives the same chart (same estimates, same pairs solved).
    slow = stability_probability(DIST, TOOL, COND, ALUMINIUM_7075, rpm[12:], exact=False,
                                 fast_estimator=estimator, solver="numpy", **kw)  # fmt: skip
    assert slow.settings["solver"] == "numpy"
    fast_hi = stability_probability(DIST, TOOL, COND, ALUMINIUM_7075, rpm[12:], exact=False,
                                    fast_estimator=estimator, **kw)  # fmt: skip
    for q in (0.05, 0.5, 0.95):
        np.testing.assert_allclose(fast_hi.depth_quantile_m(q), slow.depth_quantile_m(q),
                                   rtol=2e-3)  # fmt: skip


def test_fast_route_finds_the_narrow_window_of_the_chapter3_chart():
    # The shipped chapter-3 model near 406 rpm (200-speed chart's speeds 17-25): samples with a
    # narrow unstable window below a stable pocket, which a scan starting near a too-high
    # estimate would step over.
    from robovib.gp.chapter3_model import load_chapter3_predictor
    from robovib.milling.chart import cutting_setup
    from robovib.milling.uncertainty import mode_distribution_at_pose

    tool, cond, coef = cutting_setup(ALUMINIUM_7075, diameter_m=0.0254, n_flutes=2,
                                     helix_deg=30.0, radial_depth_m=6e-3)  # fmt: skip
    dist = mode_distribution_at_pose(load_chapter3_predictor(), (2400, 0, 45))
    rpm = np.linspace(100.0, 3000.0, 200)[17:26]
    kw = dict(n_samples=100, rng=0, method_error=False, fit_bias=0.0)
    ref = stability_probability(dist, tool, cond, coef, rpm, solver="numpy", **kw)
    fast = stability_probability(dist, tool, cond, coef, rpm, exact=False, **kw)
    assert fast.settings["estimate_error"]["solved_exactly"] < 0.8  # not everything solved
    for q in (0.05, 0.5, 0.95):
        np.testing.assert_allclose(fast.depth_quantile_m(q), ref.depth_quantile_m(q), rtol=0.01)
    # The lowest 5 % at every speed (where a window puts a sample) are exact SDM values.
    low = ref.a_lim_samples_m <= ref.depth_quantile_m(0.05)[None, :]
    np.testing.assert_allclose(fast.a_lim_samples_m[low], ref.a_lim_samples_m[low], rtol=2e-3)


def _truth_and_setup(n=20, nj=8):
    structs = _structures(n, 7)
    rpm = np.linspace(1200.0, 2600.0, nj)
    mean = [([ModalParameters(16.4, 4.19e6, 0.11)], [ModalParameters(8.49, 9.38e5, 0.19)])]
    a_mean = sdm_limits(mean, TOOL, COND, ALUMINIUM_7075, rpm)[0][0]
    opts = {"scan_from_m": _scan_start(rpm, a_mean)}
    truth = sdm_limits(structs, TOOL, COND, ALUMINIUM_7075, rpm, start_m=opts["scan_from_m"])[0]
    feed_s, norm_s = [s[0] for s in structs], [s[1] for s in structs]
    return truth, feed_s, norm_s, rpm, opts


def test_band_follows_the_estimate_error_and_falls_back_where_it_is_gross():
    truth, feed_s, norm_s, rpm, opts = _truth_and_setup()
    n, nj = truth.shape
    gen = np.random.default_rng(1)
    est = truth * (1 + 0.002 * gen.uniform(-1, 1, truth.shape))  # a good estimate ...
    j0 = 2
    est[:, j0] = truth[:, j0] * (1 + 0.3 * gen.uniform(-1, 1, n))  # ... but at one speed
    # A planted missed window at a far speed: a sample estimated on top (a stable pocket) whose
    # true limit is the lowest of all.
    j1, k = 6, int(np.argmin(truth[:, 6]))
    est[k, j1] = 1.6 * np.max(truth[:, j1])
    a, exact, err, counts = _refine_at_ranks(est, feed_s, norm_s, TOOL, COND, ALUMINIUM_7075,
                                             rpm, (0.05, 0.5, 0.95), 0.01, 8, opts,
                                             np.zeros(nj, bool), compiled=True)  # fmt: skip
    # The gross error at j0 was measured on the samples near the ranks: every sample solved
    # there and at both neighbours (the band would exceed FAST_MAX_ESTIMATE_ERROR).
    assert np.max(err) > FAST_MAX_ESTIMATE_ERROR
    assert exact[:, j0 - 1 : j0 + 2].all()
    np.testing.assert_allclose(a[:, j0], truth[:, j0], rtol=2e-3)
    # Where the estimate is good, not every sample is solved, and yet the quantiles are exact.
    assert not exact[:, 0].all() and not exact[:, 4].all()
    for q in (0.05, 0.5, 0.95):
        got = np.quantile(a, q, axis=0, method="nearest")
        np.testing.assert_allclose(got, np.quantile(truth, q, axis=0, method="nearest"),
                                   rtol=2e-3)  # fmt: skip
    # The planted sample sat beyond the 95 % rank by its estimate: solved, its error seen, so
    # every sample solved there and at the neighbouring speeds.
    assert exact[k, j1] and exact[:, j1 - 1 :].all()
    np.testing.assert_allclose(a[k, j1], truth[k, j1], rtol=2e-3)
    assert counts["rounds"] >= 1 and sum(counts["pairs_per_round"]) == int(exact.sum())
