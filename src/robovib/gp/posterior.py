"""The posterior of a batch of exact GPs (thesis Eq. 9-10): one implementation, NumPy only.

:class:`~robovib.gp.BatchedGPRegressor` (after fitting), the scikit-learn-free
:class:`~robovib.gp.predictor.PosePredictor` (from a saved file) and next-pose selection
(:func:`robovib.campaign.next_poses`) all evaluate the posterior through :class:`GPPosterior`.

Everything is held in the scaled space of the fit (standardised inputs, centred and scaled
targets) and converted to data units on the way out::

    mean(x*) = m + k*ᵀ α,              α = K_y⁻¹ (y − m)
    var(x*)  = σ_f² − |L⁻¹ k*|²,        K_y = L Lᵀ

(the variance as ``σ_f² − |L⁻¹ k*|²``, as scikit-learn, to limit cancellation). Unobserved
targets have zero ``α`` and zero columns of ``L⁻¹``, so they drop out without a mask.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .kernels import correlation

__all__ = ["GPPosterior"]


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
        Covariance family (:func:`robovib.gp.kernels.correlation`).
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
