"""The chapter-3 study: GPR of the dominant modal parameters over the workspace (thesis §3.3).

:func:`chapter3_study` fits the 9 modal outputs of Table A1 (natural frequency, stiffness and
damping coefficient in X, Y, Z) as functions of the pose (X, Y, Rz), and reports

* 5-fold cross-validation, plain (the thesis' protocol, Table 2) and grouped by pose (honest:
  the replicates of a test pose are never in the training folds);
* the 2nd-order MLR baseline, in-sample (what the thesis' Table 2 MLR row matches) and
  cross-validated;
* external validation on Table A2.

By default (``mode_switch=True``) the X-direction outputs are modelled with
:class:`~robovib.gp.mode_switch.ModeSwitchingGPRegressor`: the ~63 Hz mode that dominates at full
extension with Rz = 0°/180° is classified, not smoothed over (a smooth GP predicts 40 Hz modes
that exist nowhere between X = 2400 and 2700 mm). ``mode_switch=False`` gives the thesis' single
GP per output.

All figures are in the thesis' units (Hz, MN/m, kN·s/m) so they can be set beside Table 2.
The models fitted here are the thesis-unit regressors (:func:`make_chapter3_regressor`); the
SI pose model for applications is :func:`robovib.gp.fit_chapter3_model` /
:func:`robovib.gp.load_chapter3_model`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
import pandas as pd
from sklearn.base import clone

from ..datasets import (
    DIRECTIONS,
    MODAL_QUANTITIES,
    X_HIGH_MODE_THRESHOLD_HZ,
    load_reference_table,
    load_table_a1,
    load_table_a2,
    modal_output_columns,
    pose_columns,
)
from ..gp.mode_switch import ModeSwitchingGPRegressor, symmetric_rz_features
from ..gp.regressor import BatchedGPRegressor
from ..gp.validation import (
    PolynomialRegression,
    cross_validate,
    external_validation,
    regression_scores,
)

__all__ = [
    "OUTPUT_LABELS",
    "Chapter3Study",
    "chapter3_study",
    "fit_chapter3_regressor",
    "make_chapter3_regressor",
]

#: Short labels of the 9 outputs in Table-2 order, with the thesis' units.
OUTPUT_LABELS: tuple[str, ...] = tuple(
    f"{d.upper()} {q}" for d in DIRECTIONS for q in ("fn [Hz]", "k [MN/m]", "c [kN·s/m]")
)
_TABLE2_NAMES = [f"{q}_{d}" for d in DIRECTIONS for q in MODAL_QUANTITIES]


@dataclass(frozen=True)
class Chapter3Study:
    """Per-output figures of the chapter-3 study (arrays of length 9, Table-2 order).

    Attributes
    ----------
    outputs
        The 9 output names.
    thesis_gpr_r2, thesis_gpr_rmse, thesis_mlr_r2, thesis_mlr_rmse
        Thesis Table 2 (targets to compare with).
    gpr_plain_r2, gpr_plain_rmse
        GPR cross-validation with replicates of a pose in the training folds (thesis protocol).
    gpr_grouped_r2, gpr_grouped_rmse
        GPR cross-validation holding out whole poses.
    mlr_insample_r2, mlr_insample_rmse, mlr_cv_r2, mlr_cv_rmse
        The 2nd-order MLR baseline, in sample and cross-validated.
    external_rmse, external_mean_relative_error, external_max_relative_error
        External validation on Table A2.
    n_iter
        Optimiser iterations per output.
    settings
        Settings of the run.
    """

    outputs: tuple[str, ...]
    thesis_gpr_r2: np.ndarray
    thesis_gpr_rmse: np.ndarray
    thesis_mlr_r2: np.ndarray
    thesis_mlr_rmse: np.ndarray
    gpr_plain_r2: np.ndarray
    gpr_plain_rmse: np.ndarray
    gpr_grouped_r2: np.ndarray
    gpr_grouped_rmse: np.ndarray
    mlr_insample_r2: np.ndarray
    mlr_insample_rmse: np.ndarray
    mlr_cv_r2: np.ndarray
    mlr_cv_rmse: np.ndarray
    external_rmse: np.ndarray
    external_mean_relative_error: np.ndarray
    external_max_relative_error: np.ndarray
    n_iter: np.ndarray
    settings: dict

    def to_frame(self) -> pd.DataFrame:
        """One row per output, one column per figure (thesis units: Hz, MN/m, kN·s/m).

        Returns
        -------
        pandas.DataFrame
            The figures.
        """
        data = {k: v for k, v in self.__dict__.items() if isinstance(v, np.ndarray)}
        return pd.DataFrame(data, index=list(self.outputs))

    def to_dict(self) -> dict:
        """JSON-ready: settings, units and one record per output.

        Returns
        -------
        dict
            The study as plain JSON types.
        """
        return {
            "settings": dict(self.settings),
            "units": {"fn": "Hz", "stiffness": "MN/m", "damping": "kN*s/m", "rmse": "output units"},
            "outputs": self.to_frame().reset_index(names="output").to_dict(orient="records"),
        }


def _training_data(stiffness_reading: str):
    a1 = load_table_a1(units="thesis", stiffness_reading=stiffness_reading)
    X = a1[pose_columns("thesis")].to_numpy()
    Y = a1[modal_output_columns("thesis")].to_numpy()
    return a1, X, Y, np.isfinite(Y)


def make_chapter3_regressor(
    kernel: Literal["isotropic", "ard"] = "ard",
    mode_switch: bool = True,
    rng: int | np.random.Generator | None = 0,
) -> BatchedGPRegressor | ModeSwitchingGPRegressor:
    """An unfitted 9-output regressor in thesis units (Table-2 order, X outputs first).

    Parameters
    ----------
    kernel : {"ard", "isotropic"}
        One length scale per input, or the thesis' isotropic kernel (Eq. 7).
    mode_switch : bool
        Classify the X-direction dominant-mode switch instead of smoothing over it.
    rng : int or numpy.random.Generator, optional
        Seed of the optimiser restarts.

    Returns
    -------
    BatchedGPRegressor or ModeSwitchingGPRegressor
        The unfitted regressor.
    """
    if mode_switch:
        return ModeSwitchingGPRegressor(
            switching_outputs=(0, 1, 2),
            indicator_output=0,
            threshold=X_HIGH_MODE_THRESHOLD_HZ,
            classifier_features=symmetric_rz_features,
            kernel=kernel,
            rng=rng,
        )
    return BatchedGPRegressor(kernel=kernel, rng=rng)


def fit_chapter3_regressor(
    kernel: Literal["isotropic", "ard"] = "ard",
    mode_switch: bool = True,
    stiffness_reading: Literal["corrected", "printed"] = "corrected",
    rng: int | np.random.Generator | None = 0,
) -> BatchedGPRegressor | ModeSwitchingGPRegressor:
    """The 9-output regressor of Table A1 over (X [mm], Y [mm], Rz [deg]), thesis units.

    Parameters
    ----------
    kernel : {"ard", "isotropic"}
        One length scale per input, or the thesis' isotropic kernel (Eq. 7).
    mode_switch : bool
        Classify the X-direction dominant-mode switch instead of smoothing over it.
    stiffness_reading : {"corrected", "printed"}
        Reading of Table A1's shifted stiffness cells.
    rng : int or numpy.random.Generator, optional
        Seed of the optimiser restarts.

    Returns
    -------
    BatchedGPRegressor or ModeSwitchingGPRegressor
        The fitted regressor.
    """
    _, X, Y, mask = _training_data(stiffness_reading)
    return make_chapter3_regressor(kernel, mode_switch, rng).fit(X, Y, mask=mask)


def chapter3_study(
    kernel: Literal["isotropic", "ard"] = "ard",
    n_splits: int = 5,
    stiffness_reading: Literal["corrected", "printed"] = "corrected",
    mode_switch: bool = True,
    rng: int = 0,
) -> Chapter3Study:
    """Run the chapter-3 validation study on the shipped Table A1/A2 data.

    Parameters
    ----------
    kernel
        ``"ard"`` (default: one length scale per input) or ``"isotropic"`` (thesis Eq. 7).
    n_splits
        Folds of the cross-validation (thesis: 5).
    stiffness_reading
        Reading of Table A1's shifted stiffness cells (see :func:`robovib.datasets.load_table_a1`).
    mode_switch
        Classify the X-direction dominant-mode switch (default) instead of smoothing over it.
    rng
        Seed of the fold shuffles and the optimiser restarts.

    Returns
    -------
    Chapter3Study
        Per-output figures beside thesis Table 2.
    """
    a1, X, Y, mask = _training_data(stiffness_reading)

    gp = make_chapter3_regressor(kernel, mode_switch, rng)
    plain = cross_validate(gp, X, Y, n_splits=n_splits, mask=mask, rng=rng)
    grouped = cross_validate(
        gp, X, Y, n_splits=n_splits, mask=mask, pose_groups=a1["test"].to_numpy(), rng=rng
    )
    mlr = PolynomialRegression(degree=2).fit(X, Y, mask=mask)
    mlr_in_r2, _, mlr_in_rmse = regression_scores(np.where(mask, Y, np.nan), mlr.predict(X), mask)
    mlr_cv = cross_validate(PolynomialRegression(2), X, Y, n_splits=n_splits, mask=mask, rng=rng)

    model = clone(gp).fit(X, Y, mask=mask)
    a2 = load_table_a2(units="thesis")
    ext = external_validation(
        model, a2[pose_columns("thesis")].to_numpy(), a2[modal_output_columns("thesis")].to_numpy()
    )

    t2 = load_reference_table(2)

    def thesis(model_name, metric):
        sel = t2[(t2["model"] == model_name) & (t2["metric"] == metric)].set_index("output")
        return sel.loc[_TABLE2_NAMES, "value"].to_numpy()

    return Chapter3Study(
        outputs=OUTPUT_LABELS,
        thesis_gpr_r2=thesis("GPR", "r2"),
        thesis_gpr_rmse=thesis("GPR", "rmse"),
        thesis_mlr_r2=thesis("MLR", "r2"),
        thesis_mlr_rmse=thesis("MLR", "rmse"),
        gpr_plain_r2=plain.r2,
        gpr_plain_rmse=plain.rmse,
        gpr_grouped_r2=grouped.r2,
        gpr_grouped_rmse=grouped.rmse,
        mlr_insample_r2=mlr_in_r2,
        mlr_insample_rmse=mlr_in_rmse,
        mlr_cv_r2=mlr_cv.r2,
        mlr_cv_rmse=mlr_cv.rmse,
        external_rmse=ext.rmse,
        external_mean_relative_error=ext.mean_relative_error,
        external_max_relative_error=ext.max_relative_error,
        n_iter=model.low_model_.n_iter_ if mode_switch else model.n_iter_,
        settings={
            "kernel": kernel,
            "n_splits": n_splits,
            "stiffness_reading": stiffness_reading,
            "mode_switch": mode_switch,
            "seed": rng,
            "inputs": ["x_mm", "y_mm", "rz_deg"],
            "n_training_rows": int(X.shape[0]),
        },
    )
