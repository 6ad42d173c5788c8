"""The compiled semi-discretization against LAPACK, SciPy's expm, a closed form and the NumPy SDM."""

import math

import numpy as np
import pytest
from scipy.linalg import expm

from robovib.milling import ALUMINIUM_7075, CuttingConditions, MillingTool
from robovib.milling.sdm import critical_depths, sdm_lobes, turning_minimum_depth
from robovib.milling.sdm_kernel import (
    critical_depths_pairs,
    hessenberg_eigenvalues,
    sdm_envelopes,
    sdm_limits,
    step_matrices,
)
from robovib.milling.uncertainty import ModeDistribution, stability_probability
from robovib.modal import ModalParameters

TOOL = MillingTool(diameter_m=0.0254, n_flutes=2, helix_deg=30.0)
COND = CuttingConditions(2000.0, 1e-4, 1e-3, 6e-3, down_milling=True)


def test_hessenberg_eigenvalues_match_lapack():
    rng = np.random.default_rng(0)
    for trial in range(300):
        k = int(rng.integers(2, 16))
        a = np.triu(rng.normal(size=(k, k)), -1) * 10.0 ** rng.uniform(-4, 4)
        wr, wi = np.empty(k), np.empty(k)
        assert hessenberg_eigenvalues(a.copy(), k, wr, wi), trial
        ref = np.sort_complex(np.linalg.eigvals(a))
        got = np.sort_complex(wr + 1j * wi)
        assert np.max(np.abs(got - ref)) <= 1e-10 * np.max(np.abs(ref))


@pytest.mark.parametrize("h", [1e-4, 3e-3, 0.2])  # no halving, a few, many (free flight)
def test_step_matrices_match_the_van_loan_exponential(h):
    rng = np.random.default_rng(1)
    n = 3
    d = 2 * n
    wq = rng.uniform(50, 400, n)
    zq = -2 * rng.uniform(0.01, 0.2, n) * wq
    q = -np.diag(wq) - rng.uniform(0, 100, (n, n))
    amat = np.zeros((d, d))
    amat[:n, n:] = np.diag(wq)
    amat[n:, :n] = q
    amat[n:, n:] = np.diag(zq)
    e, r, s = np.zeros((d, d)), np.zeros((d, d)), np.zeros((d, d))
    step_matrices(wq, zq, q, h, n, e, r, s, np.zeros((9, d, d)))
    # Van Loan: exp([[A, I, 0], [0, 0, I/h], [0, 0, 0]] h) holds E, int e^{A(h-s)} ds and
    # int e^{A(h-s)} s/h ds.
    big = np.zeros((3 * d, 3 * d))
    big[:d, :d] = amat
    big[:d, d : 2 * d] = np.eye(d)
    big[d : 2 * d, 2 * d :] = np.eye(d) / h
    ref = expm(big * h)
    scale = np.abs(ref[:d]).max()
    np.testing.assert_allclose(e, ref[:d, :d], atol=1e-11 * scale)
    np.testing.assert_allclose(r, ref[:d, d : 2 * d], atol=1e-11 * scale)
    np.testing.assert_allclose(s, ref[:d, 2 * d :], atol=1e-11 * scale)


def test_turning_limit_closed_form_and_numpy_path():
    # A cut over the whole period (no free flight): the limit's minimum over the delays is the
    # closed-form 1-DOF turning limit 2 k zeta (1 + zeta) / h.
    mode = ModalParameters(150.0, 2e7, 0.025)
    h, m = 8e8, 60
    hmat = np.zeros((m, 2, 2))
    hmat[:, 1, 1] = h
    frac = np.full(m, 1 / m)
    delays = np.geomspace(0.6 / 150, 5 / 150, 60)
    p = delays.size
    a, mu, counts = critical_depths_pairs(
        np.full((p, 1), mode.omega_n), np.full((p, 1), mode.damping_ratio),
        np.full((p, 1), mode.mass_kg), 0, hmat, delays[:, None] * frac[None, :],
        np.full(p, np.nan), (1e-5, 1.0),
    )  # fmt: skip
    a_min = turning_minimum_depth(mode, h)
    assert np.min(a) == pytest.approx(a_min, rel=0.01)
    assert np.all(a >= a_min * (1 - 1e-3))
    np.testing.assert_allclose(np.abs(mu), 1.0, atol=0.01)
    ref, _ = critical_depths([], [mode], hmat, frac, delays, depth_range_m=(1e-5, 1.0),
                             warm_start=False, eigensolver="dense")  # fmt: skip
    np.testing.assert_allclose(a, ref, rtol=1.5e-3)
    assert np.all(counts["evaluations"] > 0)


@pytest.mark.parametrize(
    ("modes_x", "modes_y"),
    [
        ([ModalParameters(16.4, 4.19e6, 0.11)], [ModalParameters(8.49, 9.38e5, 0.19)]),
        (  # several modes per direction: the delayed state holds only x and y
            [ModalParameters(16.4, 4.2e6, 0.11), ModalParameters(63.5, 4.2e7, 0.04)],
            [ModalParameters(8.5, 9.4e5, 0.19), ModalParameters(21.9, 1.0e7, 0.06)],
        ),
    ],
)
def test_envelopes_match_dense_numpy_sdm(modes_x, modes_y):
    # Low speeds need more than 40 steps (steps_per_vibration) for the 63.5 Hz mode.
    rpm = np.array([100.0, 230.0, 480.0, 900.0, 1400.0, 2100.0, 3000.0])
    ref = sdm_lobes(modes_x, modes_y, TOOL, COND, ALUMINIUM_7075, rpm, warm_start=False,
                    eigensolver="dense")  # fmt: skip
    (env,) = sdm_envelopes([(modes_x, modes_y)], TOOL, COND, ALUMINIUM_7075, rpm,
                           warm_start=False)  # fmt: skip
    np.testing.assert_allclose(env.a_lim_m, ref.a_lim_m, rtol=1.5e-3)
    assert list(env.kind) == list(ref.kind)
    np.testing.assert_allclose(env.chatter_hz, ref.chatter_hz, rtol=0.02)
    # The warm start (the default) finds the same lowest unstable depths.
    (warm,) = sdm_envelopes([(modes_x, modes_y)], TOOL, COND, ALUMINIUM_7075, rpm)
    np.testing.assert_allclose(warm.a_lim_m, ref.a_lim_m, rtol=1.5e-3)


def test_sdm_limits_refuses_bad_input():
    mx, my = [ModalParameters(16.4, 4.19e6, 0.11)], [ModalParameters(8.49, 9.38e5, 0.19)]
    with pytest.raises(ValueError, match="positive speeds"):
        sdm_limits([(mx, my)], TOOL, COND, ALUMINIUM_7075, [1000.0, -5.0])
    with pytest.raises(ValueError, match="not available"):
        sdm_envelopes([(mx, my)], TOOL, COND, ALUMINIUM_7075, [1000.0], eigensolver="dense")
    with pytest.raises(ValueError, match="solver"):
        dist = {
            "x": ModeDistribution(16.4, 4.19e6, 9270.0),
            "y": ModeDistribution(8.49, 9.38e5, 6730.0),
        }
        stability_probability(dist, TOOL, COND, ALUMINIUM_7075, [1000.0], solver="cuda")


def test_stability_probability_compiled_matches_per_sample_dense_sdm():
    dist = {
        "x": ModeDistribution(16.4, 4.19e6, 9270.0, 0.04 * 16.4, 0.07 * 4.19e6, 0.03 * 9270.0),
        "y": ModeDistribution(8.49, 9.38e5, 6730.0, 0.04 * 8.49, 0.08 * 9.38e5, 0.05 * 6730.0),
    }
    rpm = np.linspace(100.0, 3000.0, 20)  # coarse: the flip windows move between speeds
    kw = dict(n_samples=8, rng=3, method_error=False, fit_bias=0.0)
    fast = stability_probability(dist, TOOL, COND, ALUMINIUM_7075, rpm, **kw)
    assert fast.settings["solver"] == "compiled"
    # The reference: every sample by the NumPy SDM from the bottom of the range.
    gen_free = stability_probability(dist, TOOL, COND, ALUMINIUM_7075, rpm, solver="numpy",
                                     warm_start=False, warm_from_mean=False, **kw)  # fmt: skip
    assert gen_free.settings["solver"] == "numpy"
    ratio = fast.a_lim_samples_m / gen_free.a_lim_samples_m
    assert np.nanmax(np.abs(ratio - 1)) < 2e-3
    for q in (0.05, 0.5, 0.95):
        np.testing.assert_allclose(fast.depth_quantile_m(q), gen_free.depth_quantile_m(q),
                                   rtol=2e-3)  # fmt: skip
    assert math.isclose(fast.mean.minimum_depth_m, gen_free.mean.minimum_depth_m, rel_tol=2e-3)


def test_coarse_steps_with_the_mean_ratio_keep_the_quantiles():
    dist = {
        "x": ModeDistribution(16.4, 4.19e6, 9270.0, 0.04 * 16.4, 0.07 * 4.19e6, 0.03 * 9270.0),
        "y": ModeDistribution(8.49, 9.38e5, 6730.0, 0.04 * 8.49, 0.08 * 9.38e5, 0.05 * 6730.0),
    }
    rpm = np.linspace(600.0, 3000.0, 16)
    kw = dict(n_samples=8, rng=5, method_error=False, fit_bias=0.0)
    ref = stability_probability(dist, TOOL, COND, ALUMINIUM_7075, rpm, solver="numpy",
                                warm_start=False, warm_from_mean=False, **kw)  # fmt: skip
    coarse = stability_probability(dist, TOOL, COND, ALUMINIUM_7075, rpm,
                                   coarse_tolerance=2e-3, **kw)  # fmt: skip
    assert coarse.settings["coarse"]["coarse_speeds"] > 0.5  # most speeds solved coarse
    for q in (0.05, 0.5, 0.95):
        np.testing.assert_allclose(coarse.depth_quantile_m(q), ref.depth_quantile_m(q),
                                   rtol=5e-3)  # fmt: skip
    with pytest.raises(ValueError, match="coarse_tolerance"):
        stability_probability(dist, TOOL, COND, ALUMINIUM_7075, rpm, coarse_tolerance=0.5, **kw)


def test_compiled_scan_uses_the_numpy_depth_grid_and_finds_its_windows():
    # The shipped chapter-3 model near 406 rpm: one of 100 samples has a narrow unstable
    # window at 6.4 mm below a stable pocket; a scan on lo * 1.2^k (instead of the reference's
    # geomspace grid) stepped over it and reported 7.8 mm.
    from robovib.gp.chapter3_model import load_chapter3_predictor
    from robovib.milling.chart import cutting_setup
    from robovib.milling.uncertainty import mode_distribution_at_pose

    tool, cond, coef = cutting_setup(ALUMINIUM_7075, diameter_m=0.0254, n_flutes=2,
                                     helix_deg=30.0, radial_depth_m=6e-3)  # fmt: skip
    dist = mode_distribution_at_pose(load_chapter3_predictor(), (2400, 0, 45))
    rpm = np.linspace(100.0, 3000.0, 200)[17:26]
    kw = dict(n_samples=100, rng=0, method_error=False, fit_bias=0.0)
    fast = stability_probability(dist, tool, cond, coef, rpm, **kw).a_lim_samples_m
    ref = stability_probability(dist, tool, cond, coef, rpm, solver="numpy", **kw)
    np.testing.assert_allclose(fast, ref.a_lim_samples_m, rtol=2e-3)


def test_without_a_compiler_the_numpy_path_gives_the_same_chart(monkeypatch):
    """numba missing or NUMBA_DISABLE_JIT=1 (AVAILABLE False): the NumPy SDM, not an interpreted
    kernel; the result equals an explicit ``solver="numpy"`` run bit for bit."""
    import robovib.milling.sdm_kernel as kernel

    dist = {
        "x": ModeDistribution(16.4, 4.19e6, 9270.0, 0.04 * 16.4, 0.07 * 4.19e6, 0.03 * 9270.0),
        "y": ModeDistribution(8.49, 9.38e5, 6730.0, 0.04 * 8.49, 0.08 * 9.38e5, 0.05 * 6730.0),
    }
    rpm = np.linspace(1000.0, 3000.0, 6)
    kw = dict(n_samples=4, rng=5, method_error=False, fit_bias=0.0)
    ref = stability_probability(dist, TOOL, COND, ALUMINIUM_7075, rpm, solver="numpy", **kw)
    monkeypatch.setattr(kernel, "AVAILABLE", False)
    fallback = stability_probability(dist, TOOL, COND, ALUMINIUM_7075, rpm, **kw)
    assert fallback.settings["solver"] == "numpy"
    np.testing.assert_array_equal(fallback.a_lim_samples_m, ref.a_lim_samples_m)


def test_the_decorator_compiles_uncached_where_numba_cannot_cache(monkeypatch):
    """A read-only install: numba refuses ``cache=True`` with a RuntimeError at decoration."""
    import numba

    import robovib.milling.sdm_kernel as kernel

    real = numba.njit
    calls = []

    def njit(*args, **kwargs):
        calls.append(kwargs.get("cache", False))
        if kwargs.get("cache"):
            raise RuntimeError("cannot cache function 'f': no locator available for file")
        return real(*args, **kwargs)

    monkeypatch.setattr(numba, "njit", njit)

    def add_one(x):
        return x + 1.0

    compiled = kernel.jit(add_one)
    assert calls == [True, False]
    assert compiled(1.5) == 2.5
