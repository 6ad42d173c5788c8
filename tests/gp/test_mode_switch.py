"""Mode-switch-aware pose model on a synthetic two-mode truth."""

import numpy as np
import pytest
from sklearn.exceptions import NotFittedError

from robovib.gp import BatchedGPRegressor
from robovib.gp.mode_switch import ModeSwitchingGPRegressor, symmetric_rz_features


def truth(X):
    """Low mode everywhere; a high mode dominates where x > 0.6 (known by construction)."""
    x, y = X[:, 0], X[:, 1]
    high = x > 0.6
    fn = np.where(high, 63.0 + 0.5 * y, 16.0 + 4.0 * x + y)
    damping = np.where(high, 1.0, 7.0 + x)
    other = 9.0 - 1.5 * x + 0.2 * y  # an output that does not switch
    return np.column_stack([fn, damping, other]), high


@pytest.fixture(scope="module")
def data():
    grid = np.array([(x, y) for x in np.linspace(0, 1, 7) for y in np.linspace(-1, 1, 5)])
    rng = np.random.default_rng(0)
    Y, _ = truth(grid)
    return grid, Y + 0.02 * rng.normal(size=Y.shape)


def test_switching_model_picks_the_right_mode(data):
    X, Y = data
    model = ModeSwitchingGPRegressor(
        switching_outputs=(0, 1), indicator_output=0, threshold=40.0
    ).fit(X, Y)
    Xq = np.array([[0.1, 0.3], [0.45, -0.5], [0.8, 0.2], [0.95, -0.9]])
    Yq, high = truth(Xq)
    p = model.high_mode_probability(Xq)
    np.testing.assert_array_equal(p > 0.5, high)
    mean, std = model.predict(Xq, return_std=True)
    np.testing.assert_allclose(mean, Yq, atol=0.3)
    assert np.all(np.isfinite(std))
    # A single smooth GP blends the modes near the switch; the switching model does not.
    smooth = BatchedGPRegressor(kernel="ard", rng=0).fit(X, Y)
    x_edge = np.array([[0.58, 0.0], [0.62, 0.0]])
    err_smooth = np.abs(smooth.predict(x_edge)[:, 0] - truth(x_edge)[0][:, 0]).max()
    err_switch = np.abs(model.predict(x_edge)[:, 0] - truth(x_edge)[0][:, 0]).max()
    assert err_switch < 1.0 < err_smooth


def test_switching_model_without_high_samples_is_the_plain_gp(data):
    X, Y = data
    low_only = X[:, 0] < 0.5
    model = ModeSwitchingGPRegressor(switching_outputs=(0, 1)).fit(X[low_only], Y[low_only])
    assert model.classifier_ is None and model.n_high_ == 0
    plain = BatchedGPRegressor(kernel="ard", rng=0).fit(X[low_only], Y[low_only])
    np.testing.assert_allclose(model.predict(X[:5]), plain.predict(X[:5]), atol=1e-10)
    np.testing.assert_array_equal(model.high_mode_probability(X[:3]), 0.0)


def test_symmetric_rz_features():
    f = symmetric_rz_features(
        np.array([[2400.0, 0.0, 0.0], [2400.0, 0.0, 180.0], [2400.0, 0.0, 90.0]])
    )
    np.testing.assert_allclose(f[:, 2], [1.0, 1.0, -1.0], atol=1e-12)


def test_switching_model_errors():
    with pytest.raises(NotFittedError, match="not fitted"):
        ModeSwitchingGPRegressor().predict(np.zeros((1, 2)))
    with pytest.raises(ValueError, match="indicator_output"):
        ModeSwitchingGPRegressor(switching_outputs=(1,), indicator_output=0).fit(
            np.zeros((4, 2)), np.ones((4, 2))
        )
