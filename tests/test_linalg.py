"""robovib._linalg (NumPy only) against SciPy: matrix exponential and discrete Riccati equation."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import linalg

from robovib._linalg import batched_expm, solve_dare
from robovib.control.lqr import THESIS_Q, _delay_augmented, continuous_model, discretize
from robovib.modal import ModalParameters


@pytest.mark.oracle
def test_expm_of_one_matrix_matches_scipy():
    rng = np.random.default_rng(0)
    for scale in (1e-3, 1.0, 30.0):
        a = scale * rng.normal(size=(5, 5))
        ref = linalg.expm(a)
        np.testing.assert_allclose(batched_expm(a), ref, rtol=1e-10, atol=1e-12 * np.abs(ref).max())


@pytest.mark.oracle
def test_expm_of_a_stack_with_small_and_large_norms_matches_scipy():
    """Degree 9 below 1-norm 2.098, degree 13 with squaring above: both to SciPy's precision."""
    rng = np.random.default_rng(1)
    a = rng.normal(size=(3, 4, 6, 6)) * np.array([1e-4, 0.05, 0.3, 40.0])[None, :, None, None]
    assert (np.abs(a).sum(axis=-2).max(axis=-1) <= 2.097847961257068).any()
    got = batched_expm(a)
    for idx in np.ndindex(a.shape[:2]):
        ref = linalg.expm(a[idx])
        np.testing.assert_allclose(got[idx], ref, rtol=1e-10, atol=1e-12 * np.abs(ref).max())


def _residual(a, b, q, r, x):
    gain = np.linalg.solve(r + b.T @ x @ b, b.T @ x @ a)
    return np.max(np.abs(a.T @ x @ a - a.T @ x @ b @ gain + q - x)) / np.max(np.abs(x))


@pytest.mark.oracle
@pytest.mark.parametrize("fn_hz", [8.0, 16.4, 63.0])
@pytest.mark.parametrize("zeta", [0.02, 0.2])
@pytest.mark.parametrize("plant_input", ["displacement", "force"])
@pytest.mark.parametrize("delay_steps", [0, 8])
def test_dare_matches_scipy_on_lqr_problems(fn_hz, zeta, plant_input, delay_steps):
    """The LQR problems of robovib.control (one mode at 250 Hz, with an 8-step delay line whose
    plant matrix is singular): the same X as SciPy, and a relative residual below 1e-11."""
    a, b = continuous_model(ModalParameters(fn_hz, 4e6, zeta), input=plant_input)
    ad, bd = _delay_augmented(*discretize(a, b, 4e-3), delay_steps)
    n = ad.shape[0]
    q = np.zeros((n, n))
    q[:2, :2] = THESIS_Q
    q += 1e-12 * np.eye(n) if delay_steps else 0.0
    for r in (np.array([[1e-3]]), np.array([[1.0]])):
        ref = linalg.solve_discrete_are(ad, bd, q, r)
        x = solve_dare(ad, bd, q, r)
        np.testing.assert_allclose(x, ref, rtol=0, atol=1e-11 * np.abs(ref).max())
        np.testing.assert_array_equal(x, x.T)
        assert _residual(ad, bd, q, r, x) < 1e-11


def test_dare_kalman_dual_and_fallback():
    rng = np.random.default_rng(1)
    a = rng.normal(size=(4, 4))  # unstable open loop
    c = rng.normal(size=(2, 4))
    q, r = np.eye(4), np.diag([0.5, 2.0])
    np.testing.assert_allclose(
        solve_dare(a.T, c.T, q, r), linalg.solve_discrete_are(a.T, c.T, q, r), rtol=1e-9
    )
    # No doubling converges in one step: SciPy answers.
    np.testing.assert_allclose(
        solve_dare(a, c.T, q, r, max_iter=1), linalg.solve_discrete_are(a, c.T, q, r), rtol=1e-12
    )
