"""BatchedGPRegressor against scikit-learn, SciPy, finite differences and known functions."""

import warnings

import numpy as np
import pytest
from sklearn.exceptions import NotFittedError
from sklearn.gaussian_process import GaussianProcessRegressor
from sklearn.gaussian_process.kernels import RBF
from sklearn.gaussian_process.kernels import ConstantKernel as C

from robovib.gp import BatchedGPRegressor, GPHyperparameters, GPNumericalError
from robovib.gp._likelihood import _factor_and_invert


def _data(rng, n=25, d=3, n_out=3):
    X = rng.uniform(-2, 2, (n, d)) * np.array([1.0, 300.0, 50.0])[:d]
    base = np.column_stack(
        [np.sin(X[:, 0]) + X[:, 1] / 300, (X[:, 1] / 300) ** 2, np.cos(X[:, 2] / 50) * 3 + 10]
    )[:, :n_out]
    return X, base + 0.05 * rng.normal(size=base.shape)


def _sklearn(hp: GPHyperparameters, b: int, X, y):
    kernel = C(hp.signal_std[b] ** 2, "fixed") * RBF(hp.length_scales[b], "fixed")
    return GaussianProcessRegressor(kernel, alpha=hp.noise_std[b] ** 2, optimizer=None).fit(X, y)


@pytest.mark.oracle
@pytest.mark.parametrize("kernel", ["isotropic", "ard"])
def test_fixed_hyperparameters_match_sklearn(kernel):
    rng = np.random.default_rng(1)
    X, Y = _data(rng)
    X = X / np.array([1.0, 300.0, 50.0])
    ls = np.array([[0.8, 1.1, 2.0], [0.5, 0.6, 0.9], [1.5, 1.5, 1.5]])
    if kernel == "isotropic":
        ls = np.repeat(ls[:, :1], 3, axis=1)
    hp = GPHyperparameters(np.array([1.3, 0.7, 2.0]), ls, np.array([0.1, 0.05, 0.2]), np.zeros(3))
    gp = BatchedGPRegressor(
        kernel=kernel, mean="zero", normalize=False, optimizer=None, initial_hyperparameters=hp
    ).fit(X, Y)
    Xq = rng.uniform(-2, 2, (7, 3))
    mean, std = gp.predict(Xq, return_std=True)
    for b in range(3):
        sk = _sklearn(hp, b, X, Y[:, b])
        m_ref, s_ref = sk.predict(Xq, return_std=True)
        np.testing.assert_allclose(mean[:, b], m_ref, rtol=0, atol=1e-8)
        np.testing.assert_allclose(std[:, b], s_ref, rtol=0, atol=1e-8)
        assert gp.log_marginal_likelihood_value_[b] == pytest.approx(
            sk.log_marginal_likelihood_value_, abs=1e-8
        )
    # predict_one (control-cycle fast path) gives the same numbers.
    m1, s1 = gp.predict_one(Xq[0])
    np.testing.assert_allclose(m1, mean[0], atol=1e-12)
    np.testing.assert_allclose(s1, std[0], atol=1e-12)


@pytest.mark.oracle
def test_fitted_model_in_data_units_matches_sklearn():
    """Normalisation and the estimated constant mean are reported correctly in data units."""
    rng = np.random.default_rng(2)
    X, Y = _data(rng)
    gp = BatchedGPRegressor(kernel="ard", rng=0).fit(X, Y)
    hp = gp.hyperparameters_
    Xq = rng.uniform(-2, 2, (5, 3)) * np.array([1.0, 300.0, 50.0])
    mean, std = gp.predict(Xq, return_std=True)
    for b in range(3):
        sk = _sklearn(hp, b, X, Y[:, b] - hp.mean[b])
        m_ref, s_ref = sk.predict(Xq, return_std=True)
        scale = np.std(Y[:, b])
        np.testing.assert_allclose(mean[:, b], m_ref + hp.mean[b], atol=1e-8 * scale)
        np.testing.assert_allclose(std[:, b], s_ref, atol=1e-8 * scale)
        assert gp.log_marginal_likelihood_value_[b] == pytest.approx(
            sk.log_marginal_likelihood_value_, abs=1e-7
        )
        assert gp.log_marginal_likelihood(hp)[b] == pytest.approx(
            sk.log_marginal_likelihood_value_, abs=1e-7
        )


def test_mean_is_the_gls_estimate():
    rng = np.random.default_rng(3)
    X, Y = _data(rng, n_out=1)
    gp = BatchedGPRegressor(kernel="ard", rng=0).fit(X, Y[:, 0])
    hp = gp.hyperparameters_
    sk = _sklearn(hp, 0, X, Y[:, 0])
    k = sk.kernel_(X) + hp.noise_std[0] ** 2 * np.eye(len(X))
    kinv = np.linalg.inv(k)
    ones = np.ones(len(X))
    m_gls = ones @ kinv @ Y[:, 0] / (ones @ kinv @ ones)
    assert hp.mean[0] == pytest.approx(m_gls, rel=1e-8)


@pytest.mark.parametrize("kernel", ["isotropic", "ard"])
@pytest.mark.parametrize("mean", ["constant", "zero"])
def test_gradient_matches_finite_differences(kernel, mean):
    rng = np.random.default_rng(4)
    X, Y = _data(rng, n=15)
    mask = np.ones(Y.shape, bool)
    mask[3, 1] = False
    gp = BatchedGPRegressor(kernel=kernel, mean=mean, optimizer=None).fit(X, Y, mask=mask)
    xs, ys = gp._scale_x(X), gp._scale_y(np.where(mask, Y, 0), mask)
    sq = (xs[:, None] - xs[None]) ** 2
    p = 2 + (1 if kernel == "isotropic" else 3)
    theta = rng.normal(scale=0.5, size=(3, p))
    _, grad, _ = gp._nll_and_grad(theta, ys.T, mask.T, sq)
    eps = 1e-6
    for j in range(p):
        tp, tm = theta.copy(), theta.copy()
        tp[:, j] += eps
        tm[:, j] -= eps
        fp, _, _ = gp._nll_and_grad(tp, ys.T, mask.T, sq, want_grad=False)
        fm, _, _ = gp._nll_and_grad(tm, ys.T, mask.T, sq, want_grad=False)
        np.testing.assert_allclose(grad[:, j], (fp - fm) / (2 * eps), rtol=1e-5, atol=1e-6)


def test_batched_equals_one_at_a_time():
    rng = np.random.default_rng(5)
    X, Y = _data(rng)
    batch = BatchedGPRegressor(kernel="ard", n_restarts=0).fit(X, Y)
    for b in range(3):
        single = BatchedGPRegressor(kernel="ard", n_restarts=0).fit(X, Y[:, b])
        np.testing.assert_allclose(
            single.hyperparameters_.length_scales[0],
            batch.hyperparameters_.length_scales[b],
            rtol=1e-4,
        )
        np.testing.assert_allclose(
            single.log_marginal_likelihood_value_[0],
            batch.log_marginal_likelihood_value_[b],
            rtol=1e-9,
        )
        assert abs(int(single.n_iter_[0]) - int(batch.n_iter_[b])) <= 1


@pytest.mark.oracle
def test_bfgs_reaches_scipy_optimum():
    rng = np.random.default_rng(6)
    X, Y = _data(rng, n=30)
    ours = BatchedGPRegressor(kernel="ard", n_restarts=3, rng=1).fit(X, Y)
    ref = BatchedGPRegressor(kernel="ard", optimizer="scipy", n_restarts=3, rng=1).fit(X, Y)
    assert np.all(ours.log_marginal_likelihood_value_ >= ref.log_marginal_likelihood_value_ - 1e-3)
    assert ours.n_iter_.shape == (3,) and np.all(ours.n_iter_ > 0)


def test_interpolates_known_function():
    x = np.linspace(0, 2 * np.pi, 15)
    gp = BatchedGPRegressor(kernel="isotropic", rng=0).fit(x[:, None], np.sin(x))
    xq = np.linspace(0.2, 6.0, 50)
    mean, std = gp.predict(xq[:, None], return_std=True)
    np.testing.assert_allclose(mean, np.sin(xq), atol=5e-3)
    assert std.max() < 0.01
    _, std_far = gp.predict(np.array([[20.0]]), return_std=True)
    assert std_far[0] > 0.5  # back to the prior far from the data


def test_mask_equals_dropping_the_row():
    rng = np.random.default_rng(7)
    X, Y = _data(rng, n=20, n_out=2)
    mask = np.ones(Y.shape, bool)
    mask[[2, 9], 0] = False
    Y_nan = Y.copy()
    Y_nan[~mask] = np.nan
    hp = GPHyperparameters(
        np.array([1.0, 1.0]), np.array([[1.0, 200.0, 40.0]] * 2), np.array([0.1, 0.1]), np.zeros(2)
    )
    masked = BatchedGPRegressor(
        kernel="ard", optimizer=None, normalize=False, initial_hyperparameters=hp
    ).fit(X, Y_nan, mask=mask)
    keep = mask[:, 0]
    dropped = BatchedGPRegressor(
        kernel="ard", optimizer=None, normalize=False, initial_hyperparameters=hp.select([0])
    ).fit(X[keep], Y[keep, :1])
    Xq = X[:4] + 0.1
    m1, s1 = masked.predict(Xq, return_std=True)
    m2, s2 = dropped.predict(Xq, return_std=True)
    np.testing.assert_allclose(m1[:, 0], m2[:, 0], atol=1e-10)
    np.testing.assert_allclose(s1[:, 0], s2[:, 0], atol=1e-10)
    assert masked.log_marginal_likelihood_value_[0] == pytest.approx(
        dropped.log_marginal_likelihood_value_[0], abs=1e-9
    )


def test_add_observations_posterior_update_is_exact():
    rng = np.random.default_rng(8)
    X, Y = _data(rng, n=30)
    gp = BatchedGPRegressor(kernel="ard", rng=0).fit(X[:20], Y[:20])
    hp = gp.hyperparameters_
    gp.add_observations(X[20:], Y[20:])
    assert np.all(gp.n_iter_ == 0)
    ref = BatchedGPRegressor(kernel="ard", optimizer=None, initial_hyperparameters=hp).fit(X, Y)
    Xq = X[:5] * 0.9
    m1, s1 = gp.predict(Xq, return_std=True)
    m2, s2 = ref.predict(Xq, return_std=True)
    np.testing.assert_allclose(m1, m2, atol=1e-8)
    np.testing.assert_allclose(s1, s2, atol=1e-8)


def test_add_observations_with_reoptimisation_improves_likelihood():
    """Warm re-optimisation must move the hyperparameters to a clearly better likelihood.

    Judged by scikit-learn's log marginal likelihood of all 40 points (an independent
    implementation) at the hyperparameters before and after the update: it fails if
    ``reoptimize`` is ignored (the hyperparameters, hence both values, would be equal).
    """
    rng = np.random.default_rng(9)
    X, Y = _data(rng, n=40)
    kept = BatchedGPRegressor(kernel="ard", rng=0).fit(X[:10], Y[:10])
    kept.add_observations(X[10:], Y[10:])
    assert np.all(kept.n_iter_ == 0)
    hp_before = kept.hyperparameters_
    gp = BatchedGPRegressor(kernel="ard", rng=0).fit(X[:10], Y[:10])
    gp.add_observations(X[10:], Y[10:], reoptimize=True)
    hp_after = gp.hyperparameters_
    assert np.all(gp.n_iter_ > 0)
    for b in range(Y.shape[1]):
        lml_before = _sklearn(hp_before, b, X, Y[:, b] - hp_before.mean[b])
        lml_after = _sklearn(hp_after, b, X, Y[:, b] - hp_after.mean[b])
        # a real improvement, not a tie: the 10-point optimum is poor for 40 points
        assert (
            lml_after.log_marginal_likelihood_value_
            > lml_before.log_marginal_likelihood_value_ + 1.0
        )
    # the model's own likelihood of the enlarged data set improves too
    assert np.all(gp.log_marginal_likelihood_value_ > kept.log_marginal_likelihood_value_ + 1.0)


@pytest.mark.parametrize(
    ("X", "Y", "message"),
    [
        (np.full((5, 2), np.nan), np.ones(5), "X contains NaN"),
        (np.ones((5, 2)), np.array([1, 2, np.inf, 4, 5.0]), "Y contains NaN or inf"),
        (np.ones((5, 2)), np.ones(4), "mismatched lengths"),
        (np.ones((5, 2, 1)), np.ones(5), "must be 2-D"),
        (np.arange(10.0).reshape(5, 2), np.full(5, 3.0), "constant targets"),
        (np.ones((1, 2)), np.ones(1), "fewer than 2"),
    ],
)
def test_bad_input(X, Y, message):
    with pytest.raises(ValueError, match=message):
        BatchedGPRegressor().fit(X, Y)


def test_bad_parameters_and_unfitted():
    X, Y = np.arange(10.0).reshape(5, 2), np.arange(5.0)
    with pytest.raises(ValueError, match="unknown kernel"):
        BatchedGPRegressor(kernel="matern").fit(X, Y)
    with pytest.raises(ValueError, match="unknown optimizer"):
        BatchedGPRegressor(optimizer="adam").fit(X, Y)
    with pytest.raises(NotFittedError, match="not fitted"):
        BatchedGPRegressor().predict(X)
    gp = BatchedGPRegressor(rng=0).fit(X, Y)
    with pytest.raises(ValueError, match="features"):
        gp.predict(np.ones((2, 3)))
    with pytest.raises(ValueError, match="mask shape"):
        BatchedGPRegressor().fit(X, Y, mask=np.ones((5, 2), bool))


def test_cholesky_jitter_escalation_and_failure():
    singular = np.ones((1, 4, 4))
    buf, logdet, jitter = singular.copy(), np.empty(1), np.zeros(1)
    _factor_and_invert(buf, logdet, jitter)
    assert jitter[0] > 0 and np.all(np.isfinite(buf))
    # The inverse of the jittered matrix (condition number ~1e10: relative accuracy ~1e-6).
    ref = np.linalg.inv(singular[0] + jitter[0] * np.eye(4))
    np.testing.assert_allclose(buf[0], ref, rtol=1e-4, atol=1e-4 * np.abs(ref).max())
    broken = -np.eye(3)[None].copy()
    _factor_and_invert(broken, logdet, jitter)
    assert np.isinf(jitter[0]) and np.isinf(logdet[0])
    gp = BatchedGPRegressor(kernel="ard", optimizer=None, normalize=False)
    with pytest.raises(GPNumericalError, match="not positive definite"), warnings.catch_warnings():
        warnings.simplefilter("ignore")
        gp._nll_and_grad(
            np.array([[0.0, 0.0, np.nan]]),
            np.zeros((1, 3)),
            np.ones((1, 3), bool),
            np.zeros((3, 3, 1)),
            allow_fail=False,
        )


def test_noise_groups_estimate_each_source_noise_and_gradient():
    rng = np.random.default_rng(0)
    X = rng.uniform(0, 1, (80, 1))
    groups = np.repeat([0, 1], 40)
    Y = np.sin(6 * X[:, 0]) + np.where(groups == 0, 0.01, 0.2) * rng.normal(size=80)
    gp = BatchedGPRegressor(n_noise_groups=2, rng=0).fit(X, Y, groups=groups)
    noise = gp.hyperparameters_.noise_std[0]
    assert noise[0] == pytest.approx(0.01, rel=0.5) and noise[1] == pytest.approx(0.2, rel=0.3)
    xs, ys = gp._scale_x(X), gp._scale_y(Y[:, None], np.ones((80, 1), bool))
    sq = (xs[:, None] - xs[None]) ** 2
    theta = np.array([[0.1, -0.5, -2.0, -1.0]])
    mask = np.ones((1, 80), bool)
    _, grad, _ = gp._nll_and_grad(theta, ys.T, mask, sq)
    for j in range(4):
        e = np.zeros_like(theta)
        e[0, j] = 1e-6
        fp = gp._nll_and_grad(theta + e, ys.T, mask, sq, want_grad=False)[0]
        fm = gp._nll_and_grad(theta - e, ys.T, mask, sq, want_grad=False)[0]
        assert grad[0, j] == pytest.approx(((fp - fm) / 2e-6)[0], rel=1e-5)
    with pytest.raises(ValueError, match="groups"):
        BatchedGPRegressor(n_noise_groups=2).fit(X, Y)
