"""Pose model that tracks a dominant-mode switch instead of smoothing across it.

At X = 2700 mm with Rz = 0°/180° Table A1 reports a 61-65 Hz dominant X mode (damping ≈ 1 kN·s/m)
next to 15-23 Hz everywhere else: another mode of the arm has become the most compliant one
(see ``docs/data.md``, "Mode switch in X"). A single smooth GP over the pose averages the two modes
and predicts physically meaningless 40 Hz modes in between. This model instead keeps

* a *low-mode* GP of all outputs, fitted with the switching outputs of the high-mode rows
  masked out (so it describes the usual 15-23 Hz mode everywhere);
* a *high-mode* GP of the switching outputs, fitted on the high-mode rows only;
* a GP classifier (:class:`sklearn.gaussian_process.GaussianProcessClassifier`) of the
  probability that the high mode is dominant at a pose.

``predict`` returns, for the switching outputs, the parameters of the more probable mode
(never a blend of the two), and :meth:`high_mode_probability` how sure that choice is.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass

import numpy as np
from sklearn.base import BaseEstimator
from sklearn.exceptions import NotFittedError

from .._threads import single_blas_thread
from .regressor import BatchedGPRegressor, _as_2d_float, _checked_query

__all__ = [
    "ModeSwitchDetection",
    "ModeSwitchingGPRegressor",
    "detect_mode_switch",
    "symmetric_rz_features",
]


@dataclass(frozen=True)
class ModeSwitchDetection:
    """Outcome of the mode-switch test of one direction (see the module docstring).

    Attributes
    ----------
    direction
        The direction tested.
    found
        A switch is modelled in this direction.
    assumed
        The switch was given by the user (``mode_switch={direction: threshold_hz}``), not tested.
    threshold_hz
        Frequency separating the low and the high mode (NaN when none is found).
    delta_bic
        BIC(1 component) − BIC(2 components) of ``log fn``.
    ashman_d
        Ashman's D of the two mixture components.
    gap_sigma
        Empty gap between the modes / larger within-mode std, both in ``log fn``.
    n_low, n_high
        Samples in the low and the high mode.
    reason
        One line explaining the decision.
    """

    direction: str
    found: bool
    assumed: bool
    threshold_hz: float
    delta_bic: float
    ashman_d: float
    gap_sigma: float
    n_low: int
    n_high: int
    reason: str

    def to_dict(self) -> dict:
        """Plain dict (JSON-ready; NaN stays NaN).

        Returns
        -------
        dict
            The detection's fields.
        """
        return asdict(self)


def detect_mode_switch(
    fn_hz,
    *,
    direction: str = "",
    min_delta_bic: float = 10.0,
    min_ashman_d: float = 3.0,
    min_gap_sigma: float = 3.0,
    min_samples: int = 3,
    poses=None,
    distinct_ratio: float = 2.0,
    max_smooth_fraction: float = 0.75,
    min_high_samples: int = 1,
) -> ModeSwitchDetection:
    """Test whether the natural frequencies of one direction come from two distinct modes.

    Parameters
    ----------
    fn_hz
        (n,) observed natural frequencies of the dominant mode [Hz], over the workspace.
    direction
        Label stored in the result.
    min_delta_bic, min_ashman_d, min_gap_sigma, min_samples
        The thresholds of rules 1-4 of the module docstring (``min_samples``: of the low,
        usual mode).
    poses
        Optional (n, d) poses of the samples. With them, rule 5 (smooth variation) is applied:
        two clusters whose mean frequencies differ by less than ``distinct_ratio`` are taken as
        one mode whose frequency varies over the workspace when a GP of ``log fn`` over the
        pose, fitted without the pose predicted (grouped by pose, 5 folds), puts more than
        ``max_smooth_fraction`` of the smaller cluster's samples nearer their own cluster's
        mean than the other's. A factorial grid with few levels of Rz, for example, shows the
        X mode's smooth 16-22 Hz variation as two clusters of frequencies; a real switch to
        another mode (Table A1: 15-23 Hz vs 61-65 Hz) is not predictable from the neighbouring
        poses, so its high-mode samples are predicted near the low mode.
    distinct_ratio
        Ratio of the clusters' mean frequencies from which two clusters are distinct modes
        without rule 5 (another mode of the arm, not the same mode's drift).
    max_smooth_fraction
        See ``poses``.
    min_high_samples
        Fewest samples of the high mode. A high mode seen at fewer than ``min_samples``
        samples is still a switch (issue 36): smoothing it into the low mode would predict
        a blend of the two that exists nowhere. It then has no GP of its own (a constant with
        a wide band, :data:`robovib.gp.bands.UNMODELLED_MODE_RELATIVE_STD`), and the
        reason says so.

    Returns
    -------
    ModeSwitchDetection

    Raises
    ------
    ValueError
        If ``fn_hz`` is not 1-D or holds non-finite or non-positive values.
    """
    from sklearn.mixture import GaussianMixture

    fn = np.asarray(fn_hz, float)
    if fn.ndim != 1:
        raise ValueError(f"fn_hz must be 1-D, got shape {fn.shape}")
    if not np.all(np.isfinite(fn)) or np.any(fn <= 0):
        raise ValueError("fn_hz must be positive finite natural frequencies [Hz]")
    nan = float("nan")

    def none(reason, dbic=nan, d=nan, gap=nan, n_low=fn.size, n_high=0):
        return ModeSwitchDetection(
            direction, False, False, nan, dbic, d, gap, int(n_low), int(n_high), reason
        )

    if fn.size < 2 * min_samples or np.unique(fn).size < 2:
        return none(f"too few distinct samples ({fn.size}) to test for two modes")
    v = np.log(fn)[:, None]
    one = GaussianMixture(1).fit(v)
    two = GaussianMixture(2, n_init=5, random_state=0).fit(v)
    delta_bic = float(one.bic(v) - two.bic(v))
    labels = two.predict(v)
    high_label = int(np.argmax(two.means_[:, 0]))
    low, high = v[labels != high_label, 0], v[labels == high_label, 0]
    if low.size == 0 or high.size == 0:
        return none("the 2-component mixture put every sample in one mode", delta_bic)
    ashman = float(np.sqrt(2.0) * abs(high.mean() - low.mean()) / np.hypot(low.std(), high.std()))
    # Floor of the within-mode spread: frequencies are read to ~0.5 %, and identical replicates
    # must not make any gap look infinitely wide.
    spread = max(low.std(), high.std(), 0.005)
    gap = float(max(high.min() - low.max(), 0.0) / spread)
    stats = dict(dbic=delta_bic, d=ashman, gap=gap, n_low=low.size, n_high=high.size)
    if delta_bic < min_delta_bic:
        return none(f"one mode: ΔBIC = {delta_bic:.1f} < {min_delta_bic:g}", **stats)
    if ashman < min_ashman_d:
        return none(f"modes not separated: Ashman's D = {ashman:.2f} < {min_ashman_d:g}", **stats)
    if gap < min_gap_sigma:
        return none(
            f"no clear gap between the modes: gap = {gap:.2f} within-mode std < {min_gap_sigma:g}",
            **stats,
        )
    if low.size < min_samples:
        return none(f"the low mode has fewer than {min_samples} samples", **stats)
    if high.size < min_high_samples:
        return none(f"the high mode has fewer than {min_high_samples} samples", **stats)
    few = (
        f"; the high mode at only {high.size} sample(s): too few to model its field (a constant "
        "with a wide band)"
        if high.size < min_samples
        else ""
    )
    threshold = float(np.exp(0.5 * (low.max() + high.min())))
    ratio = float(np.exp(high.mean() - low.mean()))
    if poses is not None and ratio < distinct_ratio:
        followed = _fraction_predicted_in_cluster(poses, v[:, 0], labels == high_label)
        if followed > max_smooth_fraction:
            return none(
                f"one mode varying over the workspace: the clusters {np.exp(low.mean()):.3g} Hz "
                f"and {np.exp(high.mean()):.3g} Hz (ratio {ratio:.2f} < {distinct_ratio:g}) are "
                f"predicted from the neighbouring poses ({100 * followed:.0f} % of the smaller "
                "cluster's samples nearer their own cluster)",
                **stats,
            )
    return ModeSwitchDetection(
        direction,
        True,
        False,
        threshold,
        delta_bic,
        ashman,
        gap,
        int(low.size),
        int(high.size),
        f"two modes: {np.exp(low.min()):.3g}-{np.exp(low.max()):.3g} Hz and "
        f"{np.exp(high.min()):.3g}-{np.exp(high.max()):.3g} Hz (ΔBIC = {delta_bic:.0f}, "
        f"D = {ashman:.1f}, gap = {gap:.1f} std){few}",
    )


def _fraction_predicted_in_cluster(poses, log_fn: np.ndarray, high: np.ndarray) -> float:
    """Fraction of the smaller cluster's samples that a smooth GP of ``log fn`` over the pose,
    fitted without their pose (5 grouped folds, hyperparameters of the full fit), predicts
    nearer their own cluster's mean than the other's."""
    from .calibration import grouped_folds

    X = np.asarray(poses, float)
    if X.ndim != 2 or X.shape[0] != log_fn.size:
        raise ValueError(
            f"poses must be (n, d) with one row per frequency ({log_fn.size}), got {X.shape}"
        )
    y = log_fn[:, None]
    full = BatchedGPRegressor(kernel="ard", covariance="matern52", rng=0).fit(X, y)
    fold = grouped_folds(X, 5, 0)
    pred = np.empty_like(log_fn)
    for f in np.unique(fold):
        tr, te = fold != f, fold == f
        gp = BatchedGPRegressor(
            kernel="ard",
            covariance="matern52",
            optimizer=None,
            initial_hyperparameters=full.hyperparameters_,
        ).fit(X[tr], y[tr])
        pred[te] = gp.predict(X[te])[:, 0]
    small = high if high.sum() <= (~high).sum() else ~high
    own = np.where(small, log_fn[high].mean(), log_fn[~high].mean())
    other = np.where(small, log_fn[~high].mean(), log_fn[high].mean())
    nearer_own = np.abs(pred - own) < np.abs(pred - other)
    return float(np.mean(nearer_own[small]))


def symmetric_rz_features(X: np.ndarray) -> np.ndarray:
    """(X, Y, Rz [deg]) -> (X, Y, cos 2Rz): Rz and Rz + 180° give the same X-direction mode.

    Parameters
    ----------
    X : numpy.ndarray
        (n, 3) inputs (X, Y, Rz [deg]).

    Returns
    -------
    numpy.ndarray
        (n, 3) features (X, Y, cos 2Rz).
    """
    X = np.asarray(X, float)
    return np.column_stack([X[:, 0], X[:, 1], np.cos(np.radians(2.0 * X[:, 2]))])


class ModeSwitchingGPRegressor(BaseEstimator):
    """Multi-output GP with a classified switch of the dominant mode in some outputs.

    Parameters
    ----------
    switching_outputs
        Indices of the output columns that belong to the switching mode (e.g. X fn, k, c).
    indicator_output
        Output column whose value tells the modes apart (e.g. X natural frequency).
    threshold
        A sample is a high-mode sample where ``Y[:, indicator_output] > threshold``.
    classifier_features
        Optional map from the inputs (n, d) to the classifier's inputs, e.g.
        :func:`symmetric_rz_features` where Rz = 0° and 180° are the same configuration.
    kernel : {"ard", "isotropic"}
        The length scales of both modes' GPs (not the covariance family): one per input (ARD)
        or one shared (isotropic); passed to the underlying :class:`BatchedGPRegressor` models.
    rng
        Passed to the underlying :class:`BatchedGPRegressor` models.
    n_noise_groups
        Number of noise groups (``fit(..., groups=...)``), passed to the regressors.
    covariance : {"se", "matern52", "matern32"}
        The covariance family of both modes' GPs (:mod:`robovib.gp.covariances`; the length
        scales are ``kernel``).

    Attributes
    ----------
    low_model_, high_model_ : BatchedGPRegressor (``high_model_`` is None without high samples)
    classifier_ : GaussianProcessClassifier or None (None when training has one mode only)
    n_high_ : int
        Number of high-mode training samples.
    n_features_in_ : int
        Number of inputs seen in :meth:`fit`.

    Notes
    -----
    ``Y`` is always 2-D (one column per output; the scikit-learn tags say multi-output only).
    """

    def __init__(
        self,
        switching_outputs: Sequence[int] = (0, 1, 2),
        indicator_output: int = 0,
        threshold: float = 40.0,
        classifier_features: Callable[[np.ndarray], np.ndarray] | None = None,
        kernel: str = "ard",
        rng: int | np.random.Generator | None = 0,
        n_noise_groups: int = 1,
        covariance: str = "se",
    ) -> None:
        self.switching_outputs = switching_outputs
        self.indicator_output = indicator_output
        self.threshold = threshold
        self.classifier_features = classifier_features
        self.kernel = kernel
        self.rng = rng
        self.n_noise_groups = n_noise_groups
        self.covariance = covariance

    def __sklearn_tags__(self):
        """scikit-learn tags: 2-D targets only (one column per output), required by ``fit``.

        Returns
        -------
        sklearn.utils.Tags
            The default tags with ``target_tags.required``, ``target_tags.multi_output`` and
            not ``target_tags.single_output``.
        """
        tags = super().__sklearn_tags__()
        tags.target_tags.required = True
        tags.target_tags.multi_output = True
        tags.target_tags.single_output = False
        return tags

    @property
    def n_features_in_(self) -> int:
        """Number of inputs seen in :meth:`fit` (AttributeError before).

        Returns
        -------
        int
            The inputs of the low-mode GP.
        """
        return self.low_model_.n_features_in_

    def _check_query(self, X) -> np.ndarray:
        """``X`` as a finite (n, n_features_in_) float array (clear errors otherwise)."""
        self._require_fitted()
        return _checked_query("X", X, self.n_features_in_, "ModeSwitchingGPRegressor")

    def _regressor(self) -> BatchedGPRegressor:
        return BatchedGPRegressor(
            kernel=self.kernel,
            rng=self.rng,
            n_noise_groups=self.n_noise_groups,
            covariance=self.covariance,
        )

    def fit(self, X, Y, mask=None, groups=None) -> ModeSwitchingGPRegressor:
        """Fit the low-mode GP, the high-mode GP and the classifier.

        Parameters
        ----------
        X
            (n, d) inputs.
        Y
            (n, n_outputs) targets; NaN where not observed.
        mask
            Optional (n, n_outputs) bool, ``True`` where observed (default: finite ``Y``).
        groups
            Optional (n,) int noise group of each sample.

        Returns
        -------
        self
        """
        from sklearn.gaussian_process import GaussianProcessClassifier
        from sklearn.gaussian_process.kernels import RBF
        from sklearn.gaussian_process.kernels import ConstantKernel as C

        X = _as_2d_float("X", X, "(n_samples, n_features)")
        if not np.all(np.isfinite(X)):
            raise ValueError("X contains NaN or inf")
        if Y is None:
            raise ValueError(
                "ModeSwitchingGPRegressor requires y to be passed, but the target y is None"
            )
        if np.ndim(Y) != 2:
            raise ValueError(f"Y must be 2-D (n_samples, n_outputs), got shape {np.shape(Y)}")
        Y = _as_2d_float("Y", Y, "(n_samples, n_outputs)")
        if Y.shape[0] != X.shape[0]:
            raise ValueError(
                f"X and Y have mismatched lengths: {X.shape[0]} samples vs {Y.shape[0]} targets"
            )
        mask = np.isfinite(Y) if mask is None else np.asarray(mask, bool)
        groups = None if groups is None else np.asarray(groups)
        switching = np.asarray(self.switching_outputs, dtype=int)
        if self.indicator_output not in switching:
            raise ValueError("indicator_output must be one of switching_outputs")
        indicator = Y[:, self.indicator_output]
        observed = mask[:, self.indicator_output]
        high = observed & (np.where(observed, indicator, -np.inf) > self.threshold)
        self.n_high_ = int(high.sum())

        low_mask = mask.copy()
        low_mask[np.ix_(high, switching)] = False
        self.low_model_ = self._regressor().fit(X, Y, mask=low_mask, groups=groups)

        self.high_model_ = None
        if self.n_high_ >= 3:
            y_high = Y[np.ix_(high, switching)]
            m_high = mask[np.ix_(high, switching)]
            spread = np.nanstd(np.where(m_high, y_high, np.nan), axis=0)
            if np.all(spread > 0):
                self.high_model_ = self._regressor().fit(
                    X[high], y_high, mask=m_high, groups=None if groups is None else groups[high]
                )
        self._high_mean = (
            np.nanmean(
                np.where(mask[np.ix_(high, switching)], Y[np.ix_(high, switching)], np.nan), axis=0
            )
            if self.n_high_
            else None
        )

        self.classifier_ = None
        labels = high[observed]
        if 0 < labels.sum() < labels.size:
            features = self._features(X)
            self._x_loc, self._x_scale = features.mean(axis=0), features.std(axis=0)
            self._x_scale[self._x_scale == 0] = 1.0
            xs = (features[observed] - self._x_loc) / self._x_scale
            # Replicates share pose and label: classify unique (pose, label) rows (GPC is O(n^3)).
            unique = np.unique(np.column_stack([xs, labels]), axis=0)
            xs, labels = unique[:, :-1], unique[:, -1].astype(bool)
            kernel = C(1.0) * RBF(np.ones(xs.shape[1]))
            # Tens of poses: BLAS threads only contend (36 s instead of 2.7 s of CPU under load).
            with warnings.catch_warnings(), single_blas_thread():
                # Length scales running to their bound mean "irrelevant input": expected here.
                warnings.filterwarnings("ignore", message=".*close to the specified")
                seed = int(np.random.default_rng(self.rng).integers(2**31 - 1))
                self.classifier_ = GaussianProcessClassifier(
                    kernel, n_restarts_optimizer=3, random_state=seed
                ).fit(xs, labels)
        self._switching = switching
        self._all_high = labels.size > 0 and labels.all()
        return self

    def update(
        self, X_new, Y_new, mask=None, groups=None, *, mode: str = "posterior"
    ) -> ModeSwitchingGPRegressor:
        """Bayesian update with new samples (same names as :meth:`BatchedGPRegressor.update`).

        New samples are split by ``threshold`` as in :meth:`fit`: the low-mode GP gets every
        sample (switching outputs of high-mode samples masked), the high-mode GP the high-mode
        samples, the classifier the new labels. ``mode="posterior"`` keeps every
        hyperparameter (the GPs' and the classifier kernel's); ``"warm"`` re-optimises them from
        the current values.

        Parameters
        ----------
        X_new, Y_new : array_like
            New inputs and targets.
        mask : array_like, optional
            Observed targets (default: the finite ones).
        groups : array_like, optional
            Pose group of each new row.
        mode : {"posterior", "warm"}
            Keep the hyperparameters, or re-optimise them from the current values.

        Returns
        -------
        ModeSwitchingGPRegressor
            ``self``, updated.

        Raises
        ------
        NotFittedError
            If not fitted.
        ValueError
            Unknown ``mode``; high-mode samples for a model without a high-mode GP, or both
            labels for a model fitted with one (refit with :meth:`fit` then).
        """
        from sklearn.gaussian_process import GaussianProcessClassifier

        self._require_fitted()
        if mode not in ("posterior", "warm"):
            raise ValueError(f"unknown update mode {mode!r}; expected 'posterior' or 'warm'")
        X_new = np.asarray(X_new, float)
        Y_new = np.asarray(Y_new, float)
        mask = np.isfinite(Y_new) if mask is None else np.asarray(mask, bool)
        groups = None if groups is None else np.asarray(groups)
        sw = self._switching
        observed = mask[:, self.indicator_output]
        indicator = np.where(observed, Y_new[:, self.indicator_output], -np.inf)
        high = observed & (indicator > self.threshold)
        if np.any(high) and self.high_model_ is None:
            raise ValueError("this model has no high-mode GP to update; refit it with fit()")
        labels = high[observed]
        if self.classifier_ is None and labels.size and labels.any() != self._all_high:
            raise ValueError("the new samples add a second mode to a one-mode model; use fit()")
        low_mask = mask.copy()
        low_mask[np.ix_(high, sw)] = False
        self.low_model_.update(
            X_new, np.where(low_mask, Y_new, 0.0), low_mask, groups=groups, mode=mode
        )
        if np.any(high):
            m_high = mask[np.ix_(high, sw)]
            self.high_model_.update(
                X_new[high],
                np.where(m_high, Y_new[np.ix_(high, sw)], 0.0),
                m_high,
                groups=None if groups is None else groups[high],
                mode=mode,
            )
            self.n_high_ += int(high.sum())
        if self.classifier_ is not None and labels.size:
            base = self.classifier_.base_estimator_
            xs = (self._features(X_new[observed]) - self._x_loc) / self._x_scale
            rows = np.vstack(
                [
                    np.column_stack([base.X_train_, base.y_train_]),
                    np.column_stack([xs, labels]),
                ]
            )
            unique = np.unique(rows, axis=0)
            kernel = base.kernel_
            with warnings.catch_warnings(), single_blas_thread():
                warnings.filterwarnings("ignore", message=".*close to the specified")
                self.classifier_ = GaussianProcessClassifier(
                    kernel, optimizer=None if mode == "posterior" else "fmin_l_bfgs_b"
                ).fit(unique[:, :-1], unique[:, -1].astype(bool))
        return self

    def high_mode_probability(self, X) -> np.ndarray:
        """Probability (n,) that the high mode is the dominant one at each input.

        Parameters
        ----------
        X : array_like
            (n, d) inputs in the training units.

        Returns
        -------
        numpy.ndarray
            (n,) probabilities.
        """
        X = self._check_query(X)
        if self.classifier_ is None:
            return np.full(X.shape[0], 1.0 if self._all_high else 0.0)
        with single_blas_thread():
            proba = self.classifier_.predict_proba(
                (self._features(X) - self._x_loc) / self._x_scale
            )
        return proba[:, 1]

    def _require_fitted(self) -> None:
        if not hasattr(self, "low_model_"):
            raise NotFittedError(
                "this ModeSwitchingGPRegressor is not fitted yet; call fit() first"
            )

    def _features(self, X: np.ndarray) -> np.ndarray:
        return (
            X
            if self.classifier_features is None
            else np.asarray(self.classifier_features(X), float)
        )

    def components(self, X):
        """Both modes of every output: ``(p_high, low, high)``.

        ``low``/``high`` are ``(mean, latent_std, noise_std)`` with arrays (n, n_outputs); the
        non-switching outputs repeat the low-mode GP in ``high``. A high mode seen fewer than 3
        times has no GP: its mean is the observed mean and its latent std
        :data:`~robovib.gp.bands.UNMODELLED_MODE_RELATIVE_STD` of it.

        Parameters
        ----------
        X : array_like
            (n, d) inputs in the training units.

        Returns
        -------
        p_high : numpy.ndarray
            (n,) probability of the high mode.
        low, high : tuple of numpy.ndarray
            ``(mean, latent_std, noise_std)`` of each mode.
        """
        from .bands import UNMODELLED_MODE_RELATIVE_STD, noise_std_of

        X = self._check_query(X)
        mean, std = self.low_model_.predict(X, return_std=True)
        noise = np.broadcast_to(noise_std_of(self.low_model_.hyperparameters_), mean.shape)
        h_mean, h_std, h_noise = mean.copy(), std.copy(), noise.copy()
        cols = self._switching
        if self.high_model_ is not None:
            m, s = self.high_model_.predict(X, return_std=True)
            h_mean[:, cols], h_std[:, cols] = m, s
            h_noise[:, cols] = noise_std_of(self.high_model_.hyperparameters_)
        elif self._high_mean is not None:
            h_mean[:, cols] = self._high_mean
            h_std[:, cols] = UNMODELLED_MODE_RELATIVE_STD * np.abs(self._high_mean)
            h_noise[:, cols] = 0.0
        p = self.high_mode_probability(X)
        return p, (mean, std, noise), (h_mean, h_std, h_noise)

    def predict(self, X, return_std: bool = False):
        """Mean (and std) of every output; switching outputs from the more probable mode.

        Parameters
        ----------
        X : array_like
            (n, d) inputs in the training units.
        return_std : bool
            Also return the latent std.

        Returns
        -------
        mean : numpy.ndarray
            (n, n_outputs) means.
        std : numpy.ndarray
            (n, n_outputs) latent std (only with ``return_std``).
        """
        X = self._check_query(X)
        mean, std = self.low_model_.predict(X, return_std=True)
        use_high = self.high_mode_probability(X) > 0.5
        if np.any(use_high):
            cols = self._switching
            if self.high_model_ is not None:
                h_mean, h_std = self.high_model_.predict(X[use_high], return_std=True)
            else:
                h_mean = np.tile(self._high_mean, (int(use_high.sum()), 1))
                h_std = np.full_like(h_mean, np.nan)
            mean[np.ix_(use_high, cols)] = h_mean
            std[np.ix_(use_high, cols)] = h_std
        return (mean, std) if return_std else mean
