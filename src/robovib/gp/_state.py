"""The fitted state of a :class:`BatchedGPRegressor` for robovib's own packages (gp-internal).

Estimators built on the regressor (the hybrid FRF model) need three things its public API
does not give: the noise group of each training row, a start value for a noise group with no
data yet, and its exact state (log hyperparameters in scaled units and the scalers) to store
and re-create it bit for bit. They get them here, so that only ``gp`` touches the regressor's
private attributes.
"""

from __future__ import annotations

import numpy as np

from .regressor import BatchedGPRegressor

__all__ = [
    "SCALED_STATE",
    "noise_groups",
    "regressor_from_scaled_state",
    "scaled_state",
    "start_noise_group_like",
]

#: The arrays of :func:`scaled_state`: log hyperparameters in scaled units (one row per
#: output: log signal std, log length scales, log noise std per group), the input and target
#: scalers, and the noise group of each training row.
SCALED_STATE = ("theta", "x_loc", "x_scale", "y_loc", "y_scale", "groups")


def noise_groups(gp: BatchedGPRegressor) -> np.ndarray:
    """(n_train,) int noise group of each training row of a fitted regressor."""
    gp._require_fitted()
    return np.asarray(gp._active_groups, int)


def start_noise_group_like(gp: BatchedGPRegressor, group: int, like: int) -> None:
    """Set the noise of ``group`` to that of ``like`` when no training row is in ``group``.

    A noise group without data is not identified by the fit; a later update that adds its
    first rows starts it at the level of the ``like`` group (e.g. OMA at the EMA noise).
    """
    gp._require_fitted()
    if not np.any(gp._active_groups == group):
        gp._theta[:, group - gp._n_groups] = gp._theta[:, like - gp._n_groups]


def scaled_state(gp: BatchedGPRegressor) -> dict[str, np.ndarray]:
    """The arrays :data:`SCALED_STATE` of a fitted regressor (copies)."""
    gp._require_fitted()
    if gp._squeeze:
        raise ValueError("only regressors fitted on a 2-D Y have a stored state")
    return {
        "theta": np.array(gp._theta, float),
        "x_loc": np.array(gp._x_loc, float),
        "x_scale": np.array(gp._x_scale, float),
        "y_loc": np.array(gp._y_loc, float),
        "y_scale": np.array(gp._y_scale, float),
        "groups": np.array(gp._active_groups, int),
    }


def regressor_from_scaled_state(
    state, X, Y, mask, *, kernel: str, n_noise_groups: int
) -> BatchedGPRegressor:
    """Re-create the regressor :func:`scaled_state` described, on its training data.

    Parameters
    ----------
    state
        Mapping with the arrays :data:`SCALED_STATE`.
    X, Y, mask
        The training inputs (n, d), targets (n, n_out) and observed mask (n, n_out).
    kernel, n_noise_groups
        The regressor's parameters.

    Returns
    -------
    BatchedGPRegressor
        Fitted, with exactly the stored hyperparameters and scalers (``n_iter_`` zero).

    Raises
    ------
    ValueError, numpy.linalg.LinAlgError
        Data that do not fit the state, or a covariance that cannot be factorised.
    """
    gp = BatchedGPRegressor(kernel=kernel, n_noise_groups=n_noise_groups)
    gp._x_loc, gp._x_scale = np.asarray(state["x_loc"]), np.asarray(state["x_scale"])
    gp._y_loc, gp._y_scale = np.asarray(state["y_loc"]), np.asarray(state["y_scale"])
    gp._theta = np.asarray(state["theta"])
    gp._active_groups = np.asarray(state["groups"]).astype(int)
    gp._squeeze = False
    gp.n_iter_ = np.zeros(gp._theta.shape[0], int)
    gp._set_training_data(X, Y, mask)
    return gp
