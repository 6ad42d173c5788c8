"""Pose model of a user's robot from the campaign's modal table, and where to hammer next.

* :func:`fit_pose_model_from_table` — reads ``modal.csv`` (:func:`process_campaign`), builds
  one training row per pose (and replicate) with ``[fn_hz, stiffness_n_per_m,
  damping_ns_per_m]`` per direction (missing cells masked), fits the pose model
  (:class:`robovib.gp.PoseModalModel`: mode switches detected and modelled) and
  cross-validates it grouped by pose (all replicates of a pose left out together, thesis
  §3.3.2).
* :func:`next_poses` — greedy choice of the candidate poses whose measurement reduces the
  integrated posterior variance over all candidates the most (thesis Eq. 10: the GP variance
  does not depend on the measured values, so the reduction is known before measuring):
  ``sum_j Sigma[j, c]^2 / (Sigma[c, c] + sigma_n^2)``, summed over outputs each normalised by
  its prior variance and weighted by its band calibration ``c²`` (the same calibrated band as
  every prediction), followed by the rank-one update of ``Sigma``.
"""

from __future__ import annotations

import json
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..gp.loader import load_pose_model
from ..gp.pose_model import PoseModalModel
from ..gp.saved_model import PosePrediction, predict_at
from .quality import ModelQualityWarning, model_quality_warnings
from .selection import NextPoses, _gps_of, _posterior_cov, next_poses  # noqa: F401 (re-exported)

__all__ = [
    "NextPoses",
    "PoseModelFit",
    "PosePrediction",
    "fit_pose_model_from_table",
    "load_pose_model",
    "mode_switches_found",
    "next_poses",
    "predict_at",
    "save_pose_model",
]

_OUTPUTS = ("fn_hz", "stiffness_n_per_m", "damping_ns_per_m")
_OUTPUT_UNITS = ("Hz", "N/m", "N*s/m")
_FIT_FLAGS = ("band edge", "residual", "coherence")


@dataclass(frozen=True)
class PoseModelFit:
    """A fitted pose model with its grouped-by-pose cross-validation.

    Attributes
    ----------
    model
        The fitted model (``PoseModalModel`` interface).
    cv_table
        DataFrame, one row per output: ``output``, ``unit``, ``n``, ``rmse`` (in ``unit``),
        ``relative_rmse_pct`` (of the mean), ``r2``, ``mean_std_ratio`` (mean |error|/std).
    X, Y, groups
        Training data (SI outputs) and pose group of each row.
    excluded
        ``(modal.csv row, reason)`` of rows left out (fit flags).
    warnings
        Named warnings on the model's quality and on what the table left out
        (:func:`robovib.campaign.quality.model_quality_warnings`); each is also issued as a
        :class:`~robovib.campaign.quality.ModelQualityWarning`.
    """

    model: object
    cv_table: object
    X: np.ndarray
    Y: np.ndarray
    groups: np.ndarray
    excluded: tuple = field(default=())
    warnings: tuple[str, ...] = field(default=())


def _training_table(table, inputs, directions, use_flagged):
    excluded = []
    if not use_flagged and "flags" in table.columns:
        flags = table["flags"].astype("string").fillna("")
        bad = flags.apply(lambda s: any(f in s for f in _FIT_FLAGS))
        for _, r in table[bad].iterrows():
            excluded.append((int(r.get("row", -1)), str(r["flags"])))
        table = table[~bad]
    rep = table["replicate"] if "replicate" in table.columns else 0
    table = table.assign(_rep=rep)
    key = [*inputs, "_rep"]
    rows = []
    for vals, grp in table.groupby(key, sort=True):
        y = np.full(3 * len(directions), np.nan)
        for j, d in enumerate(directions):
            sel = grp[grp["direction"] == d]
            if len(sel):
                y[3 * j : 3 * j + 3] = sel[list(_OUTPUTS)].mean().to_numpy(float)
        rows.append((np.asarray(vals[:-1], float), y))
    X = np.array([r[0] for r in rows])
    Y = np.array([r[1] for r in rows])
    _, groups = np.unique(np.round(X, 9), axis=0, return_inverse=True)
    return X, Y, np.ravel(groups), tuple(excluded)


def _refuse_constant_outputs(Y, directions, source) -> None:
    """An output with one value at every pose cannot be fitted: name it (not its index)."""
    names = [f"{d} {out}" for d in directions for out in _OUTPUTS]
    const = []
    for j, name in enumerate(names):
        y = Y[np.isfinite(Y[:, j]), j]
        if y.size > 1 and np.ptp(y) <= 1e-12 * max(1.0, float(np.abs(y).max())):
            const.append(f"{name} (= {y[0]:.6g} in all {y.size} rows)")
    if const:
        raise ValueError(
            f"{source}: {'; '.join(const)}: a constant output cannot be fitted by a GP "
            "(a column copied down by hand, or a fit that hit a bound in every row?)"
        )


def _cv_table(model, Y):
    """Grouped-CV table of a calibrated model (its out-of-fold predictions, per output)."""
    import pandas as pd

    cal = model.calibration_
    rows = []
    for j, name in enumerate(cal.output_names):
        y = Y[np.isfinite(Y[:, j]), j]
        ss = float(np.sum((y - y.mean()) ** 2)) if y.size else np.nan
        rmse = float(cal.rmse[j])
        rows.append({
            "output": name, "unit": _OUTPUT_UNITS[j % 3], "n": int(cal.n[j]),
            "rmse": rmse,
            "relative_rmse_pct": 100 * rmse / float(np.mean(y)) if y.size else np.nan,
            "r2": 1 - rmse**2 * y.size / ss if ss > 0 else np.nan,
            "coverage_50": float(cal.coverage[j, 0]), "coverage_90": float(cal.coverage[j, 1]),
            "coverage_95": float(cal.coverage[j, 2]),
            "coverage_95_uncalibrated": float(cal.coverage_uncalibrated[j, 2]),
            "nlpd": float(cal.nlpd[j]), "covariance": cal.covariance[j],
            "scale": float(cal.scale[j, 0]), "dof": float(cal.dof[j, 0]),
        })  # fmt: skip
    return pd.DataFrame(rows)


def fit_pose_model_from_table(
    modal_csv,
    inputs=("x_mm", "y_mm", "rz_deg"),
    kernel: str = "ard",
    *,
    directions=None,
    mode_switch="auto",
    n_folds: int = 5,
    use_flagged: bool = False,
    rng=0,
    covariance: str = "auto",
) -> PoseModelFit:
    """Fit the pose model of every output of a campaign's ``modal.csv``.

    Parameters
    ----------
    modal_csv
        Path to ``modal.csv`` or a DataFrame with its columns.
    inputs
        Pose columns used as model inputs (units in the names).
    kernel : {"ard", "isotropic"}
        The length scales (not the covariance family, which is ``covariance``): one per input
        (``"ard"``) or one shared by all inputs (``"isotropic"``, thesis Eq. 7).
    directions
        Directions modelled (default: those in the table, x/y/z order).
    mode_switch
        Passed to the pose model.
    n_folds
        Folds of the grouped-by-pose cross-validation.
    use_flagged
        Also use rows whose fit is flagged (band edge, residual, coherence).
    rng
        Seed of the fold shuffle and the optimiser restarts.
    covariance : {"auto", "se", "matern52", "matern32"}
        The covariance family (:mod:`robovib.gp.covariances`; the length scales are ``kernel``), or
        ``"auto"`` (default): chosen per output by grouped-CV log
        predictive density (:mod:`robovib.gp.calibration`).

    Returns
    -------
    PoseModelFit
        The fitted, calibrated :class:`~robovib.gp.PoseModalModel` and its grouped
        cross-validation scores (R², RMSE per output in SI units, coverage of the calibrated
        measurement sets at 50/90/95 %, NLPD; the same out-of-fold predictions the calibration
        was fitted on, see :mod:`robovib.gp.calibration`).

    Raises
    ------
    ValueError
        Missing columns, unknown inputs, fewer than 2 poses, a non-physical value or a gross
        outlier (:func:`robovib.campaign.table_checks.check_modal_table`: file, line, column).

    See ``docs/methods.md`` section 3 (GP pose models).

    Examples
    --------
    >>> import tempfile
    >>> from robovib.campaign import fit_pose_model_from_table, process_campaign
    >>> from robovib.sim import simulate_campaign
    >>> folder = tempfile.mkdtemp()  # doctest: +SKIP
    >>> simulate_campaign(folder, rng=0)  # doctest: +SKIP
    >>> fit = fit_pose_model_from_table(process_campaign(folder).modal_csv)  # doctest: +SKIP
    """
    import pandas as pd

    from ..files.csv_table import read_table
    from .table_checks import check_modal_table

    raw = None
    if isinstance(modal_csv, pd.DataFrame):
        table, source, lines = modal_csv, "modal table", np.arange(2, len(modal_csv) + 2)
    else:  # the one CSV reader: errors name the line
        raw = read_table(modal_csv, what="modal table")
        table, source, lines = raw.to_frame(), str(modal_csv), np.asarray(raw.lines, int)
    inputs = tuple(inputs)
    missing = [c for c in (*inputs, "direction", *_OUTPUTS) if c not in table.columns]
    if missing:
        raise ValueError(f"{source} lacks column(s) {', '.join(missing)}")
    if raw is not None:  # a word in a number column: the file, line and column, not pandas' words
        for c in (*inputs, *_OUTPUTS):
            raw.numbers(c, allow_empty=True)
    used = np.ones(len(table), bool)
    if not use_flagged and "flags" in table.columns:
        flags = table["flags"].astype("string").fillna("")
        used = ~flags.apply(lambda s: any(f in s for f in _FIT_FLAGS)).to_numpy(bool)
    # Non-physical values and gross outliers (a 1e6 Hz typo) are refused before the fit.
    check_modal_table(table[used], source=source, lines=lines[used])
    if not inputs:
        raise ValueError("give at least one input column")
    if directions is None:
        directions = tuple(d for d in ("x", "y", "z") if d in set(table["direction"]))
        if not directions:
            found = sorted({str(v) for v in table["direction"]})[:5]
            raise ValueError(
                f"{'modal table' if raw is None else raw.path}: no row has direction x, y or z "
                f"(column direction holds {', '.join(map(repr, found))})"
            )
    X, Y, groups, excluded = _training_table(table, inputs, tuple(directions), use_flagged)
    cls = PoseModalModel
    n_poses = int(np.unique(groups).size)
    if n_poses < 2:
        raise ValueError(f"cross-validation needs at least 2 poses, got {n_poses}")
    _refuse_constant_outputs(Y, tuple(directions), "modal table" if raw is None else raw.path)
    k = min(int(n_folds), n_poses)
    params = dict(input_names=inputs, directions=tuple(directions), kernel=kernel,
                  mode_switch=mode_switch, rng=rng, covariance=covariance, calibrate=True,
                  calibration_folds=k)  # fmt: skip
    model = cls(**params).fit(X, Y)  # groups of fit() are noise groups, not poses
    cv_table = _cv_table(model, np.where(model.mask_, model.Y_train_, np.nan))
    model.cv_table_ = cv_table
    model.cv_ = {
        c: cv_table[c].to_numpy(float)
        for c in cv_table.columns
        if c not in ("output", "unit") and cv_table[c].dtype.kind in "biuf"
    }
    model.provenance_ = {
        "source": str(modal_csv) if not isinstance(modal_csv, pd.DataFrame) else "DataFrame",
        "n_rows": len(table),
        "n_training_rows": len(X),
        "n_poses": int(np.unique(groups).size),
        "cv_folds": int(k),
        "cv": "k-fold grouped by pose (replicates left out together); bands calibrated on it",
        "covariances": list(model.covariances_),
        "excluded_rows": [list(e) for e in excluded],
        "mode_switch_found": mode_switches_found(model),
    }
    quality = tuple(model_quality_warnings(model, cv_table))
    if quality:
        model.provenance_["quality_warnings"] = json.dumps(list(quality))
    for w in quality:
        warnings.warn(w, ModelQualityWarning, stacklevel=2)
    return PoseModelFit(model, cv_table, X, Y, groups, excluded, quality)


def mode_switches_found(model) -> dict[str, bool]:
    """Direction -> whether the fitted model found a mode switch there (either model class).

    Parameters
    ----------
    model : object
        A fitted :class:`~robovib.gp.PoseModalModel` (``mode_switches_``) or a model with
        ``mode_switch_found_``.

    Returns
    -------
    dict of str to bool
        Direction -> mode switch found.
    """
    if hasattr(model, "mode_switches_"):  # PoseModalModel: ModeSwitchDetection per direction
        return {d: bool(det.found) for d, det in model.mode_switches_.items()}
    return {d: bool(f) for d, f in getattr(model, "mode_switch_found_", {}).items()}


def _flat_provenance(prov: dict) -> dict:
    return {
        k: v if isinstance(v, str | int | float | bool) else json.dumps(v) for k, v in prov.items()
    }


def save_pose_model(fit: PoseModelFit, path) -> Path:
    """Save the model (``PoseModalModel.save``: HDF5, format tag, no pickle, atomic) with the
    grouped CV figures and the provenance of the fit.

    Parameters
    ----------
    fit : PoseModelFit
        The result of :func:`fit_pose_model_from_table`.
    path : str or pathlib.Path
        The ``.h5`` file to write (an existing file is replaced atomically).

    Returns
    -------
    pathlib.Path
        The file written (read it back with :func:`robovib.gp.load_pose_model`).

    Examples
    --------
    >>> import pathlib, tempfile
    >>> import numpy as np, pandas as pd
    >>> from robovib.campaign import fit_pose_model_from_table, save_pose_model
    >>> x = np.linspace(2100, 2600, 8)  # one direction along X [mm]; outputs in SI
    >>> table = pd.DataFrame({"x_mm": x, "y_mm": 0 * x, "rz_deg": 0 * x, "direction": "x",
    ...     "fn_hz": 20 - 0.004 * (x - 2100), "stiffness_n_per_m": 3e6 - 1e3 * (x - 2100),
    ...     "damping_ns_per_m": 7e3 + 2 * (x - 2100)})
    >>> fit = fit_pose_model_from_table(table, inputs=("x_mm",), n_folds=2)
    >>> save_pose_model(fit, pathlib.Path(tempfile.mkdtemp()) / "model.h5").name
    'model.h5'
    """
    cv = fit.cv_table
    cv_arrays = {
        c: cv[c].to_numpy(float)
        for c in cv.columns
        if c not in ("output", "unit") and cv[c].dtype.kind in "biuf"
    }
    return fit.model.save(path, cv=cv_arrays, provenance=_flat_provenance(fit.model.provenance_))
