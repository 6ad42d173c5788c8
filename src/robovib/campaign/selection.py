"""Where to hammer next: greedy integrated-variance reduction over candidate poses.

:func:`next_poses` needs only the GP posteriors, so it runs on a saved model read without
scikit-learn (:class:`robovib.gp.saved_model.PosePredictor`). It is the one next-poses algorithm
of the package: :class:`robovib.gp.PoseModalModel` (modal outputs), its predictor and
:class:`robovib.hybrid.FRFPoseModel` (FRF bins) all go through it, and
:func:`robovib.campaign.plot_next_poses` draws its :class:`NextPoses`.

What it needs from a model (a small protocol): ``input_names`` and either ``gp_posteriors()``
(a list of ``(GPPosterior, noise_std, signal_std, columns, mode)``, as
:meth:`robovib.gp.saved_model.PosePredictor.gp_posteriors` and
:meth:`robovib.hybrid.FRFPoseModel.gp_posteriors`) or the fitted regressors of a
:class:`~robovib.gp.PoseModalModel` (``estimators_``, ``estimator_columns_``); optionally a
``calibration_`` with per-output band scales.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

__all__ = ["NextPoses", "next_poses"]


@dataclass(frozen=True)
class NextPoses:
    """Chosen poses and what each pick removes.

    Attributes
    ----------
    poses
        (k, n_inputs) chosen candidates, in pick order.
    indices
        (k,) their rows in the candidate set.
    variance_reduction
        (k,) integrated normalised variance removed by each pick.
    total_variance_before
        Integrated normalised variance over the candidates before any pick.
    candidates
        (m, n_inputs) the candidate set, in the model's input units.
    candidate_variance
        (m,) normalised latent variance at each candidate before any pick, summed over the
        model's outputs (what ``total_variance_before`` sums).
    training_poses
        (n, n_inputs) the poses the model was trained on.
    input_names
        The model's input names (units in the names).
    """

    poses: np.ndarray
    indices: np.ndarray
    variance_reduction: np.ndarray
    total_variance_before: float
    candidates: np.ndarray
    candidate_variance: np.ndarray
    training_poses: np.ndarray
    input_names: tuple[str, ...]


def _gps_of(model) -> list:
    """The BatchedGPRegressors of a fitted :class:`~robovib.gp.PoseModalModel` with the
    calibration factor of each of their outputs (1 where uncalibrated); the per-mode GPs of a
    mode-switching direction included (the tests' reference for :func:`next_poses`)."""
    from ..gp.regressor import BatchedGPRegressor

    cal = model.calibration_
    out = []
    for est, cols in zip(model.estimators_, model.estimator_columns_, strict=True):
        cols = np.asarray(cols, int)
        scale = np.ones((cols.size, 2)) if cal is None else np.asarray(cal.scale)[cols]
        if isinstance(est, BatchedGPRegressor):
            out.append((est, scale[:, 0]))
            continue
        out.append((est.low_model_, scale[:, 0]))
        if est.high_model_ is not None:
            out.append((est.high_model_, scale[np.asarray(est.switching_outputs, int), 1]))
    return out


def _posterior_cov(gp, Xc: np.ndarray):
    """Latent posterior covariance (B, m, m) at Xc, noise and prior variances (B,), in target
    units (the regressor's own posterior, :class:`robovib.gp.posterior.GPPosterior`)."""
    from ..gp.bands import noise_std_of

    hp = gp.hyperparameters_
    return (
        gp.posterior_.covariance_at(Xc),
        noise_std_of(hp) ** 2,
        np.asarray(hp.signal_std, float) ** 2,
    )


def _covariances(model, Xc: np.ndarray) -> list:
    """``((cov, noise var, prior var), c²)`` of every GP of the model at the candidates.

    Every pose model (:class:`~robovib.gp.PoseModalModel`, its read-only
    :class:`~robovib.gp.saved_model.PosePredictor`, the hybrid FRF model) gives its GP
    posteriors through ``gp_posteriors``; same numbers from the same file.
    """
    cal = getattr(model, "calibration_", None)  # the FRF pose model has no band calibration
    out = []
    for post, noise, signal, cols, mode in model.gp_posteriors():
        c = np.ones(cols.size) if cal is None else np.asarray(cal.scale)[cols, mode]
        out.append(((post.covariance_at(Xc), noise**2, signal**2), c**2))
    return out


def _training_poses(model) -> np.ndarray:
    """(n, n_inputs) training poses of the model."""
    return np.asarray(model.X_train_, float)


def next_poses(model, candidates, k: int = 5) -> NextPoses:
    """The ``k`` candidate poses whose measurement most reduces the integrated variance.

    Parameters
    ----------
    model
        A fitted :class:`robovib.gp.PoseModalModel` or its read-only
        :class:`~robovib.gp.saved_model.PosePredictor` (all its GPs count, the per-mode GPs of a
        switching direction included), or a fitted :class:`robovib.hybrid.FRFPoseModel` (one
        GP per bin and Re/Im; the EMA noise group counts, as the next poses are hammer tests);
        see the module docs for what a model must provide.
    candidates
        (m, n_inputs) array ((m,) for a model with one input), or a DataFrame / CSV path with
        the model's input columns.
    k
        Poses to choose (1 <= k <= m).

    Returns
    -------
    NextPoses
        The picks (greedy: each maximises the summed reduction of the latent variance over
        all candidates, thesis Eq. 10 conditioned on the earlier picks), normalised per output
        by its prior variance and scaled by the calibration factor squared.

    Raises
    ------
    ValueError
        Missing input columns, bad ``k``, an unfitted model.

    Examples
    --------
    >>> import numpy as np
    >>> from robovib.campaign import next_poses
    >>> from robovib.gp import load_chapter3_model
    >>> cand = np.array([[2100.0, -300.0, 0.0], [2400.0, 0.0, 45.0], [2700.0, 600.0, 90.0]])
    >>> len(next_poses(load_chapter3_model(), cand, k=2).poses)
    2
    """
    names = tuple(model.input_names)
    if isinstance(candidates, str | Path):
        from ..io import read_pose_table

        candidates = read_pose_table(candidates, names)
    if hasattr(candidates, "columns"):
        missing = [c for c in names if c not in candidates.columns]
        if missing:
            raise ValueError(f"candidates lack the model's input column(s) {', '.join(missing)}")
        candidates = candidates[list(names)].to_numpy(float)
    C = np.asarray(candidates, float)
    C = C[:, None] if C.ndim == 1 and len(names) == 1 else np.atleast_2d(C)
    if C.ndim != 2 or C.shape[1] != len(names):
        raise ValueError(f"candidates must be (m, {len(names)}) = {names}, got {C.shape}")
    if not np.all(np.isfinite(C)):
        raise ValueError("candidates contain NaN or inf")
    if not 1 <= int(k) <= len(C):
        raise ValueError(f"k must be in [1, {len(C)}] (the number of candidate poses), got {k}")
    # Calibrated bands (issue 24): latent and noise variance both scaled by c² per output, so an
    # output whose plain GP band was too narrow weighs more in the choice.
    parts = _covariances(model, C)
    cov = np.concatenate([c2[:, None, None] * c / p[:, None, None] for (c, _, p), c2 in parts])
    noise = np.concatenate([c2 * n / p for (_, n, p), c2 in parts])
    variance = np.sum(np.diagonal(cov, axis1=1, axis2=2), axis=0)  # (m,)
    before = float(np.sum(variance))
    chosen, gains = [], []
    for _ in range(int(k)):
        diag = np.diagonal(cov, axis1=1, axis2=2)  # (B, m)
        score = np.sum(np.sum(cov**2, axis=1) / (diag + noise[:, None]), axis=0)
        score[chosen] = -np.inf
        c = int(np.argmax(score))
        chosen.append(c)
        gains.append(float(score[c]))
        col = cov[:, :, c]  # (B, m)
        cov = cov - col[:, :, None] * col[:, None, :] / (diag[:, c] + noise)[:, None, None]
    idx = np.array(chosen)
    return NextPoses(
        C[idx], idx, np.array(gains), before, C, variance, _training_poses(model), names
    )
