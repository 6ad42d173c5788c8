"""Stationary covariance functions of the GP pose models, on squared scaled distances (NumPy only).

The covariance families (``covariance=``; the length scales, ``kernel="ard"`` or
``"isotropic"``, are the estimators'), in one place for every GP in robovib: the likelihood core
(:mod:`robovib.gp._likelihood`), the estimator's posterior (:class:`~robovib.gp.BatchedGPRegressor`),
the scikit-learn-free predictor (:mod:`robovib.gp.saved_model`) and next-pose selection all call
:func:`correlation`.

With ``r² = Σ_d (q_d − q'_d)² / l_d²`` (thesis Eq. 7 with the squared length scale, see
:mod:`robovib.gp.regressor`) and ``k = σ_f² ρ(r)``:

* ``"se"`` — squared exponential (thesis Eq. 7): ``ρ = exp(−r²/2)``;
* ``"matern52"`` — Matérn ν = 5/2: ``ρ = (1 + √5 r + 5r²/3) exp(−√5 r)``;
* ``"matern32"`` — Matérn ν = 3/2: ``ρ = (1 + √3 r) exp(−√3 r)``.

The Matérn kernels give rougher sample paths than the SE kernel (twice and once mean-square
differentiable); with the same data they widen the band between measured poses, which is where
an SE kernel fitted by marginal likelihood is overconfident (issue 24, Rasmussen & Williams 2006,
§4.2.1). For the length-scale gradient, :func:`correlation` also returns
``γ(r) = −2 dρ/d(r²)``, so that ``∂k/∂log l_d = σ_f² γ(r) (q_d − q'_d)² / l_d²`` for every family
(for the SE kernel ``γ = ρ``).
"""

from __future__ import annotations

import numpy as np

__all__ = ["COVARIANCES", "correlation"]

#: The covariance families every robovib GP accepts.
COVARIANCES = ("se", "matern52", "matern32")

_SQRT3 = np.sqrt(3.0)
_SQRT5 = np.sqrt(5.0)


def correlation(r2: np.ndarray, covariance: str = "se", *, with_gradient: bool = False):
    """Correlation ``ρ(r)`` (and ``γ = −2 dρ/d(r²)``) at squared scaled distances ``r2``.

    Parameters
    ----------
    r2
        Squared scaled distances (any shape, >= 0).
    covariance
        ``"se"``, ``"matern52"`` or ``"matern32"``.
    with_gradient
        Also return ``γ`` (same shape).

    Returns
    -------
    rho : ndarray
    gamma : ndarray, if ``with_gradient``

    Raises
    ------
    ValueError
        On an unknown covariance name.

    Examples
    --------
    >>> import numpy as np
    >>> from robovib.gp.covariances import correlation
    >>> float(correlation(np.array(0.0), "matern52"))
    1.0
    """
    r2 = np.asarray(r2, float)
    if covariance == "se":
        rho = np.exp(-0.5 * r2)
        return (rho, rho) if with_gradient else rho
    if covariance not in COVARIANCES:
        raise ValueError(f"unknown covariance {covariance!r}; expected one of {COVARIANCES}")
    r = np.sqrt(np.maximum(r2, 0.0))
    if covariance == "matern52":
        e = np.exp(-_SQRT5 * r)
        rho = (1.0 + _SQRT5 * r + (5.0 / 3.0) * r2) * e
        if not with_gradient:
            return rho
        return rho, (5.0 / 3.0) * (1.0 + _SQRT5 * r) * e
    e = np.exp(-_SQRT3 * r)
    rho = (1.0 + _SQRT3 * r) * e
    return (rho, 3.0 * e) if with_gradient else rho
