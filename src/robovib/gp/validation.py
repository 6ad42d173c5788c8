"""Validation of pose models: k-fold cross-validation, MLR baseline, external validation (§3.3.2).

Cross-validation comes in two flavours:

* ``groups=None`` — plain shuffled k-fold over rows, the thesis' protocol. With replicated
  measurements (Table A1 has 3 near-identical replicates per pose) copies of a test pose sit in
  the training folds, so this measures interpolation between replicates.
* ``groups=pose_id`` — grouped k-fold: all replicates of a pose are in the same fold, so every
  prediction is at a pose the model has not seen (the honest figure).

Scores are computed on the pooled out-of-fold predictions. ``r2`` is the coefficient of
determination (:func:`sklearn.metrics.r2_score`); the thesis calls its figure a "correlation
coefficient R²"; ``r2_corr`` (squared Pearson correlation of prediction and measurement) is
reported beside it.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
from sklearn.base import BaseEstimator, clone
from sklearn.exceptions import NotFittedError
from sklearn.linear_model import LinearRegression
from sklearn.model_selection import GroupKFold, KFold
from sklearn.pipeline import make_pipeline
from sklearn.preprocessing import PolynomialFeatures, StandardScaler

__all__ = [
    "CVResult",
    "ExternalValidationResult",
    "PolynomialRegression",
    "cross_validate",
    "external_validation",
    "regression_scores",
]


@dataclass(frozen=True)
class CVResult:
    """Out-of-fold predictions and scores per output (batch axis: outputs last in arrays).

    Attributes
    ----------
    predictions
        (n_samples, n_outputs) out-of-fold predictions.
    r2
        (n_outputs,) coefficient of determination.
    r2_corr
        (n_outputs,) squared Pearson correlation.
    rmse
        (n_outputs,) root mean squared error.
    folds
        (n_samples,) fold index of each sample.
    grouped
        Whether the folds hold out whole poses.
    """

    predictions: np.ndarray  #: (n_samples, n_outputs) out-of-fold predictions
    r2: np.ndarray  #: (n_outputs,) coefficient of determination
    r2_corr: np.ndarray  #: (n_outputs,) squared Pearson correlation
    rmse: np.ndarray  #: (n_outputs,)
    folds: np.ndarray  #: (n_samples,) fold index of each sample
    grouped: bool


@dataclass(frozen=True)
class ExternalValidationResult:
    """Scores of a fitted model on an independent test set.

    Attributes
    ----------
    predictions
        (n_samples, n_outputs) predictions.
    std
        (n_samples, n_outputs) predictive std, if the model gives one.
    rmse
        (n_outputs,) root mean squared error.
    mean_relative_error, max_relative_error
        (n_outputs,) mean and max of |pred - meas| / |meas|.
    """

    predictions: np.ndarray  #: (n_samples, n_outputs)
    std: np.ndarray | None  #: (n_samples, n_outputs) predictive std if the model gives one
    rmse: np.ndarray  #: (n_outputs,)
    mean_relative_error: np.ndarray  #: (n_outputs,) mean |pred - meas| / |meas|
    max_relative_error: np.ndarray  #: (n_outputs,)


def regression_scores(y_true, y_pred, mask=None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """R² (coefficient of determination), squared correlation and RMSE per output column.

    Parameters
    ----------
    y_true, y_pred : array_like
        (n, n_outputs) targets and predictions.
    mask : array_like, optional
        Observed targets (default: the finite ones).

    Returns
    -------
    r2, r2_corr, rmse : numpy.ndarray
        (n_outputs,) each.
    """
    y_true = np.atleast_2d(np.asarray(y_true, float).T).T
    y_pred = np.atleast_2d(np.asarray(y_pred, float).T).T
    if mask is None:
        mask = np.isfinite(y_true)
    n_out = y_true.shape[1]
    r2, r2c, rmse = np.empty(n_out), np.empty(n_out), np.empty(n_out)
    for b in range(n_out):
        m = mask[:, b]
        t, p = y_true[m, b], y_pred[m, b]
        resid = t - p
        rmse[b] = np.sqrt(np.mean(resid**2))
        ss_tot = np.sum((t - t.mean()) ** 2)
        r2[b] = 1.0 - np.sum(resid**2) / ss_tot if ss_tot > 0 else np.nan
        r2c[b] = np.corrcoef(t, p)[0, 1] ** 2 if np.std(p) > 0 and np.std(t) > 0 else np.nan
    return r2, r2c, rmse


def _check_validation_inputs(X, Y, mask):
    from .regressor import _as_2d_float

    X = _as_2d_float("X", X, "(n_samples, n_features)") if np.ndim(X) >= 2 else np.asarray(X)
    Y = _as_2d_float("Y", Y, "(n_samples, n_outputs)")
    if Y.ndim == 1:
        Y = Y[:, None]
    if X.ndim != 2 or Y.ndim != 2:
        raise ValueError(f"X must be 2-D and Y 1-D or 2-D; got shapes {X.shape} and {Y.shape}")
    if X.shape[0] != Y.shape[0]:
        raise ValueError(f"X and Y have mismatched lengths: {X.shape[0]} vs {Y.shape[0]}")
    if not np.all(np.isfinite(X)):
        raise ValueError("X contains NaN or inf")
    if mask is None:
        if not np.all(np.isfinite(Y)):
            raise ValueError(
                "Y contains NaN or inf; pass mask=np.isfinite(Y) to mark missing targets"
            )
        mask = np.ones(Y.shape, bool)
    mask = np.asarray(mask, bool).reshape(Y.shape)
    return X, Y, mask


def cross_validate(
    estimator,
    X,
    Y,
    *,
    n_splits: int = 5,
    pose_groups=None,
    mask=None,
    rng: int | np.random.Generator | None = 0,
    warm_start=False,
    groups=None,
) -> CVResult:
    """Shuffled k-fold cross-validation of a multi-output model.

    Parameters
    ----------
    estimator
        An unfitted scikit-learn-style estimator with ``fit(X, Y, mask=...)`` and
        ``predict(X)`` (e.g. ``BatchedGPRegressor(rng=0)``); each fold fits a
        :func:`sklearn.base.clone` of it, ``estimator`` itself is left untouched.
    X, Y
        (n, d) inputs and (n, B) targets.
    n_splits
        Number of folds (5 in the thesis).
    pose_groups
        Optional (n,) labels (e.g. one per pose of repeated measurements); samples of one group
        never sit on both sides (grouped CV).
    mask
        Optional (n, B) observed-target mask (NaN targets must be masked explicitly).
    rng
        Seed or Generator for the fold shuffle.
    warm_start : bool or GPHyperparameters
        ``True``: fit ``estimator`` once on all data and start every fold's optimiser from
        those hyperparameters (``initial_hyperparameters=...``, ``n_restarts=0``), much
        cheaper than the restarts of a cold fit; a :class:`~robovib.gp.GPHyperparameters`:
        start from these. Only for estimators with an ``initial_hyperparameters`` parameter
        (:class:`~robovib.gp.BatchedGPRegressor`). The held-out fold then influenced the
        starting point (not the fit), so the scores can be slightly optimistic; ``False``
        (default) keeps the folds fully independent.
    groups
        Deprecated name of ``pose_groups`` (``groups`` of the estimators' ``fit`` are noise
        groups).

    Returns
    -------
    CVResult

    Raises
    ------
    TypeError
        If ``estimator`` is not an estimator (e.g. a factory function), or ``warm_start`` is
        asked of an estimator without ``initial_hyperparameters``.
    ValueError
        On bad shapes, NaN inputs or fewer samples/groups than folds.
    """
    if not (hasattr(estimator, "fit") and hasattr(estimator, "get_params")):
        raise TypeError(
            f"estimator must be an unfitted scikit-learn-style estimator (with fit and "
            f"get_params), got {type(estimator).__name__}; pass the model, not a factory"
        )
    if groups is not None:
        warnings.warn(
            "cross_validate(groups=) is deprecated; pass the pose groups as pose_groups=",
            DeprecationWarning,
            stacklevel=2,
        )
        pose_groups = groups if pose_groups is None else pose_groups
    groups = pose_groups
    X, Y, mask = _check_validation_inputs(X, Y, mask)
    n = X.shape[0]
    if n_splits < 2:
        raise ValueError(f"n_splits must be at least 2, got {n_splits}")
    seed = int(np.random.default_rng(rng).integers(2**31 - 1))
    if groups is None:
        if n < n_splits:
            raise ValueError(
                f"cannot split {n} samples into {n_splits} folds: fewer samples than folds"
            )
        splitter = KFold(n_splits=n_splits, shuffle=True, random_state=seed).split(X)
    else:
        groups = np.asarray(groups)
        if groups.shape != (n,):
            raise ValueError(f"pose_groups must have shape ({n},), got {groups.shape}")
        n_groups = np.unique(groups).size
        if n_groups < n_splits:
            raise ValueError(
                f"cannot split {n_groups} groups into {n_splits} folds: fewer groups than folds"
            )
        splitter = GroupKFold(n_splits=n_splits, shuffle=True, random_state=seed).split(
            X, groups=groups
        )
    template = estimator
    if warm_start is not False and warm_start is not None:
        if "initial_hyperparameters" not in estimator.get_params():
            raise TypeError(
                f"warm_start needs an estimator with initial_hyperparameters (e.g. "
                f"BatchedGPRegressor), got {type(estimator).__name__}"
            )
        start = (
            clone(estimator).fit(X, Y, mask=mask).hyperparameters_
            if warm_start is True
            else warm_start
        )
        template = clone(estimator).set_params(initial_hyperparameters=start, n_restarts=0)
    predictions = np.full(Y.shape, np.nan)
    folds = np.empty(n, dtype=int)
    for k, (train, test) in enumerate(splitter):
        model = clone(template)
        model.fit(X[train], Y[train], mask=mask[train])
        pred = np.asarray(model.predict(X[test]))
        predictions[test] = pred.reshape(len(test), -1)
        folds[test] = k
    r2, r2c, rmse = regression_scores(np.where(mask, Y, np.nan), predictions, mask)
    return CVResult(predictions, r2, r2c, rmse, folds, groups is not None)


class PolynomialRegression(BaseEstimator):
    """Multivariate polynomial least squares (the thesis' 2nd-order MLR baseline, §3.3.2).

    A full polynomial of ``degree`` in all inputs (standardised first), one independent
    least-squares fit per output column. Missing targets (``mask=False``) are left out of the
    fit of their output only.

    Parameters
    ----------
    degree : int
        Polynomial degree.
    """

    def __init__(self, degree: int = 2) -> None:
        self.degree = degree

    def fit(self, X, Y, mask=None) -> PolynomialRegression:
        X, Y, mask = _check_validation_inputs(X, Y, mask)
        self.models_ = []
        for b in range(Y.shape[1]):
            m = mask[:, b]
            model = make_pipeline(
                StandardScaler(),
                PolynomialFeatures(self.degree),
                LinearRegression(fit_intercept=False),
            )
            model.fit(X[m], Y[m, b])
            self.models_.append(model)
        self.n_features_in_ = X.shape[1]
        return self

    def predict(self, X) -> np.ndarray:
        from .regressor import _as_2d_float

        if not hasattr(self, "models_"):
            raise NotFittedError("this PolynomialRegression is not fitted yet; call fit() first")
        if np.ndim(X) == 1:
            raise ValueError("X is 1-D: Reshape your data to (n_samples, n_features)")
        X = _as_2d_float("X", X, "(n_samples, n_features)")
        if X.shape[1] != self.n_features_in_:
            raise ValueError(
                f"X has {X.shape[1]} features, but PolynomialRegression is expecting "
                f"{self.n_features_in_} features as input"
            )
        return np.column_stack([m.predict(X) for m in self.models_])


def external_validation(model, X_test, Y_test, mask=None) -> ExternalValidationResult:
    """Score a fitted model on an independent test set (thesis Table A2 / Figure 9).

    Parameters
    ----------
    model : object
        A fitted model with ``predict``.
    X_test, Y_test : array_like
        Test inputs and targets.
    mask : array_like, optional
        Observed targets (default: all; Y must then be finite).

    Returns
    -------
    ExternalValidationResult
        Predictions and scores per output.
    """
    X_test, Y_test, mask = _check_validation_inputs(X_test, Y_test, mask)
    std = None
    try:
        pred, std = model.predict(X_test, return_std=True)
    except TypeError:
        pred = model.predict(X_test)
    pred = np.asarray(pred).reshape(Y_test.shape)
    _, _, rmse = regression_scores(np.where(mask, Y_test, np.nan), pred, mask)
    with np.errstate(divide="ignore", invalid="ignore"):
        rel = np.where(mask, np.abs(pred - Y_test) / np.abs(Y_test), np.nan)
    return ExternalValidationResult(
        predictions=pred,
        std=None if std is None else np.asarray(std).reshape(Y_test.shape),
        rmse=rmse,
        mean_relative_error=np.nanmean(rel, axis=0),
        max_relative_error=np.nanmax(rel, axis=0),
    )
