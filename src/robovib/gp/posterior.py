"""The posterior of a batch of exact GPs (thesis Eq. 9-10): one implementation, NumPy only.

:class:`~robovib.gp.BatchedGPRegressor` (after fitting), the scikit-learn-free
:class:`~robovib.gp.saved_model.PosePredictor` (from a saved file) and next-pose selection
(:func:`robovib.campaign.next_poses`) all evaluate the posterior through :class:`GPPosterior`.

Everything is held in the scaled space of the fit (standardised inputs, centred and scaled
targets) and converted to data units on the way out::

    mean(x*) = m + k*ᵀ α,              α = K_y⁻¹ (y − m)
    var(x*)  = σ_f² − |L⁻¹ k*|²,        K_y = L Lᵀ

(the variance as ``σ_f² − |L⁻¹ k*|²``, as scikit-learn, to limit cancellation). Unobserved
targets have zero ``α`` and zero columns of ``L⁻¹``, so they drop out without a mask.

It is also built in one place: :func:`fitted_posterior` (from log-hyperparameters and the
replicate-collapsed training set, through :func:`robovib.gp._likelihood.evaluate`), with the
scaling of :func:`standardisation` and the parameter vector of :func:`theta_from_hyperparameters`.
The estimator calls them after fitting, the predictor on the stored hyperparameters (with NumPy's
LAPACK, so without SciPy).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import _likelihood
from .covariances import correlation

__all__ = ["GPPosterior", "fitted_posterior", "standardisation", "theta_from_hyperparameters"]


@dataclass(frozen=True)
class GPPosterior:
    """Posterior of ``B`` independent GPs over ``n`` (unique) training inputs.

    Attributes
    ----------
    x_loc, x_scale
        (d,) input standardisation.
    y_loc, y_scale
        (B,) target centring and scaling.
    x_s
        (n, d) scaled training inputs.
    sf2, inv_l2
        (B,) signal variance and (B, d) inverse squared length scales, scaled space.
    mean_s
        (B,) constant mean, scaled space.
    alpha
        (B, n) ``K_y⁻¹ (y − m)``.
    chol_inv
        (B, n, n) ``L⁻¹`` (zero columns where a target is unobserved).
    covariance
        Covariance family (:func:`robovib.gp.covariances.correlation`).
    """

    x_loc: np.ndarray
    x_scale: np.ndarray
    y_loc: np.ndarray
    y_scale: np.ndarray
    x_s: np.ndarray
    sf2: np.ndarray
    inv_l2: np.ndarray
    mean_s: np.ndarray
    alpha: np.ndarray
    chol_inv: np.ndarray
    covariance: str = "se"

    def _cross(self, A_s: np.ndarray, B_s: np.ndarray) -> np.ndarray:
        """(B, a, b) prior covariance between scaled inputs ``A_s`` and ``B_s``."""
        sq = (A_s[:, None, :] - B_s[None, :, :]) ** 2  # (a, b, d)
        a, b = sq.shape[:2]
        r2 = (self.inv_l2 @ sq.reshape(a * b, -1).T).reshape(-1, a, b)
        return self.sf2[:, None, None] * correlation(r2, self.covariance)

    def predict(self, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Mean and latent std (m, B) at inputs ``X`` (m, d), data units.

        Parameters
        ----------
        X : numpy.ndarray
            (m, d) inputs.

        Returns
        -------
        mean, std : numpy.ndarray
            (m, B) each.
        """
        xq = (np.asarray(X, float) - self.x_loc) / self.x_scale
        k_star = self._cross(xq, self.x_s)  # (B, m, n)
        mean_s = self.mean_s[:, None] + np.matmul(k_star, self.alpha[:, :, None])[:, :, 0]
        v = np.matmul(self.chol_inv, k_star.transpose(0, 2, 1))  # (B, n, m)
        var_s = self.sf2[:, None] - np.sum(v * v, axis=1)
        mean = (mean_s * self.y_scale[:, None] + self.y_loc[:, None]).T
        std = (np.sqrt(np.maximum(var_s, 0.0)) * self.y_scale[:, None]).T
        return mean, std

    def covariance_at(self, X: np.ndarray) -> np.ndarray:
        """(B, m, m) latent posterior covariance at inputs ``X`` (m, d), data units.

        Parameters
        ----------
        X : numpy.ndarray
            (m, d) inputs.

        Returns
        -------
        numpy.ndarray
            (B, m, m) covariance.
        """
        xq = (np.asarray(X, float) - self.x_loc) / self.x_scale
        v = np.matmul(self.chol_inv, self._cross(xq, self.x_s).transpose(0, 2, 1))  # (B, n, m)
        cov_s = self._cross(xq, xq) - np.matmul(v.transpose(0, 2, 1), v)
        return cov_s * (self.y_scale**2)[:, None, None]


def standardisation(X: np.ndarray, Y: np.ndarray, mask: np.ndarray, normalize: bool):
    """Input standardisation and target centring/scaling of a fit (observed targets only).

    Parameters
    ----------
    X : numpy.ndarray
        (n, d) inputs.
    Y : numpy.ndarray
        (n, B) targets (any value where unobserved).
    mask : numpy.ndarray
        (n, B) bool, observed.
    normalize : bool
        ``False``: identity scaling.

    Returns
    -------
    x_loc, x_scale, y_loc, y_scale : numpy.ndarray
        (d,) and (B,) each.

    Raises
    ------
    ValueError
        An output with constant targets (``normalize=True``).
    """
    if not normalize:
        return np.zeros(X.shape[1]), np.ones(X.shape[1]), np.zeros(Y.shape[1]), np.ones(Y.shape[1])
    x_loc = X.mean(axis=0)
    x_scale = X.std(axis=0)
    x_scale[x_scale == 0] = 1.0
    counts = mask.sum(axis=0)
    y_loc = np.where(mask, Y, 0).sum(axis=0) / counts
    y_scale = np.sqrt(np.where(mask, (Y - y_loc) ** 2, 0).sum(axis=0) / counts)
    constant = y_scale <= 1e-12 * np.maximum(1.0, np.abs(y_loc))
    if np.any(constant):
        raise ValueError(
            f"outputs {np.flatnonzero(constant).tolist()} have constant targets; "
            "a GP cannot be fitted to them"
        )
    return x_loc, x_scale, y_loc, y_scale


def theta_from_hyperparameters(
    signal_std, length_scales, noise_std, *, n_groups: int, isotropic: bool, x_scale, y_scale
) -> np.ndarray:
    """(B, p) log-hyperparameters ``[log sf, log l (1 or d), log sn (G)]`` in the scaled space.

    Parameters
    ----------
    signal_std, length_scales, noise_std : array_like
        Data units: (B,) or scalar; (B, d), (d,) or scalar; (B,), (G,), (B, G) or scalar.
    n_groups : int
        Noise groups ``G``.
    isotropic : bool
        One length scale per output: the geometric mean of the scaled ones (standardisation makes
        an isotropic kernel anisotropic in data units).
    x_scale, y_scale : numpy.ndarray
        (d,) and (B,) scalings (:func:`standardisation`).

    Returns
    -------
    numpy.ndarray
        (B, p) parameter vectors (not clipped to any bounds).
    """
    n_out, n_features = np.size(y_scale), np.size(x_scale)
    sf = np.broadcast_to(np.asarray(signal_std, float), (n_out,)) / y_scale
    noise = np.asarray(noise_std, float)
    if noise.ndim == 1:
        noise = noise[:, None] if noise.size == n_out else noise[None, :]
    sn = np.broadcast_to(noise, (n_out, n_groups)) / y_scale[:, None]
    ls = np.broadcast_to(np.asarray(length_scales, float), (n_out, n_features)) / x_scale
    if isotropic:
        ls = np.exp(np.mean(np.log(ls), axis=1, keepdims=True))
    return np.column_stack([np.log(sf), np.log(ls), np.log(sn)])


def fitted_posterior(
    theta: np.ndarray,
    design: _likelihood.Design,
    *,
    n_groups: int,
    constant_mean: bool,
    covariance: str,
    x_loc: np.ndarray,
    x_scale: np.ndarray,
    y_loc: np.ndarray,
    y_scale: np.ndarray,
    linalg: str = "scipy",
) -> tuple[GPPosterior, np.ndarray, np.ndarray]:
    """The posterior at fixed hyperparameters: Cholesky, profiled (GLS) mean, ``α`` and ``L⁻¹``.

    Parameters
    ----------
    theta : numpy.ndarray
        (B, p) log-hyperparameters (:func:`theta_from_hyperparameters`).
    design : robovib.gp._likelihood.Design
        Replicate-collapsed scaled training set (:func:`robovib.gp._likelihood.collapse_replicates`).
    n_groups : int
        Noise groups.
    constant_mean : bool
        Profiled constant mean (else zero mean).
    covariance : {"se", "matern52", "matern32"}
        The covariance family (:func:`robovib.gp.covariances.correlation`), not the length scales.
    x_loc, x_scale, y_loc, y_scale : numpy.ndarray
        Scaling (:func:`standardisation`).
    linalg : str
        ``"scipy"`` or ``"numpy"``: whose LAPACK factorises (same formulas).

    Returns
    -------
    posterior : GPPosterior
        Over the unique training inputs.
    nll : numpy.ndarray
        (B,) negative log marginal likelihood in the scaled space (``inf``: not factorised).
    jitter : numpy.ndarray
        (B,) jitter added to the diagonal (scaled units; 0 where none was needed).
    """
    nll, _, state = _likelihood.evaluate(
        theta, design, n_groups=n_groups, constant_mean=constant_mean, want_grad=False,
        want_state=True, covariance=covariance, linalg=linalg,
    )  # fmt: skip
    # Unobserved entries are decoupled (unit diagonal) and alpha is zero there; zeroing the
    # columns of L^-1 makes k* of those entries drop out without a mask at prediction time.
    chol_inv = state["chol_inv"]
    chol_inv *= design.obs[:, None, :]
    sf2 = np.exp(2.0 * theta[:, 0])
    inv_l2 = np.broadcast_to(
        np.exp(-2.0 * theta[:, 1:-n_groups]), (theta.shape[0], design.x.shape[1])
    )
    posterior = GPPosterior(
        x_loc, x_scale, y_loc, y_scale, design.x, sf2, inv_l2.copy(), state["mean"],
        state["alpha"], chol_inv, covariance,
    )  # fmt: skip
    return posterior, nll, state["jitter"]
