"""Is a prediction outside the training data? One answer for every pose model.

A GP far from its training inputs returns its prior (constant mean, large std) — a number that
looks like an answer. Every prediction made outside the calibrated region must therefore carry
an extrapolation flag. The region is the per-input range of the training inputs (the box the
thesis calibrated, §3.3); models that know better (``extrapolating(X)``, e.g. the pose model)
are asked directly.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["TrainingRegion", "extrapolating", "outside_inputs", "training_range"]


def _unique_rows(a: np.ndarray) -> np.ndarray:
    """Distinct rows of ``a`` (``np.unique(a, axis=0)`` imports numpy.ma: ~30 ms at start-up)."""
    s = a[np.lexsort(a.T[::-1])]
    return s[np.r_[True, np.any(s[1:] != s[:-1], axis=1)]]


def _in_hull(points: np.ndarray, x: np.ndarray, tol: float = 1e-9) -> bool:
    """Whether ``x`` (d,) lies in the convex hull of ``points`` (m, d), within ``tol``.

    ``x`` is in the hull iff weights ``w >= 0`` with ``sum(w) = 1`` and ``points.T @ w = x``
    exist: the non-negative least-squares residual of ``[points.T; 1] w = [x; 1]`` is zero
    (Lawson & Hanson's active-set algorithm, NumPy only).
    """
    A = np.vstack([points.T, np.ones(points.shape[0])])
    b = np.append(x, 1.0)
    n = A.shape[1]
    passive = np.zeros(n, bool)
    w = np.zeros(n)
    for _ in range(3 * n):
        grad = A.T @ (b - A @ w)
        if np.linalg.norm(b - A @ w) <= tol or passive.all() or grad[~passive].max() <= 1e-14:
            break
        passive[np.argmax(np.where(passive, -np.inf, grad))] = True
        while True:
            z = np.zeros(n)
            z[passive] = np.linalg.lstsq(A[:, passive], b, rcond=None)[0]
            if np.all(z[passive] > 0):
                w = z
                break
            neg = passive & (z <= 0)
            step = np.min(w[neg] / (w[neg] - z[neg]))
            w = w + step * (z - w)
            passive &= w > 1e-15
            w[~passive] = 0.0
    return bool(np.linalg.norm(b - A @ w) <= tol)


@dataclass(frozen=True)
class TrainingRegion:
    """Where a pose model was calibrated: the box of its training inputs and their hull.

    One rule for every pose model (:class:`~robovib.gp.PoseModalModel` and its fast
    :class:`~robovib.gp.saved_model.PosePredictor`): an input is outside when it leaves the
    training range by more than ``1e-9`` of that range; a pose extrapolates when an input is
    outside or, for two or more inputs spanning a volume, the pose lies outside the convex hull
    of the standardised unique training poses (:func:`_in_hull`, NumPy only).

    Attributes
    ----------
    lo, hi
        (d,) training range of each input.
    hull_loc, hull_scale
        (d,) standardisation of the hull test.
    hull_points
        (m, d) standardised unique training poses, or None (box test only).
    """

    lo: np.ndarray
    hi: np.ndarray
    hull_loc: np.ndarray
    hull_scale: np.ndarray
    hull_points: np.ndarray | None

    @classmethod
    def of(cls, X) -> TrainingRegion:
        """The region of training inputs ``X`` (n, d).

        Parameters
        ----------
        X
            Training inputs.

        Returns
        -------
        TrainingRegion
        """
        X = np.asarray(X, float)
        loc = X.mean(axis=0)
        scale = np.where(X.std(axis=0) > 0, X.std(axis=0), 1.0)
        pts = None
        if X.shape[1] >= 2:
            u = _unique_rows((X - loc) / scale)
            # No hull (box test only) where the poses span no volume.
            if u.shape[0] > X.shape[1] and np.linalg.matrix_rank(u - u[0]) == X.shape[1]:
                pts = u
        return cls(X.min(axis=0), X.max(axis=0), loc, scale, pts)

    def outside_inputs(self, X) -> np.ndarray:
        """(n, d) bool: input value outside the training range of that input.

        Parameters
        ----------
        X : array_like
            (n, d) inputs in the training units.

        Returns
        -------
        numpy.ndarray
            (n, d) bool.
        """
        X = np.atleast_2d(np.asarray(X, float))
        tol = 1e-9 * np.maximum(1.0, self.hi - self.lo)
        return (self.lo - tol > X) | (self.hi + tol < X)

    def extrapolating(self, X) -> np.ndarray:
        """(n,) bool: outside the box or the convex hull of the training inputs.

        Parameters
        ----------
        X : array_like
            (n, d) inputs in the training units.

        Returns
        -------
        numpy.ndarray
            (n,) bool.
        """
        X = np.atleast_2d(np.asarray(X, float))
        out = np.any(self.outside_inputs(X), axis=1)
        if self.hull_points is not None:
            xs = (X - self.hull_loc) / self.hull_scale
            for i in np.flatnonzero(~out):
                out[i] = not _in_hull(self.hull_points, xs[i])
        return out


def training_range(model) -> tuple[np.ndarray, np.ndarray]:
    """Per-input (lo, hi) of the training inputs of a fitted model.

    Works with :class:`~robovib.gp.BatchedGPRegressor` (``X_train_``), the mode-switching
    model (its low-mode GP), and models exposing ``pose_range_``.

    Parameters
    ----------
    model : object
        The fitted model.

    Returns
    -------
    lo, hi : numpy.ndarray
        (d,) per-input bounds.

    Raises
    ------
    TypeError
        The model exposes none of these.
    """
    from .contract import PoseModel

    if isinstance(model, PoseModel):  # every pose model of either kind
        lo, hi = np.array(list(model.input_range().values()), float).T
        return lo, hi
    if hasattr(model, "pose_range_"):
        lo, hi = model.pose_range_
        return np.atleast_1d(np.asarray(lo, float)), np.atleast_1d(np.asarray(hi, float))
    for m in (model, getattr(model, "low_model_", None)):
        X = getattr(m, "X_train_", None)
        if X is not None:
            X = np.asarray(X, float)
            return X.min(axis=0), X.max(axis=0)
    raise TypeError(f"cannot tell the training range of a {type(model).__name__}")


def extrapolating(model, X) -> np.ndarray:
    """(n,) bool: rows of ``X`` (same units as the training inputs) outside the training range.

    Parameters
    ----------
    model : object
        A fitted model (see :func:`training_range`).
    X : array_like
        (n, d) inputs.

    Returns
    -------
    numpy.ndarray
        (n,) bool.
    """
    from .contract import PoseModel

    X = np.atleast_2d(np.asarray(X, float))
    if isinstance(model, PoseModel):  # the contract's one rule (box and hull)
        return np.asarray(model.extrapolating(X), bool).reshape(-1)
    lo, hi = training_range(model)
    if X.shape[1] != lo.size:
        raise ValueError(f"X has {X.shape[1]} inputs, the model was trained on {lo.size}")
    box = TrainingRegion(lo, hi, np.zeros_like(lo), np.ones_like(lo), None)
    return box.extrapolating(X) | np.any(~np.isfinite(X), axis=1)


def outside_inputs(model, x, names) -> tuple[str, ...]:
    """Names of the inputs of one point ``x`` that lie outside the training range.

    Parameters
    ----------
    model : object
        A fitted model (see :func:`training_range`).
    x : array_like
        (d,) one input point.
    names : sequence of str
        Input names.

    Returns
    -------
    tuple of str
        The names of the inputs outside their training range.
    """
    from .contract import PoseModel

    x = np.asarray(x, float).reshape(-1)
    if isinstance(model, PoseModel):
        flags = np.asarray(model.outside_inputs(x[None, :]), bool).reshape(-1)
        return tuple(n for n, f in zip(names, flags, strict=True) if f)
    lo, hi = training_range(model)
    if x.size != lo.size or len(names) != lo.size:
        raise ValueError(f"need {lo.size} inputs and names, got {x.size} and {len(names)}")
    box = TrainingRegion(lo, hi, np.zeros_like(lo), np.ones_like(lo), None)
    flags = box.outside_inputs(x[None, :])[0]
    return tuple(n for n, f in zip(names, flags, strict=True) if f)
