"""Batched quasi-Newton minimisation of many independent small problems at once.

SciPy's optimisers minimise one function at a time; fitting 393 independent GPs through them
means 393 Python-level optimisation loops. Here the BFGS update of the thesis (Eq. 34-36) runs
on a batch of problems in lock-step, with one inverse-Hessian approximation, one step length and
one convergence flag per problem, so every linear-algebra call is vectorised across the batch.
The result for each problem is the same kind of local optimum that :func:`scipy.optimize.minimize`
with ``method="BFGS"`` finds (tested in ``tests/gp/test_optimize.py``).

Box bounds are handled by projection (variables at a bound with the gradient pointing outward
are frozen for that step), which is enough for the log-hyperparameter boxes used here.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

__all__ = ["BatchedMinimizeResult", "batched_bfgs"]

# fun(theta[k, p], index[k]) -> (f[k], grad[k, p]); rows of theta belong to problems ``index``.
BatchedObjective = Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]


@dataclass(frozen=True)
class BatchedMinimizeResult:
    """Outcome per problem of :func:`batched_bfgs` (batch axis first).

    Attributes
    ----------
    x
        (B, p) minimisers.
    fun
        (B,) objective values.
    grad
        (B, p) gradients at ``x``.
    n_iter
        (B,) quasi-Newton iterations (accepted steps).
    n_fev
        (B,) objective evaluations.
    converged
        (B,) gradient or function-change criterion met.
    """

    x: np.ndarray  #: (B, p) minimisers
    fun: np.ndarray  #: (B,) objective values
    grad: np.ndarray  #: (B, p) gradients at ``x``
    n_iter: np.ndarray  #: (B,) quasi-Newton iterations (accepted steps)
    n_fev: np.ndarray  #: (B,) objective evaluations
    converged: np.ndarray  #: (B,) gradient or function-change criterion met


def _projected_gradient(theta, grad, lower, upper):
    pg = grad.copy()
    at_lower = (theta <= lower) & (grad > 0)
    at_upper = (theta >= upper) & (grad < 0)
    pg[at_lower | at_upper] = 0.0
    return pg


def _merge_duplicates(theta, f, active, label, tol) -> None:
    """Deactivate the worse of two active rows with one label whose x are within ``tol``."""
    idx = np.flatnonzero(active)
    if idx.size < 2:
        return
    idx = idx[np.lexsort((f[idx], label[idx]))]  # by label, best f first
    lab = label[idx]
    for lag in range(1, idx.size):
        a, b = idx[:-lag], idx[lag:]
        same = lab[:-lag] == lab[lag:]
        if not np.any(same):
            break
        close = same & (np.max(np.abs(theta[a] - theta[b]), axis=1) < tol)
        # b sorts after a within its label, so f[b] >= f[a]: stop b (if a still runs).
        active[b[close & active[a]]] = False


def batched_bfgs(
    fun: BatchedObjective,
    x0: np.ndarray,
    *,
    lower: np.ndarray | None = None,
    upper: np.ndarray | None = None,
    max_iter: int = 200,
    gtol: float = 1e-5,
    ftol: float = 1e-10,
    max_backtracks: int = 30,
    armijo: float = 1e-4,
    same_problem: np.ndarray | None = None,
    merge_tol: float = 1e-2,
) -> BatchedMinimizeResult:
    """Minimise ``B`` independent smooth functions with BFGS (thesis Eq. 34-36), vectorised.

    Parameters
    ----------
    fun
        ``fun(theta, index) -> (f, grad)`` for the problems listed in ``index`` (rows of
        ``theta``). Non-finite ``f`` marks a trial point as infeasible (the step is shortened).
    x0
        (B, p) starting points.
    lower, upper
        (p,) or (B, p) box bounds; ``None`` means unbounded.
    max_iter
        Maximum number of accepted quasi-Newton steps per problem.
    gtol
        Stop a problem when the max-norm of its projected gradient falls below ``gtol``.
    ftol
        Stop when the relative decrease of ``f`` in one step falls below ``ftol``.
    max_backtracks
        Step halvings tried per line search.
    armijo
        Sufficient-decrease constant of the line search.
    same_problem
        Optional (B,) integer labels: rows with the same label are starts of one problem
        (restarts). When two active starts of a problem come within ``merge_tol`` (max-norm of
        ``x``) of each other they are in one basin; the one with the higher ``f`` stops there
        (not ``converged``), saving the evaluations of a duplicate descent.
    merge_tol
        Distance (max-norm) under which two starts of a problem count as one basin.

    Returns
    -------
    BatchedMinimizeResult
    """
    theta = np.array(x0, dtype=float, copy=True)
    if theta.ndim != 2:
        raise ValueError(f"x0 must have shape (B, p), got {theta.shape}")
    n_problems, n_params = theta.shape
    lower = np.broadcast_to(-np.inf if lower is None else lower, theta.shape).astype(float)
    upper = np.broadcast_to(np.inf if upper is None else upper, theta.shape).astype(float)
    theta = np.clip(theta, lower, upper)

    everyone = np.arange(n_problems)
    f, g = fun(theta, everyone)
    if not np.all(np.isfinite(f)):
        bad = np.flatnonzero(~np.isfinite(f))
        raise ValueError(
            f"objective is not finite at the starting point of problems {bad.tolist()}"
        )
    n_fev = np.ones(n_problems, dtype=int)
    n_iter = np.zeros(n_problems, dtype=int)
    converged = np.zeros(n_problems, dtype=bool)
    active = np.ones(n_problems, dtype=bool)
    eye = np.eye(n_params)
    inv_hessian = np.repeat(eye[None], n_problems, axis=0)

    pg = _projected_gradient(theta, g, lower, upper)
    done = np.max(np.abs(pg), axis=1) < gtol
    converged |= done
    active &= ~done

    for _ in range(max_iter):
        idx = np.flatnonzero(active)
        if idx.size == 0:
            break
        th, gi, hi = theta[idx], g[idx], inv_hessian[idx]
        lo, up = lower[idx], upper[idx]
        direction = -np.einsum("kij,kj->ki", hi, gi)
        blocked = ((th <= lo) & (direction < 0)) | ((th >= up) & (direction > 0))
        direction[blocked] = 0.0
        slope = np.sum(direction * gi, axis=1)
        not_descent = slope >= -1e-300
        if np.any(not_descent):
            # Reset to steepest (projected) descent where the quasi-Newton direction fails.
            pgi = _projected_gradient(th, gi, lo, up)
            direction[not_descent] = -pgi[not_descent]
            hi[not_descent] = eye
            slope = np.sum(direction * gi, axis=1)
        first = n_iter[idx] == 0
        # On the first step the Hessian guess is the identity: keep the step at most unit length.
        step = np.ones(idx.size)
        dnorm = np.linalg.norm(direction, axis=1)
        step[first] = np.minimum(1.0, 1.0 / np.maximum(dnorm[first], 1e-300))

        new_theta = th.copy()
        new_f = f[idx].copy()
        new_g = gi.copy()
        accepted = np.zeros(idx.size, dtype=bool)
        pending = np.arange(idx.size)
        for _bt in range(max_backtracks):
            trial = np.clip(
                th[pending] + step[pending, None] * direction[pending], lo[pending], up[pending]
            )
            ft, gt = fun(trial, idx[pending])
            n_fev[idx[pending]] += 1
            actual_slope = np.sum((trial - th[pending]) * gi[pending], axis=1)
            ok = np.isfinite(ft) & (ft <= f[idx[pending]] + armijo * actual_slope)
            good = pending[ok]
            new_theta[good], new_f[good], new_g[good] = trial[ok], ft[ok], gt[ok]
            accepted[good] = True
            pending = pending[~ok]
            if pending.size == 0:
                break
            step[pending] *= 0.5

        # A failed line search means no further decrease is attainable along any tried step.
        failed = ~accepted
        s = new_theta - th
        y = new_g - gi
        sy = np.sum(s * y, axis=1)
        update = accepted & (sy > 1e-12 * np.linalg.norm(s, axis=1) * np.linalg.norm(y, axis=1))
        if np.any(update):
            u = np.flatnonzero(update)
            rho = 1.0 / sy[u]
            hu = hi[u]
            scale_first = first[u]
            if np.any(scale_first):
                # Shanno-Phua scaling of the identity before the first update.
                yy = np.sum(y[u] * y[u], axis=1)
                gamma = sy[u] / yy
                hu[scale_first] = gamma[scale_first, None, None] * eye[None]
            # Eq. 35 in the usual form: H+ = (I - rho s y^T) H (I - rho y s^T) + rho s s^T.
            left = eye[None] - rho[:, None, None] * np.einsum("ki,kj->kij", s[u], y[u])
            hu = np.einsum("kij,kjl,kml->kim", left, hu, left)
            hu += rho[:, None, None] * np.einsum("ki,kj->kij", s[u], s[u])
            hi[u] = hu

        f_old = f[idx]
        theta[idx], f[idx], g[idx], inv_hessian[idx] = new_theta, new_f, new_g, hi
        n_iter[idx] += accepted
        pg_new = _projected_gradient(new_theta, new_g, lo, up)
        small_grad = np.max(np.abs(pg_new), axis=1) < gtol
        small_change = accepted & (
            np.abs(f_old - new_f)
            <= ftol * np.maximum(1.0, np.maximum(np.abs(f_old), np.abs(new_f)))
        )
        stop = small_grad | small_change | failed
        converged[idx] |= small_grad | small_change
        active[idx[stop]] = False
        if same_problem is not None:
            _merge_duplicates(theta, f, active, same_problem, merge_tol)

    return BatchedMinimizeResult(
        x=theta, fun=f, grad=g, n_iter=n_iter, n_fev=n_fev, converged=converged
    )
