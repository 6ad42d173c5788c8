"""Semi-discretization against closed forms, SciPy, quadrature and the zero-order method."""

import math

import numpy as np
import pytest
from scipy.linalg import expm

from robovib.milling import ALUMINIUM_7075, CuttingCoefficients, CuttingConditions, MillingTool
from robovib.milling.lobes import LobeEnvelope, zoa_envelope
from robovib.milling.sdm import (
    batched_expm,
    critical_depths,
    dominant_eigenvalues,
    floquet_multipliers,
    milling_force_matrices,
    sdm_lobes,
    semi_discretization_multipliers,
    turning_minimum_depth,
)
from robovib.milling.stability import directional_coefficients, stability_lobes
from robovib.modal import ModalParameters

# Insperger & Stépán's 1-DOF benchmark (2 teeth, down-milling, a/D = 0.05).
BENCH_MODE = ModalParameters(922.0, 1.34e6, 0.011)
BENCH_TOOL = MillingTool(diameter_m=0.02, n_flutes=2, helix_deg=0.0)
BENCH_COND = CuttingConditions(5000, 1e-4, 1e-3, 0.05 * 0.02, down_milling=True)
BENCH_COEF = CuttingCoefficients(ktc=6e8, krc=2e8, kac=0.0)


def test_batched_expm_matches_scipy():
    rng = np.random.default_rng(0)
    a = rng.normal(size=(40, 7, 7)) * rng.uniform(1e-3, 40, size=(40, 1, 1))
    ref = expm(a)
    err = np.abs(batched_expm(a) - ref).max(axis=(1, 2)) / np.abs(ref).max(axis=(1, 2))
    assert err.max() < 1e-10
    with pytest.raises(ValueError, match="square"):
        batched_expm(np.zeros((3, 2, 4)))


@pytest.mark.parametrize(
    ("n_flutes", "ratio", "down"), [(2, 1.0, True), (3, 0.3, False), (4, 0.1, True)]
)
def test_force_matrices_average_to_altintas_directional_factors(n_flutes, ratio, down):
    tool = MillingTool(diameter_m=0.02, n_flutes=n_flutes, helix_deg=0.0)
    cond = CuttingConditions(5000, 1e-4, 1e-3, ratio * 0.02, down_milling=down)
    from robovib.milling import engagement_angles

    st, ex = engagement_angles(tool, cond)
    h, frac = milling_force_matrices(n_flutes, st, ex, ALUMINIUM_7075, 17)
    assert frac.sum() == pytest.approx(1.0)
    mean = np.einsum("i,ijk->jk", frac, h)
    axx, axy, ayx, ayy = directional_coefficients(st, ex, ALUMINIUM_7075.krc / ALUMINIUM_7075.ktc)
    expected = -n_flutes * ALUMINIUM_7075.ktc / (4 * math.pi) * np.array([[axx, axy], [ayx, ayy]])
    np.testing.assert_allclose(mean, expected, rtol=1e-10, atol=1e-6 * ALUMINIUM_7075.ktc)
    # (h = -K_t A(phi) / 2 with Altintas A, alpha its integral.) Each step average vs fine midpoint quadrature of H(phi) summed over the flutes.
    kt, kn = ALUMINIUM_7075.ktc, ALUMINIUM_7075.krc
    edges = np.concatenate([[0.0], np.cumsum(frac)]) * 2 * math.pi / n_flutes
    start = st if frac.size > 17 else 0.0
    for i in (0, 5, 16):
        q = (
            start
            + np.linspace(edges[i], edges[i + 1], 20001)[:-1]
            + (edges[i + 1] - edges[i]) / 40002
        )
        tot = np.zeros((2, 2))
        for j in range(n_flutes):
            p = (q + 2 * math.pi * j / n_flutes) % (2 * math.pi)
            g = (p >= st) & (p <= ex)
            s, c = np.sin(p), np.cos(p)
            tot += np.array(
                [[np.mean(g * s * (kt * c + kn * s)), np.mean(g * c * (kt * c + kn * s))],
                 [np.mean(g * s * (-kt * s + kn * c)), np.mean(g * c * (-kt * s + kn * c))]]
            )  # fmt: skip
        np.testing.assert_allclose(h[i], tot, atol=2e-4 * kt)


def _turning_boundary(mode, h, delays, n_w=200000):
    """Exact lobes of m x'' + c x' + k x = -a h (x - x(t - tau)): a(w) and tau_k(w), envelope."""
    w = np.linspace(mode.omega_n * 1.0001, mode.omega_n * 3, n_w)
    g = 1 / (mode.stiffness_n_per_m - mode.mass_kg * w**2 + 1j * mode.damping_ns_per_m * w)
    a = -1 / (2 * h * g.real)
    out = np.full(delays.size, np.inf)
    for k in range(40):
        tau = (3 * math.pi + 2 * np.angle(g) + 2 * math.pi * k) / w
        order = np.argsort(tau)
        inside = (delays >= tau.min()) & (delays <= tau.max())
        out[inside] = np.minimum(out[inside], np.interp(delays[inside], tau[order], a[order]))
    return out


@pytest.mark.parametrize("eigensolver", ["arnoldi", "dense"])
def test_turning_limit_closed_form_and_lobes(eigensolver):
    mode = ModalParameters(150.0, 2e7, 0.025)
    h = 8e8
    m = 80
    hmat = np.zeros((m, 2, 2))
    hmat[:, 1, 1] = h
    frac = np.full(m, 1 / m)
    delays = np.geomspace(0.6 / 150, 5 / 150, 60)
    a_lim, mu = critical_depths([], [mode], hmat, frac, delays, eigensolver=eigensolver)
    a_min = turning_minimum_depth(mode, h)
    assert a_min == pytest.approx(2 * 2e7 * 0.025 * 1.025 / h)
    assert np.min(a_lim) == pytest.approx(a_min, rel=0.01)
    assert np.all(a_lim >= a_min * (1 - 1e-3))
    exact = _turning_boundary(mode, h, delays)
    np.testing.assert_allclose(a_lim, exact, rtol=0.03)  # worst at the lobe cusps
    assert np.median(np.abs(a_lim / exact - 1)) < 0.003
    np.testing.assert_allclose(np.abs(mu), 1.0, atol=0.01)
    # x direction works the same as y.
    hx = np.zeros((m, 2, 2))
    hx[:, 0, 0] = h
    ax, _ = critical_depths([mode], [], hx, frac, delays[:5], eigensolver=eigensolver)
    ay, _ = critical_depths([], [mode], hmat, frac, delays[:5], eigensolver=eigensolver)
    np.testing.assert_allclose(ax, ay, rtol=1e-6)
    # The warm-started search (default) and the scan at every delay agree to the tolerance.
    cold, _ = critical_depths([], [mode], hmat, frac, delays, eigensolver=eigensolver,
                              warm_start=False)  # fmt: skip
    np.testing.assert_allclose(a_lim, cold, rtol=2e-3)
    np.testing.assert_allclose(cold, exact, rtol=0.03)


def test_dominant_eigenvalues_match_numpy_and_fall_back_when_unconverged():
    rng = np.random.default_rng(4)
    n = 60
    # A dominant complex pair and a real multiplier over a cloud near zero (as a monodromy).
    q, _ = np.linalg.qr(rng.normal(size=(n, n)))
    lam = np.concatenate(
        [[0.9 * np.exp(0.7j), 0.9 * np.exp(-0.7j), -0.6], 0.05 * rng.normal(size=n - 3)]
    )
    blocks = np.diag(lam.real)
    blocks[0, 0] = blocks[1, 1] = lam[0].real
    blocks[0, 1], blocks[1, 0] = lam[0].imag, -lam[0].imag
    a = q @ blocks @ np.linalg.inv(q)
    # ... and a matrix with no gap at all (random orthogonal: every |mu| = 1) -> dense fallback.
    stack = np.stack([a, np.linalg.qr(rng.normal(size=(n, n)))[0]])
    got = dominant_eigenvalues(stack, 3)
    ref = np.linalg.eigvals(stack)
    ref = np.take_along_axis(ref, np.argsort(-np.abs(ref), axis=1)[:, :3], axis=1)
    np.testing.assert_allclose(
        np.sort(np.abs(got), axis=1), np.sort(np.abs(ref), axis=1), rtol=1e-9
    )
    np.testing.assert_allclose(np.sort_complex(got[0]), np.sort_complex(ref[0]), atol=1e-9)
    assert np.abs(got[0, 0]) == pytest.approx(0.9, rel=1e-9)


def test_arnoldi_chart_equals_dense_sdm_on_robot_modes():
    """Issue 27: a 2-DOF chart with the robot's low modes (fn 16 and 8.5 Hz, 40 speeds, the
    low ones needing long delays) by Arnoldi iterations equals the dense-eigenvalue SDM."""
    mx, my = ModalParameters(16.4, 4.19e6, 0.114), ModalParameters(8.49, 9.38e5, 0.191)
    tool = MillingTool(diameter_m=0.0254, n_flutes=2, helix_deg=30.0)
    cond = CuttingConditions(1750.0, 1e-4, 1e-3, 6e-3)
    rpm = np.linspace(100, 3000, 40)
    fast = sdm_lobes([mx], [my], tool, cond, ALUMINIUM_7075, rpm)
    dense = sdm_lobes([mx], [my], tool, cond, ALUMINIUM_7075, rpm, eigensolver="dense")
    np.testing.assert_allclose(fast.a_lim_m, dense.a_lim_m, rtol=1e-7)
    assert list(fast.kind) == list(dense.kind)
    assert fast.settings["eigensolver"] == "arnoldi"
    with pytest.raises(ValueError, match="eigensolver"):
        sdm_lobes([mx], [my], tool, cond, ALUMINIUM_7075, rpm[:2], eigensolver="qr")


def test_sdm_agrees_with_zero_order_at_full_immersion():
    mx, my = ModalParameters(600, 5e6, 0.03), ModalParameters(660, 6e6, 0.03)
    tool = MillingTool(diameter_m=0.02, n_flutes=4, helix_deg=0.0)
    cond = CuttingConditions(5000, 1e-4, 1e-3, 0.02)
    rpm = np.linspace(2500, 10000, 40)
    sdm = sdm_lobes([mx], [my], tool, cond, ALUMINIUM_7075, rpm)
    zoa = zoa_envelope(stability_lobes([mx], [my], tool, cond, ALUMINIUM_7075, n_lobes=20), rpm)
    ratio = sdm.a_lim_m / zoa.a_lim_m
    assert np.all(np.abs(ratio - 1) < 0.05), ratio
    assert sdm.minimum_depth_m == pytest.approx(zoa.minimum_depth_m, rel=0.01)
    assert set(sdm.kind) == {"hopf"}
    # Chatter near the modes, as the zero-order method says (ambiguous at a few lobe cusps).
    close = np.abs(sdm.chatter_hz / zoa.chatter_hz - 1) < 0.03
    assert close.mean() > 0.85


def test_sdm_converges_at_second_order_in_steps_per_period():
    mx, my = ModalParameters(600, 5e6, 0.03), ModalParameters(660, 6e6, 0.03)
    tool = MillingTool(diameter_m=0.02, n_flutes=4, helix_deg=0.0)
    cond = CuttingConditions(5000, 1e-4, 1e-3, 0.012, down_milling=False)
    rpm = np.array([6000.0, 8000.0, 9000.0])
    a = {m: sdm_lobes([mx], [my], tool, cond, ALUMINIUM_7075, rpm, steps_per_period=m,
                    steps_per_vibration=0).a_lim_m
         for m in (10, 20, 40, 160)}  # fmt: skip
    e10, e20, e40 = (np.abs(a[m] - a[160]) for m in (10, 20, 40))
    assert np.all(e40 < e20) and np.all(e20 < e10)
    assert np.all(e20 / e40 > 3.0)  # ~4 for second order
    assert np.all(e40 / a[160] < 0.01)


def test_benchmark_flip_lobes_that_zero_order_misses():
    rpm = np.linspace(5000, 25000, 60)
    sdm = sdm_lobes([BENCH_MODE], [], BENCH_TOOL, BENCH_COND, BENCH_COEF, rpm)
    zoa = zoa_envelope(
        stability_lobes([BENCH_MODE], [], BENCH_TOOL, BENCH_COND, BENCH_COEF, n_lobes=30), rpm
    )
    flip = sdm.kind == "flip"
    assert flip.sum() >= 5
    # Flip: the critical multiplier crosses at -1, chatter at odd halves of tooth passing.
    mu = floquet_multipliers([BENCH_MODE], [], BENCH_TOOL, BENCH_COND, BENCH_COEF,
                             rpm[flip], sdm.a_lim_m[flip] * 1.001)  # fmt: skip
    assert np.all(np.abs(mu) >= 1) and np.all(mu.real < 0) and np.all(np.abs(mu.imag) < 1e-6)
    tpf = rpm[flip] * 2 / 60
    half = sdm.chatter_hz[flip] / tpf - 0.5
    np.testing.assert_allclose(half, np.round(half), atol=1e-6)
    # The zero-order method has no period-doubling lobes: it overestimates the limit there.
    assert np.max(zoa.a_lim_m[flip] / sdm.a_lim_m[flip]) > 1.5
    hopf = sdm.kind == "hopf"
    # Away from the flip lobes both methods see the same Hopf lobes (within 25 %).
    assert np.median(np.abs(zoa.a_lim_m[hopf] / sdm.a_lim_m[hopf] - 1)) < 0.25


def test_sdm_multi_mode_and_bad_input():
    tool = MillingTool(diameter_m=0.02, n_flutes=3, helix_deg=0.0)
    cond = CuttingConditions(5000, 1e-4, 1e-3, 0.005)
    modes = [ModalParameters(500, 8e6, 0.04), ModalParameters(900, 2e7, 0.02)]
    env = sdm_lobes(modes, modes[:1], tool, cond, ALUMINIUM_7075, [4000.0, 9000.0])
    assert isinstance(env, LobeEnvelope) and np.all(np.isfinite(env.a_lim_m))
    with pytest.raises(ValueError, match="rpm"):
        sdm_lobes(modes, [], tool, cond, ALUMINIUM_7075, [np.nan])
    with pytest.raises(ValueError, match="at least one mode"):
        sdm_lobes([], [], tool, cond, ALUMINIUM_7075, [4000.0])
    with pytest.raises(ValueError, match="depth_m"):
        semi_discretization_multipliers(
            modes, [], np.zeros((4, 2, 2)), np.full(4, 0.25), 0.01, -1.0
        )
    with pytest.raises(ValueError, match="fraction"):
        semi_discretization_multipliers(modes, [], np.zeros((4, 2, 2)), np.full(4, 0.3), 0.01, 1e-3)


def _growth_rates(mode, tool, phi_st, phi_ex, coef, rpm, depths, *, n_step=480, periods=70):
    """Independent reference: growth rate per tooth period of the linear regenerative DDE.

    ``m x'' + c x' + k x = -a h(t) (x(t) - x(t - tau))`` (feed direction only, ``h`` the
    instantaneous specific force of the engaged flutes) integrated by classical RK4 with
    ``n_step`` steps per delay (delayed values at half steps by linear interpolation), for all
    depths at once, from a generic initial history; the rate is log(peak late / peak early)
    per period: > 0 where the cut chatters. Nothing of the semi-discretization is used.
    """
    tau = 60.0 / (tool.n_flutes * rpm)
    dt = tau / n_step
    wn, z, m = mode.omega_n, mode.damping_ratio, mode.mass_kg
    kt, kn = coef.ktc, coef.krc
    pitch = 2 * math.pi / tool.n_flutes

    def h_of(t):
        out = 0.0
        for j in range(tool.n_flutes):
            phi = (2 * math.pi * rpm / 60 * t + j * pitch) % (2 * math.pi)
            if phi_st <= phi <= phi_ex:
                s, c = math.sin(phi), math.cos(phi)
                out += s * (kt * c + kn * s)
        return out

    a = np.asarray(depths, float)
    hist = [np.cos(0.37 * i) * 1e-6 + np.zeros_like(a) for i in range(n_step + 1)]
    x, v = hist[-1].copy(), np.zeros_like(a)
    peaks = []
    for p in range(periods):
        peak = np.zeros_like(a)
        new = [x.copy()]
        for i in range(n_step):
            t = (p * n_step + i) * dt
            d0, d1 = hist[i], hist[i + 1]
            dh = 0.5 * (d0 + d1)

            def f(xx, vv, tt, dd):
                acc = -(wn**2) * xx - 2 * z * wn * vv - a * h_of(tt) / m * (xx - dd)
                return vv, acc

            k1 = f(x, v, t, d0)
            k2 = f(x + 0.5 * dt * k1[0], v + 0.5 * dt * k1[1], t + 0.5 * dt, dh)
            k3 = f(x + 0.5 * dt * k2[0], v + 0.5 * dt * k2[1], t + 0.5 * dt, dh)
            k4 = f(x + dt * k3[0], v + dt * k3[1], t + dt, d1)
            x = x + dt / 6 * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0])
            v = v + dt / 6 * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1])
            new.append(x.copy())
            peak = np.maximum(peak, np.abs(x))
        hist = new
        peaks.append(peak)
    late = np.max(peaks[-10:], axis=0)
    early = np.max(peaks[-40:-30], axis=0)
    return np.log(late / early) / 30


def test_lowest_unstable_depth_below_a_stable_pocket_against_a_time_domain_growth_rate():
    # Up-milling at a/D = 0.05: flip lenses lie below the Hopf lobe, so at 11,390 rpm the cut
    # chatters from ~1.9 mm, is stable again in a pocket, and chatters above ~5.3 mm. The
    # depth search must report the lower edge (issue 36 item 4: it reported the upper one).
    from robovib.milling.forces import engagement_angles

    cond = CuttingConditions(10000, 1e-4, 1e-3, 0.05 * 0.02, down_milling=False)
    phi_st, phi_ex = engagement_angles(BENCH_TOOL, cond)
    rpm = np.linspace(5000, 25000, 120)[[38, 39]]  # 11387, 11555 rpm: windows at both
    env = sdm_lobes([BENCH_MODE], [], BENCH_TOOL, cond, BENCH_COEF, rpm)
    depths = np.geomspace(1.2e-3, 8e-3, 48)
    for speed, a_lim in zip(rpm, env.a_lim_m, strict=True):
        rate = _growth_rates(BENCH_MODE, BENCH_TOOL, phi_st, phi_ex, BENCH_COEF, speed, depths)
        unstable = rate > 0
        lowest = depths[np.argmax(unstable)]
        # The case has a window: unstable, then stable again, then unstable (reference only).
        runs = np.flatnonzero(np.diff(unstable.astype(int)))
        assert unstable.any() and runs.size >= 2, (speed, unstable.astype(int))
        step = depths[1] / depths[0]
        assert lowest / step**1.5 <= a_lim <= lowest * step**0.5, (speed, a_lim, lowest)
        # The envelope and the growth rate agree on both sides of the reported limit.
        assert np.all(rate[depths < a_lim / step] < 0)
