"""Batched BFGS against SciPy's BFGS on independent problems with known minima."""

import numpy as np
import pytest
from scipy import optimize

from robovib.gp.optimize import batched_bfgs


def rosenbrock(theta, a):
    x, y = theta[:, 0], theta[:, 1]
    f = (a - x) ** 2 + 100 * (y - x**2) ** 2
    g = np.column_stack([-2 * (a - x) - 400 * x * (y - x**2), 200 * (y - x**2)])
    return f, g


def test_batched_bfgs_finds_rosenbrock_minima():
    a = np.array([1.0, -0.5, 2.0, 0.3])

    def fun(theta, index):
        return rosenbrock(theta, a[index])

    x0 = np.tile([-1.2, 1.0], (4, 1))
    res = batched_bfgs(fun, x0, max_iter=500, gtol=1e-8)
    np.testing.assert_allclose(res.x, np.column_stack([a, a**2]), atol=1e-5)
    assert res.converged.all()
    # Same kind of iteration counts as SciPy's BFGS on the same problems.
    for b in range(4):
        ref = optimize.minimize(
            lambda t, b=b: rosenbrock(t[None], a[b : b + 1])[0][0],
            x0[b],
            jac=lambda t, b=b: rosenbrock(t[None], a[b : b + 1])[1][0],
            method="BFGS",
        )
        np.testing.assert_allclose(res.x[b], ref.x, atol=1e-4)
        assert res.n_iter[b] < 3 * ref.nit + 10


def test_batched_bfgs_respects_bounds():
    def fun(theta, index):
        return np.sum((theta - 3.0) ** 2, axis=1), 2 * (theta - 3.0)

    res = batched_bfgs(fun, np.zeros((2, 3)), lower=-1.0, upper=np.array([1.0, 5.0, 2.0]))
    np.testing.assert_allclose(res.x, np.tile([1.0, 3.0, 2.0], (2, 1)), atol=1e-6)


def test_batched_bfgs_rejects_bad_start():
    def fun(theta, index):
        return np.full(theta.shape[0], np.nan), np.zeros_like(theta)

    with pytest.raises(ValueError, match="not finite at the starting point"):
        batched_bfgs(fun, np.zeros((2, 2)))


def test_duplicate_starts_in_one_basin_are_merged():
    """Starts of one problem that meet stop early; the kept start still reaches SciPy's optimum."""
    a = np.array([1.0, -0.5])

    x0 = np.array([[-1.2, 1.0], [-0.5, 2.0], [-1.2, 1.0001], [-1.19, 1.0]])
    label = np.array([0, 1, 0, 0])

    def fun(theta, index):
        return rosenbrock(theta, a[label[index]])

    plain = batched_bfgs(fun, x0, max_iter=500, gtol=1e-8)
    merged = batched_bfgs(fun, x0, max_iter=500, gtol=1e-8, same_problem=label)
    for b in range(2):
        ref = optimize.minimize(
            lambda t, b=b: rosenbrock(t[None], a[b : b + 1])[0][0],
            x0[b],
            jac=lambda t, b=b: rosenbrock(t[None], a[b : b + 1])[1][0],
            method="BFGS",
        )
        rows = np.flatnonzero(label == b)
        best = rows[np.argmin(merged.fun[rows])]
        np.testing.assert_allclose(merged.x[best], ref.x, atol=1e-5)
        assert merged.converged[best]
    # Rows 2 and 3 start next to row 0: stopped as duplicates, with fewer evaluations.
    assert not merged.converged[2] or not merged.converged[3]
    assert merged.n_fev[[2, 3]].sum() < plain.n_fev[[2, 3]].sum()
