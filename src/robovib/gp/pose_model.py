"""The pose model: dominant modal parameters per direction as GPs of the pose (thesis §3.3).

:class:`PoseModalModel` is the one type every consumer of a pose model takes (milling, control,
the CLI): the chapter-3 model of Table A1 over ``(x_mm, y_mm, rz_deg)``, the chapter-4 path model
over ``(s_m,)`` and any model a user fits to their own robot are all instances of it.

For each direction it models the natural frequency ``fn`` [Hz], the modal stiffness ``k``
[N/m] and the damping coefficient ``c`` [N·s/m] of the dominant mode (SI inside and out) with
exact GPs (thesis Eq. 6-10, :class:`~robovib.gp.BatchedGPRegressor`).

Mode switches
-------------
Where another mode of the arm becomes the dominant one (Table A1: 61-65 Hz in X at full
extension next to 15-23 Hz elsewhere), a smooth GP averages the two and predicts modes that
exist nowhere. With ``mode_switch="auto"`` the model first *tests* each direction for a switch
(:func:`detect_mode_switch`) and, only where it finds one, models that direction with
:class:`~robovib.gp.mode_switch.ModeSwitchingGPRegressor` (a GP classifier of which mode
dominates plus one GP per mode). The detection rule, on ``log fn`` of the observed samples:

1. a 2-component 1-D Gaussian mixture beats 1 component by ``ΔBIC = BIC₁ − BIC₂ ≥ 10``
   ("very strong" evidence on the Kass-Raftery scale);
2. the two components are separated: Ashman's ``D = √2 |μ₁ − μ₂| / √(σ₁² + σ₂²) ≥ 3``;
3. the data have an empty gap between the modes at least 3 times the larger within-mode
   standard deviation of ``log fn`` (so a skewed or merely clustered cloud, as Table A1's Z
   frequencies at 9-11 Hz, is not called a switch);
4. the low mode has at least 3 samples. A high mode seen at 1-2 samples is still modelled
   (classified, a constant with a wide band, no GP of its own) rather than blended into the
   low mode; ``robovib model fit`` warns that it is too few to model.

The threshold between the modes is the geometric midpoint of the gap. The outcome per
direction is kept in ``mode_switches_``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
from sklearn.base import BaseEstimator
from sklearn.exceptions import NotFittedError

from . import _h5
from .bands import ModalPredictive, noise_std_of
from .contract import PosePredictionSide
from .covariances import COVARIANCES
from .dominant_modes import PoseMode
from .extrapolation import TrainingRegion
from .mode_switch import ModeSwitchDetection, ModeSwitchingGPRegressor, detect_mode_switch
from .pose_file import FORMAT, FORMAT_VERSION, _RzCos2
from .regressor import BatchedGPRegressor

__all__ = [
    "FORMAT",
    "FORMAT_VERSION",
    "ModeSwitchDetection",
    "PoseModalModel",
    "PoseMode",
    "detect_mode_switch",
]


_QUANTITIES = (("fn", "hz"), ("stiffness", "n_per_m"), ("damping", "ns_per_m"))
_UNIT_LABELS = {"hz": "Hz", "n_per_m": "N/m", "ns_per_m": "N*s/m"}


def _unit_of(name: str) -> str:
    if "_" not in name.strip("_"):
        raise ValueError(
            f"input name {name!r} carries no unit: name inputs as <quantity>_<unit>, e.g. 'x_mm'"
        )
    return name.rsplit("_", 1)[1]


# ---------------------------------------------------------------------------------- the model
class PoseModalModel(PosePredictionSide, BaseEstimator):
    """Dominant modal parameters (fn, k, c) per direction as functions of the pose.

    Parameters
    ----------
    input_names
        Names of the input columns with their unit as suffix (``"x_mm"``, ``"rz_deg"``,
        ``"s_m"``); ``X`` is given in those units.
    directions
        Directions modelled; ``Y`` has 3 columns per direction. A multi-mode model uses mode
        ids as directions (``x1``, ``x2``, ``y1``: :func:`robovib.campaign.fit_multimode_pose_model`).
    kernel : {"ard", "isotropic"}
        The length scales (not the covariance family, which is ``covariance``): ``"ard"``
        (automatic relevance determination: one length scale per input) or ``"isotropic"``
        (thesis Eq. 7: one length scale shared by all inputs).
    mode_switch
        ``"auto"``: test each direction for a switch of the dominant mode and model it where
        found (:func:`detect_mode_switch`); ``True``: the same, but fitting fails when no switch
        is found; ``False``: one smooth GP per output (the thesis); a mapping
        ``{direction: threshold_hz}``: assume a switch at that frequency, untested.
    rng
        Seed of the optimiser restarts and of the classifier's optimiser.
    rz_symmetric
        The mode classifier sees cos(2 Rz) instead of ``rz_deg`` (Rz and Rz + 180° give the
        same configuration of the arm, as on Table A1). Needs an input named ``"rz_deg"``.
    covariance : {"se", "matern52", "matern32", "auto"}
        The covariance family of the GPs (:mod:`robovib.gp.covariances`; the length scales are
        ``kernel``): ``"se"`` (squared exponential, thesis Eq. 7),
        ``"matern52"``, ``"matern32"`` or ``"auto"``: chosen per output by the grouped-CV log
        predictive density (needs ``calibrate=True``).
    calibrate
        Calibrate the bands by grouped cross-validation (:mod:`robovib.gp.calibration`): a
        Student-t scale and tail per output and mode, stored in ``calibration_``. Costs
        ``calibration_folds`` extra fits per covariance family tried. ``False``: the plain GP
        posterior (fast; what the thesis reports).
    calibration_folds
        Folds of that grouped cross-validation (poses held out with all their replicates).

    Attributes
    ----------
    output_names_ : tuple of str
        ``"<direction>_fn_hz"``, ``"<direction>_stiffness_n_per_m"``,
        ``"<direction>_damping_ns_per_m"`` per direction.
    input_units_, output_units_ : tuple of str
    mode_switches_ : dict[str, ModeSwitchDetection]
        Outcome of the mode-switch test per direction.
    estimators_ : list of BatchedGPRegressor / ModeSwitchingGPRegressor
    estimator_columns_ : list of ndarray of int
        Output columns of each estimator.
    X_train_, Y_train_, mask_ : ndarray
        Training data (``Y_train_`` NaN where not observed).
    groups_ : ndarray of int or None
        Noise group of each training sample.
    input_min_, input_max_ : ndarray (n_inputs,)
        Box of the training inputs.
    region_ : TrainingRegion
        Box and hull of the training inputs (:meth:`extrapolating`).
    calibration_ : BandCalibration or None
        The band calibration and its grouped-CV scores (``calibrate=True``), else None.
    covariances_ : tuple of str
        Covariance family used for each output.

    Notes
    -----
    Noise groups are given per sample as ``groups`` (as everywhere in robovib).

    Examples
    --------
    >>> from robovib.gp import load_chapter3_model
    >>> model = load_chapter3_model()
    >>> model.output_names_[:3]
    ('x_fn_hz', 'x_stiffness_n_per_m', 'x_damping_ns_per_m')
    """

    def __init__(
        self,
        input_names: Sequence[str] = ("x_mm", "y_mm", "rz_deg"),
        directions: Sequence[str] = ("x", "y", "z"),
        kernel: str = "ard",
        mode_switch: str | bool | Mapping[str, float] = "auto",
        rng: int | np.random.Generator | None = 0,
        rz_symmetric: bool = False,
        covariance: str = "se",
        calibrate: bool = False,
        calibration_folds: int = 5,
    ) -> None:
        self.input_names = input_names
        self.directions = directions
        self.kernel = kernel
        self.mode_switch = mode_switch
        self.rng = rng
        self.rz_symmetric = rz_symmetric
        self.covariance = covariance
        self.calibrate = calibrate
        self.calibration_folds = calibration_folds

    # ------------------------------------------------------------------ validation
    def _check_params(self) -> tuple[tuple[str, ...], tuple[str, ...]]:
        names = tuple(self.input_names)
        dirs = tuple(self.directions)
        if not names or not all(isinstance(n, str) for n in names) or len(set(names)) != len(names):
            raise ValueError(f"input_names must be unique strings, got {self.input_names!r}")
        for n in names:
            _unit_of(n)
        if (
            not dirs
            or not all(isinstance(d, str) and d for d in dirs)
            or len(set(dirs)) != len(dirs)
        ):
            raise ValueError(
                f"directions must be unique non-empty strings, got {self.directions!r}"
            )
        if self.kernel not in ("isotropic", "ard"):
            raise ValueError(f"unknown kernel {self.kernel!r}; expected 'isotropic' or 'ard'")
        ms = self.mode_switch
        if isinstance(ms, Mapping):
            unknown = set(ms) - set(dirs)
            if unknown:
                raise ValueError(f"mode_switch names unknown directions {sorted(unknown)}")
            for d, thr in ms.items():
                if not (np.isfinite(thr) and thr > 0):
                    raise ValueError(f"mode_switch threshold of {d!r} must be > 0 Hz, got {thr!r}")
        elif not (ms is True or ms is False or ms == "auto"):
            raise ValueError(
                f"unknown mode_switch {ms!r}; expected 'auto', True, False or "
                "{direction: threshold_hz}"
            )
        if self.rz_symmetric and "rz_deg" not in names:
            raise ValueError("rz_symmetric=True needs an input named 'rz_deg'")
        if self.covariance not in (*COVARIANCES, "auto"):
            raise ValueError(
                f"unknown covariance {self.covariance!r}; expected one of {(*COVARIANCES, 'auto')}"
            )
        if self.covariance == "auto" and not self.calibrate:
            raise ValueError("covariance='auto' chooses by grouped CV: it needs calibrate=True")
        if int(self.calibration_folds) < 2:
            raise ValueError(f"calibration_folds must be >= 2, got {self.calibration_folds}")
        return names, dirs

    def _require_fitted(self) -> None:
        if not hasattr(self, "estimators_"):
            raise NotFittedError("this PoseModalModel is not fitted yet; call fit() first")

    # ------------------------------------------------------------------ fitting
    def fit(self, X, Y, mask=None, groups=None) -> PoseModalModel:
        """Fit the GPs (and, where a switch is found, classifiers) of every output.

        Parameters
        ----------
        X
            (n, n_inputs) poses in the units named by ``input_names``.
        Y
            (n, 3 * n_directions) SI targets, per direction in the order
            ``[fn_hz, stiffness_n_per_m, damping_ns_per_m]``; NaN where not observed.
        mask
            Optional (n, 3 * n_directions) bool, ``True`` where observed (default: finite ``Y``).
        groups
            Optional (n,) int >= 0: noise group of each sample (e.g. 0 = hammer, 1 = OMA).

        Returns
        -------
        self

        Raises
        ------
        ValueError
            On bad shapes, NaN/inf inputs, non-positive fn or k, negative c, bad parameters, or
            ``mode_switch=True`` when no switch is found.

        Examples
        --------
        >>> import numpy as np
        >>> from robovib.gp import PoseModalModel
        >>> rng = np.random.default_rng(0)
        >>> X = rng.uniform([2100, -300, 0], [2700, 600, 90], (30, 3))
        >>> Y = np.column_stack([15 + X[:, 0] / 1e3, 2e6 + 1e3 * X[:, 1], 400 + X[:, 2]])
        >>> model = PoseModalModel(directions=("x",), mode_switch=False).fit(X, Y)
        >>> model.predict(X[:2]).shape
        (2, 3)
        """
        names, dirs = self._check_params()
        X, Y, mask, obs, groups = self._validated(X, Y, mask, groups, names, dirs)
        self.mode_switches_ = self._detect(obs, mask, dirs, X)
        if self.mode_switch is True and not any(s.found for s in self.mode_switches_.values()):
            raise ValueError(
                "mode_switch=True but no direction shows a mode switch: "
                + "; ".join(f"{d}: {s.reason}" for d, s in self.mode_switches_.items())
                + " (use mode_switch='auto' to fit without one)"
            )
        n_out = 3 * len(dirs)
        families = COVARIANCES if self.covariance == "auto" else (self.covariance,)
        self.calibration_ = None
        chosen = (families[0],) * n_out
        if self.calibrate:
            chosen, self.calibration_ = self._calibrate(X, obs, mask, groups, families)
        self._fit_estimators(X, Y, mask, groups, names, dirs, chosen)
        self.covariances_ = tuple(chosen)
        self._set_fitted(names, dirs, X, np.where(mask, Y, np.nan), mask, groups)
        return self

    def _fit_estimators(self, X, Y, mask, groups, names, dirs, chosen) -> None:
        """One GP per covariance family over the smooth outputs, one switching GP per switch."""
        n_groups = 1 if groups is None else int(groups.max()) + 1
        features = _RzCos2(names.index("rz_deg")) if self.rz_symmetric else None
        switching = [i for i, d in enumerate(dirs) if self.mode_switches_[d].found]
        self.estimators_, self.estimator_columns_ = [], []
        smooth = [3 * i + j for i in range(len(dirs)) if i not in switching for j in range(3)]
        for family in dict.fromkeys(chosen[c] for c in smooth):
            cols = [c for c in smooth if chosen[c] == family]
            gp = BatchedGPRegressor(
                kernel=self.kernel, rng=self.rng, n_noise_groups=n_groups, covariance=family
            )
            gp.fit(X, Y[:, cols], mask=mask[:, cols], groups=groups)
            self.estimators_.append(gp)
            self.estimator_columns_.append(np.array(cols))
        for i in switching:
            cols = np.arange(3 * i, 3 * i + 3)
            msgp = ModeSwitchingGPRegressor(
                switching_outputs=(0, 1, 2),
                indicator_output=0,
                threshold=self.mode_switches_[dirs[i]].threshold_hz,
                classifier_features=features,
                kernel=self.kernel,
                rng=self.rng,
                n_noise_groups=n_groups,
                covariance=chosen[3 * i],
            )
            msgp.fit(
                X, np.where(mask[:, cols], Y[:, cols], np.nan), mask=mask[:, cols], groups=groups
            )
            self.estimators_.append(msgp)
            self.estimator_columns_.append(cols)
        self._set_fitted(names, dirs, X, np.where(mask, Y, np.nan), mask, groups)

    def _thresholds(self) -> np.ndarray:
        """(n_outputs,) mode threshold of each output's direction (NaN without a switch)."""
        return np.array(
            [
                self.mode_switches_[d].threshold_hz if self.mode_switches_[d].found else np.nan
                for d in self.directions_
                for _ in range(3)
            ]
        )

    def _calibrate(self, X, obs, mask, groups, families):
        """Grouped-CV predictions per covariance family -> chosen family and band calibration."""
        import warnings

        from sklearn.base import clone

        from .calibration import (
            BandCalibration,
            calibrate_mode_probabilities,
            calibrate_predictions,
            grouped_folds,
            scores,
            uncalibrated_coverage,
        )

        dirs = tuple(self.directions)
        n_out = 3 * len(dirs)
        fold = grouped_folds(
            X, self.calibration_folds, self.rng if isinstance(self.rng, int) else 0
        )
        thresholds = np.array(
            [
                self.mode_switches_[d].threshold_hz if self.mode_switches_[d].found else np.nan
                for d in dirs
                for _ in range(3)
            ]
        )
        Y = np.where(mask, obs, np.nan)
        results = {}
        for family in families:
            template = clone(self).set_params(
                covariance=family, calibrate=False, mode_switch=self._fold_mode_switch()
            )
            parts = []
            for f in np.unique(fold):
                tr, te = fold != f, fold == f
                with warnings.catch_warnings():
                    warnings.simplefilter(
                        "ignore"
                    )  # fold fits of few poses warn; the final fit speaks
                    m = clone(template).fit(
                        X[tr], Y[tr], mask=mask[tr], groups=None if groups is None else groups[tr]
                    )
                parts.append((te, m._raw_predictive(X[te])))
            pred = _stack_predictive(parts, X.shape[0])
            logit = calibrate_mode_probabilities(pred, Y, thresholds)
            scale, dof, gamma, ref = calibrate_predictions(pred, Y, thresholds)
            cal = pred.with_calibration(scale, dof, gamma, ref, logit)
            results[family] = (pred, cal, (scale, dof, gamma, ref, logit), scores(cal, Y))
        # Per output (per direction where a switch ties the three outputs): best mean LPD.
        lpd = {f: -r[3]["nlpd"] for f, r in results.items()}
        chosen = []
        for i, d in enumerate(dirs):
            cols = slice(3 * i, 3 * i + 3)
            if self.mode_switches_[d].found:
                best = max(families, key=lambda f: float(np.sum(lpd[f][cols])))
                chosen += [best] * 3
            else:
                chosen += [
                    max(families, key=lambda f: float(lpd[f][j])) for j in range(3 * i, 3 * i + 3)
                ]
        scale, dof, gamma, ref, logit = (
            np.array([results[chosen[j]][2][i][j] for j in range(n_out)]) for i in range(5)
        )
        sc = {
            k: np.array([results[chosen[j]][3][k][j] for j in range(n_out)])
            for k in ("n", "coverage", "nlpd", "rmse")
        }
        pit = np.column_stack([results[chosen[j]][3]["pit"][:, j] for j in range(n_out)])
        uncal = np.array([uncalibrated_coverage(results[chosen[j]][0], Y)[j] for j in range(n_out)])
        names = tuple(f"{d}_{q}_{u}" for d in dirs for q, u in _QUANTITIES)
        calibration = BandCalibration(
            output_names=names,
            covariance=tuple(chosen),
            scale=scale,
            dof=dof,
            gamma=gamma,
            ref_std=ref,
            mode_logit=logit,
            n_folds=int(np.unique(fold).size),
            n_poses=int(np.unique(np.round(X, 9), axis=0).shape[0]),
            n=sc["n"].astype(int),
            coverage=sc["coverage"],
            coverage_uncalibrated=uncal,
            nlpd=sc["nlpd"],
            rmse=sc["rmse"],
            lpd_by_covariance={f: v for f, v in lpd.items()},
            pit=pit,
        )
        return tuple(chosen), calibration

    def _fold_mode_switch(self):
        """The switch setting of the CV folds: the thresholds found on all data, assumed."""
        found = {d: s.threshold_hz for d, s in self.mode_switches_.items() if s.found}
        return found if found else False

    @staticmethod
    def _validated(X, Y, mask, groups, names, dirs):
        """Checked (X, Y, mask, Y with NaN where unobserved, groups) of fit/update."""
        X = np.asarray(X, float)
        Y = np.asarray(Y, float)
        n_out = 3 * len(dirs)
        if X.ndim == 1 and len(names) == 1:
            X = X[:, None]
        if X.ndim != 2 or X.shape[1] != len(names):
            raise ValueError(
                f"X must be (n, {len(names)}) with columns {list(names)}, got {X.shape}"
            )
        if Y.ndim != 2 or Y.shape != (X.shape[0], n_out):
            raise ValueError(
                f"Y must be (n, {n_out}) = [fn_hz, stiffness_n_per_m, damping_ns_per_m] per "
                f"direction {list(dirs)} for the {X.shape[0]} poses, got shape {Y.shape}"
            )
        if not np.all(np.isfinite(X)):
            raise ValueError(f"X contains NaN or inf (columns {list(names)})")
        mask = np.isfinite(Y) if mask is None else np.asarray(mask, bool)
        if mask.shape != Y.shape:
            raise ValueError(f"mask shape {mask.shape} does not match Y shape {Y.shape}")
        if not np.all(np.isfinite(Y[mask])):
            raise ValueError("Y contains NaN or inf at observed entries; mark them mask=False")
        obs = np.where(mask, Y, np.nan)
        for i, d in enumerate(dirs):
            for j, (q, unit) in enumerate(_QUANTITIES):
                col = obs[:, 3 * i + j]
                bad = col <= 0 if q != "damping" else col < 0
                if np.any(bad & mask[:, 3 * i + j]):
                    raise ValueError(
                        f"{d}_{q}_{unit} must be {'>= 0' if q == 'damping' else '> 0'} "
                        f"{_UNIT_LABELS[unit]} (SI) at every observed sample"
                    )
        if groups is not None:
            groups = np.asarray(groups)
            if groups.shape != (X.shape[0],) or not np.issubdtype(groups.dtype, np.integer):
                raise ValueError(f"groups must be an integer array of shape ({X.shape[0]},)")
            if np.any(groups < 0):
                raise ValueError("groups must be >= 0")
            groups = groups.astype(int)
        return X, Y, mask, obs, groups

    def update(
        self, X_new, Y_new, mask=None, groups=None, *, mode: str = "posterior"
    ) -> PoseModalModel:
        """Bayesian update with new poses (the one name for updating in robovib, thesis §5.2.4).

        Parameters
        ----------
        X_new, Y_new, mask, groups
            As in :meth:`fit` (same inputs, directions and SI columns).
        mode
            ``"posterior"``: every hyperparameter kept, posterior recomputed with the enlarged
            data (Eq. 9-10); ``"warm"``: hyperparameters re-optimised from the current ones.

        Returns
        -------
        self

        Notes
        -----
        The mode-switch test is not re-run: ``mode_switches_`` stays as fitted (call
        :meth:`fit` on all data to re-test). In a direction with a switch, new samples are
        assigned to a mode by its threshold.

        Raises
        ------
        NotFittedError, ValueError
        """
        self._require_fitted()
        if mode not in ("posterior", "warm"):
            raise ValueError(f"unknown update mode {mode!r}; expected 'posterior' or 'warm'")
        names, dirs = self.input_names_, self.directions_
        X_new, Y_new, mask, obs, groups = self._validated(X_new, Y_new, mask, groups, names, dirs)
        n_groups = int(self.estimators_[0].n_noise_groups)
        if groups is not None and int(groups.max()) >= n_groups:
            raise ValueError(
                f"groups must be in [0, {n_groups}): the model was fitted with {n_groups} "
                "noise group(s)"
            )
        if groups is None and self.groups_ is not None:
            groups = np.zeros(X_new.shape[0], int)
        for est, cols in zip(self.estimators_, self.estimator_columns_, strict=True):
            m = mask[:, cols]
            if isinstance(est, ModeSwitchingGPRegressor):
                est.update(X_new, obs[:, cols], m, groups=groups, mode=mode)
            else:
                est.update(X_new, np.where(m, Y_new[:, cols], 0.0), m, groups=groups, mode=mode)
        old_groups = self.groups_
        if groups is not None and old_groups is None:
            old_groups = np.zeros(self.X_train_.shape[0], int)
        self._set_fitted(
            names,
            dirs,
            np.vstack([self.X_train_, X_new]),
            np.vstack([self.Y_train_, obs]),
            np.vstack([self.mask_, mask]),
            None if groups is None else np.concatenate([old_groups, groups]),
        )
        return self

    def _detect(self, obs, mask, dirs, X=None) -> dict[str, ModeSwitchDetection]:
        nan = float("nan")
        out = {}
        for i, d in enumerate(dirs):
            fn = obs[mask[:, 3 * i], 3 * i]
            if isinstance(self.mode_switch, Mapping):
                if d in self.mode_switch:
                    thr = float(self.mode_switch[d])
                    n_high = int(np.sum(fn > thr))
                    out[d] = ModeSwitchDetection(
                        d, True, True, thr, nan, nan, nan, fn.size - n_high, n_high,
                        f"assumed by the user at {thr:g} Hz",
                    )  # fmt: skip
                else:
                    out[d] = ModeSwitchDetection(
                        d, False, True, nan, nan, nan, nan, fn.size, 0, "none assumed by the user"
                    )
            elif self.mode_switch is False:
                out[d] = ModeSwitchDetection(
                    d,
                    False,
                    False,
                    nan,
                    nan,
                    nan,
                    nan,
                    fn.size,
                    0,
                    "not tested (mode_switch=False)",
                )
            else:
                out[d] = detect_mode_switch(
                    fn, direction=d, poses=None if X is None else X[mask[:, 3 * i]]
                )
        return out

    def _set_fitted(self, names, dirs, X, Y, mask, groups) -> None:
        self.input_names_ = names
        self.directions_ = dirs
        self.input_units_ = tuple(_unit_of(n) for n in names)
        self.output_names_ = tuple(f"{d}_{q}_{u}" for d in dirs for q, u in _QUANTITIES)
        self.output_units_ = tuple(_UNIT_LABELS[u] for _ in dirs for _, u in _QUANTITIES)
        self.X_train_, self.Y_train_, self.mask_, self.groups_ = X, Y, mask, groups
        self.n_features_in_ = X.shape[1]
        self.n_outputs_ = Y.shape[1]
        self.region_ = TrainingRegion.of(X)
        self.input_min_, self.input_max_ = self.region_.lo, self.region_.hi

    # ------------------------------------------------------------------ prediction
    # The prediction side (predict, predictive, modes, mode_set, samples, bands,
    # extrapolating, ...) is the contract's, shared with the SciPy-free PosePredictor.
    def _prediction_parts(self) -> list:
        return [
            (_FittedSwitching(est) if isinstance(est, ModeSwitchingGPRegressor) else _FittedGP(est),
             cols)
            for est, cols in zip(self.estimators_, self.estimator_columns_, strict=True)
        ]  # fmt: skip

    def gp_posteriors(self) -> list:
        """Every GP of the model: ``(posterior, noise_std, signal_std, columns, mode)``.

        As :meth:`robovib.gp.saved_model.PosePredictor.gp_posteriors` (same order, same numbers):
        ``noise_std`` and ``signal_std`` (B,) in data units (the reference noise group),
        ``columns`` the model outputs of the B targets, ``mode`` 0 for the low (or only) mode
        and 1 for the high mode of a switching direction.

        Returns
        -------
        list of tuple
            ``(posterior, noise_std, signal_std, columns, mode)`` per GP.
        """
        self._require_fitted()
        out = []
        for est, cols in zip(self.estimators_, self.estimator_columns_, strict=True):
            cols = np.asarray(cols, int)
            switching = isinstance(est, ModeSwitchingGPRegressor)
            gps = [(est.low_model_ if switching else est, cols, 0)]
            if switching and est.high_model_ is not None:
                gps.append((est.high_model_, cols[np.asarray(est.switching_outputs, int)], 1))
            for gp, c, mode in gps:
                hp = gp.hyperparameters_
                out.append((gp.posterior_, noise_std_of(hp), np.asarray(hp.signal_std, float),
                            c, mode))  # fmt: skip
        return out

    # ------------------------------------------------------------------ persistence
    def save(self, path, *, cv=None, provenance: Mapping[str, object] | None = None) -> Path:
        """Write the fitted model to HDF5 (no pickle), atomically (temporary file + rename).

        Parameters
        ----------
        path
            Target file (``.h5``).
        cv
            Optional cross-validation figures to keep with the model: a
            :class:`~robovib.gp.validation.CVResult` or a mapping name -> (n_outputs,) array.
            Default: ``self.cv_`` if set.
        provenance
            Optional mapping of strings/numbers (data source, command, script, ...), stored as
            attributes of ``/provenance``. Default: ``self.provenance_`` if set.

        Returns
        -------
        Path of the written file.

        Raises
        ------
        NotFittedError, ValueError

        Examples
        --------
        >>> import tempfile, pathlib
        >>> from robovib.gp import load_chapter3_model
        >>> path = load_chapter3_model().save(pathlib.Path(tempfile.mkdtemp()) / "m.h5")
        >>> path.suffix
        '.h5'
        """
        self._require_fitted()
        cv = getattr(self, "cv_", None) if cv is None else cv
        provenance = getattr(self, "provenance_", None) if provenance is None else provenance
        from ..files.safe_write import atomic_output

        path = Path(path)
        with atomic_output(path) as tmp:  # OutputPathError (a ValueError) names a bad folder
            _h5.write_pose_model(self, tmp, cv=cv, provenance=provenance)
        return path

    @classmethod
    def load(cls, path) -> PoseModalModel:
        """Read a model written by :meth:`save`; predictions match the saved model to ~1e-12.

        Parameters
        ----------
        path : str or os.PathLike
            HDF5 file (format tag ``robovib.PoseModalModel``); never unpickled.

        Returns
        -------
        PoseModalModel
            The fitted model, with ``cv_`` and ``provenance_`` when the file has them.

        Raises
        ------
        ValueError
            If the file is not readable HDF5, not a ``robovib.PoseModalModel`` or of a newer
            format version.

        Examples
        --------
        >>> from robovib.gp import PoseModalModel, load_chapter3_model
        >>> import tempfile, pathlib
        >>> path = pathlib.Path(tempfile.mkdtemp()) / "model.h5"
        >>> _ = load_chapter3_model().save(path)
        >>> PoseModalModel.load(path).input_names
        ('x_mm', 'y_mm', 'rz_deg')
        """
        return _h5.read_pose_model(cls, path)


def _finite_or_nan(v) -> float:
    v = float(v)
    return v if math.isfinite(v) else float("nan")


class _FittedGP:
    """A fitted BatchedGPRegressor as a part of the contract's prediction side."""

    switches_mode = False

    def __init__(self, est: BatchedGPRegressor) -> None:
        self.est = est
        self.noise_std = noise_std_of(est.hyperparameters_)

    def predict(self, X):
        return self.est.predict(X, return_std=True)


class _FittedSwitching:
    """A fitted ModeSwitchingGPRegressor as a part of the contract's prediction side."""

    switches_mode = True

    def __init__(self, est: ModeSwitchingGPRegressor) -> None:
        self.est = est

    def predict(self, X):
        return self.est.predict(X, return_std=True)

    def components(self, X):
        return self.est.components(X)

    def high_mode_probability(self, X):
        return self.est.high_mode_probability(X)


def _stack_predictive(parts, n: int) -> ModalPredictive:
    """Out-of-fold predictions (rows, ModalPredictive) pieced together in row order."""
    first = parts[0][1]
    n_out = first.high_probability.shape[1]
    p = np.zeros((n, n_out))
    mean, lat, noise = (np.zeros((n, n_out, 2)) for _ in range(3))
    for rows, pr in parts:
        p[rows], mean[rows], lat[rows], noise[rows] = (
            pr.high_probability,
            pr.mean,
            pr.latent_std,
            pr.noise_std,
        )
    return ModalPredictive(
        first.output_names, first.output_units, first.directions, p, mean, lat, noise,
        first.scale, first.dof,
    )  # fmt: skip
