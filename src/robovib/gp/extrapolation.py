"""Is a prediction outside the training data? One answer for every pose model.

A GP far from its training inputs returns its prior (constant mean, large std) — a number that
looks like an answer. Every prediction made outside the calibrated region must therefore carry
an extrapolation flag. The region is the per-input range of the training inputs (the box the
thesis calibrated, §3.3); models that know better (``extrapolating(X)``, e.g. the pose model)
are asked directly.
"""

from __future__ import annotations

import numpy as np

__all__ = ["extrapolating", "outside_inputs", "training_range"]


def training_range(model) -> tuple[np.ndarray, np.ndarray]:
    """Per-input (lo, hi) of the training inputs of a fitted model.

    Works with :class:`~robovib.gp.BatchedGPRegressor` (``X_train_``), the mode-switching
    model (its low-mode GP), and models exposing ``pose_range_``.

    Raises
    ------
    TypeError
        The model exposes none of these.
    """
    if hasattr(model, "input_min_") and hasattr(model, "input_max_"):  # PoseModalModel
        return np.asarray(model.input_min_, float), np.asarray(model.input_max_, float)
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
    """(n,) bool: rows of ``X`` (same units as the training inputs) outside the training range."""
    X = np.atleast_2d(np.asarray(X, float))
    if hasattr(model, "extrapolating") and not hasattr(model, "pose_range_"):
        return np.asarray(model.extrapolating(X), bool).reshape(-1)
    lo, hi = training_range(model)
    if X.shape[1] != lo.size:
        raise ValueError(f"X has {X.shape[1]} inputs, the model was trained on {lo.size}")
    tol = 1e-9 * np.maximum(1.0, np.abs(hi - lo))
    return np.any((X < lo - tol) | (X > hi + tol) | ~np.isfinite(X), axis=1)


def outside_inputs(model, x, names) -> tuple[str, ...]:
    """Names of the inputs of one point ``x`` that lie outside the training range."""
    x = np.asarray(x, float).reshape(-1)
    if hasattr(model, "outside_inputs") and hasattr(model, "input_names"):
        flags = np.asarray(model.outside_inputs(x[None, :]), bool).reshape(-1)
        return tuple(n for n, f in zip(names, flags, strict=True) if f)
    lo, hi = training_range(model)
    if x.size != lo.size or len(names) != lo.size:
        raise ValueError(f"need {lo.size} inputs and names, got {x.size} and {len(names)}")
    return tuple(n for n, v, a, b in zip(names, x, lo, hi, strict=True) if not a <= v <= b)
