"""Cross-validation, MLR baseline and external validation against scikit-learn."""

import numpy as np
import pytest
from sklearn.linear_model import LinearRegression
from sklearn.metrics import mean_squared_error, r2_score
from sklearn.model_selection import KFold, cross_val_predict

from robovib.gp.validation import (
    PolynomialRegression,
    cross_validate,
    external_validation,
    regression_scores,
)


@pytest.mark.oracle
def test_regression_scores_match_sklearn():
    rng = np.random.default_rng(0)
    t = rng.normal(size=(40, 3))
    p = t + 0.3 * rng.normal(size=t.shape)
    r2, r2c, rmse = regression_scores(t, p)
    for b in range(3):
        assert r2[b] == pytest.approx(r2_score(t[:, b], p[:, b]))
        assert rmse[b] == pytest.approx(np.sqrt(mean_squared_error(t[:, b], p[:, b])))
        assert r2c[b] == pytest.approx(np.corrcoef(t[:, b], p[:, b])[0, 1] ** 2)


def test_polynomial_regression_recovers_quadratic():
    rng = np.random.default_rng(1)
    X = rng.uniform(-1, 1, (30, 3)) * [300, 450, 90] + [2400, 150, 90]
    y = 1.0 + 2e-3 * X[:, 0] - 3e-6 * X[:, 1] ** 2 + 1e-5 * X[:, 0] * X[:, 2]
    model = PolynomialRegression(2).fit(X, np.column_stack([y, 2 * y]))
    Xq = rng.uniform(-1, 1, (10, 3)) * [300, 450, 90] + [2400, 150, 90]
    yq = 1.0 + 2e-3 * Xq[:, 0] - 3e-6 * Xq[:, 1] ** 2 + 1e-5 * Xq[:, 0] * Xq[:, 2]
    np.testing.assert_allclose(model.predict(Xq), np.column_stack([yq, 2 * yq]), rtol=1e-8)


@pytest.mark.oracle
def test_cv_matches_sklearn_cross_val_predict():
    rng = np.random.default_rng(2)
    X = rng.normal(size=(50, 2))
    y = X @ [1.0, -2.0] + 0.1 * rng.normal(size=50)
    ours = cross_validate(PolynomialRegression(1), X, y, n_splits=5, rng=3)
    seed = int(np.random.default_rng(3).integers(2**31 - 1))
    ref = cross_val_predict(LinearRegression(), X, y, cv=KFold(5, shuffle=True, random_state=seed))
    np.testing.assert_allclose(ours.predictions[:, 0], ref, atol=1e-10)


def test_grouped_cv_keeps_groups_together():
    rng = np.random.default_rng(3)
    groups = np.repeat(np.arange(20), 3)
    X = rng.normal(size=(60, 2))
    y = X[:, 0] + rng.normal(size=60) * 0.1
    res = cross_validate(PolynomialRegression(1), X, y, pose_groups=groups, rng=0)
    assert res.grouped
    for g in range(20):
        assert np.unique(res.folds[groups == g]).size == 1
    assert np.unique(res.folds).size == 5
    with pytest.warns(DeprecationWarning, match="pose_groups"):  # the old keyword still works
        old = cross_validate(PolynomialRegression(1), X, y, groups=groups, rng=0)
    np.testing.assert_array_equal(old.folds, res.folds)


def test_cv_bad_input():
    X, y = np.ones((3, 2)), np.arange(3.0)
    with pytest.raises(ValueError, match="fewer samples than folds"):
        cross_validate(PolynomialRegression(1), X, y, n_splits=5)
    with pytest.raises(ValueError, match="fewer groups than folds"):
        cross_validate(
            PolynomialRegression(1),
            np.ones((10, 2)),
            np.arange(10.0),
            pose_groups=np.repeat([0, 1], 5),
        )
    with pytest.raises(ValueError, match="NaN"):
        cross_validate(PolynomialRegression(1), np.ones((10, 2)), np.full(10, np.nan))
    with pytest.raises(ValueError, match="mismatched"):
        cross_validate(PolynomialRegression(1), np.ones((10, 2)), np.ones(9))


def test_external_validation_relative_errors():
    class Constant:
        def predict(self, X):
            return np.full((len(X), 1), 2.0)

    res = external_validation(Constant(), np.zeros((2, 1)), np.array([[1.0], [4.0]]))
    np.testing.assert_allclose(res.mean_relative_error, [(1.0 + 0.5) / 2])
    np.testing.assert_allclose(res.max_relative_error, [1.0])
    np.testing.assert_allclose(res.rmse, [np.sqrt((1 + 4) / 2)])
