"""cross_validate(warm_start=...): folds start from the full-data hyperparameters, no restarts."""

import numpy as np
import pytest
from sklearn.model_selection import KFold

from robovib.gp import BatchedGPRegressor
from robovib.gp.validation import PolynomialRegression, cross_validate


def _data(n=40, seed=1):
    rng = np.random.default_rng(seed)
    X = rng.uniform(-1, 1, (n, 2))
    Y = np.column_stack([np.sin(2 * X[:, 0]) + X[:, 1] ** 2, np.cos(X[:, 0] * X[:, 1])])
    return X, Y + 0.01 * rng.normal(size=Y.shape)


def test_warm_start_folds_start_from_the_full_fit():
    X, Y = _data()
    gp = BatchedGPRegressor(kernel="ard", rng=0)
    warm = cross_validate(gp, X, Y, rng=3, warm_start=True)
    # reference: the same folds fitted by hand from the full-data hyperparameters
    hp = BatchedGPRegressor(kernel="ard", rng=0).fit(X, Y).hyperparameters_
    seed = int(np.random.default_rng(3).integers(2**31 - 1))
    expected = np.empty_like(Y)
    for train, test in KFold(5, shuffle=True, random_state=seed).split(X):
        m = BatchedGPRegressor(kernel="ard", rng=0, initial_hyperparameters=hp, n_restarts=0)
        expected[test] = m.fit(X[train], Y[train]).predict(X[test])
    np.testing.assert_allclose(warm.predictions, expected, rtol=1e-10, atol=1e-12)
    assert gp.initial_hyperparameters is None  # the caller's estimator is untouched
    # given hyperparameters directly: same thing
    direct = cross_validate(gp, X, Y, rng=3, warm_start=hp)
    np.testing.assert_allclose(direct.predictions, warm.predictions)
    # and the scores stay close to a cold cross-validation on smooth data
    cold = cross_validate(gp, X, Y, rng=3)
    np.testing.assert_allclose(warm.r2, cold.r2, atol=0.02)


def test_warm_start_needs_initial_hyperparameters():
    X, Y = _data(20)
    with pytest.raises(TypeError, match="initial_hyperparameters"):
        cross_validate(PolynomialRegression(2), X, Y, warm_start=True)
