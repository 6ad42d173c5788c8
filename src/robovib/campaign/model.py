"""Pose model of a user's robot from the campaign's modal table, and where to hammer next.

* :func:`fit_pose_model_from_table` — reads ``modal.csv`` (:func:`process_campaign`), builds
  one training row per pose (and replicate) with ``[fn_hz, stiffness_n_per_m,
  damping_ns_per_m]`` per direction (missing cells masked), fits the pose model
  (:class:`robovib.gp.PoseModalModel` when available, else :class:`TablePoseModel`, the same
  interface) and cross-validates it grouped by pose (all replicates of a pose left out
  together, thesis §3.3.2).
* :func:`next_poses` — greedy choice of the candidate poses whose measurement reduces the
  integrated posterior variance over all candidates the most (thesis Eq. 10: the GP variance
  does not depend on the measured values, so the reduction is known before measuring):
  ``sum_j Sigma[j, c]^2 / (Sigma[c, c] + sigma_n^2)``, summed over outputs each normalised by
  its prior variance, followed by the rank-one update of ``Sigma``.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..gp.regressor import BatchedGPRegressor, GPHyperparameters

__all__ = [
    "NextPoses",
    "PoseModelFit",
    "TablePoseModel",
    "fit_pose_model_from_table",
    "next_poses",
    "save_pose_model",
]

_OUTPUTS = ("fn_hz", "stiffness_n_per_m", "damping_ns_per_m")
_FORMAT = "robovib-pose-modal"
_FIT_FLAGS = ("band edge", "residual", "coherence")
_UNITS = {"mm": "mm", "deg": "deg", "m": "m"}


def _input_unit(name: str) -> str:
    return name.rsplit("_", 1)[-1] if "_" in name else ""


class TablePoseModel:
    """Pose model of every modal output: one GP per output on the log of the value.

    Follows the ``robovib.gp.PoseModalModel`` interface (scikit-learn contract). The GPs
    (:class:`robovib.gp.BatchedGPRegressor`, thesis Eq. 6-10) model ``log`` of fn, k and c,
    so predictions stay positive; the mean is ``exp(mu)`` and the standard deviation
    ``exp(mu) sigma`` (first order). No mode-switch classifier: ``mode_switch`` other than
    False is accepted and reported as "none found" (``mode_switch_found_ = False``).

    Parameters
    ----------
    input_names
        Names of the input columns, units in the name (``x_mm``, ``rz_deg``, ``a2_deg``...).
    directions
        Directions modelled; outputs are ``<d>_fn_hz, <d>_stiffness_n_per_m,
        <d>_damping_ns_per_m`` per direction.
    kernel
        ``"ard"`` or ``"isotropic"``.
    mode_switch
        Accepted for interface compatibility (see above).
    rng
        Seed of the optimiser restarts.
    """

    def __init__(
        self,
        input_names=("x_mm", "y_mm", "rz_deg"),
        directions=("x", "y", "z"),
        kernel: str = "ard",
        mode_switch="auto",
        rng=0,
    ) -> None:
        self.input_names = input_names
        self.directions = directions
        self.kernel = kernel
        self.mode_switch = mode_switch
        self.rng = rng

    # scikit-learn contract (clone) without importing sklearn at module import
    def get_params(self, deep: bool = True) -> dict:
        return {
            k: getattr(self, k)
            for k in ("input_names", "directions", "kernel", "mode_switch", "rng")
        }

    def set_params(self, **params) -> TablePoseModel:
        for k, v in params.items():
            setattr(self, k, v)
        return self

    @property
    def output_names_(self) -> list[str]:
        return [f"{d}_{o}" for d in self.directions for o in _OUTPUTS]

    def _check_X(self, X) -> np.ndarray:
        X = np.atleast_2d(np.asarray(X, float))
        if X.ndim != 2 or X.shape[1] != len(self.input_names):
            raise ValueError(
                f"X must be (n, {len(self.input_names)}) = {tuple(self.input_names)}, got {X.shape}"
            )
        if not np.all(np.isfinite(X)):
            raise ValueError("X contains NaN or inf")
        return X

    def fit(self, X, Y, mask=None, groups=None) -> TablePoseModel:
        """Fit on X (n, n_inputs) and SI outputs Y (n, 3 n_directions); NaN/masked cells skipped."""
        X = self._check_X(X)
        Y = np.asarray(Y, float)
        n_out = 3 * len(self.directions)
        if Y.shape != (X.shape[0], n_out):
            raise ValueError(
                f"Y must be ({X.shape[0]}, {n_out}) = {self.output_names_}, got {Y.shape}"
            )
        ok = np.isfinite(Y) & (Y > 0) if mask is None else np.asarray(mask, bool) & np.isfinite(Y)
        if np.any(ok & (Y <= 0)):
            raise ValueError("modal outputs must be positive (fn, k, c)")
        if self.kernel not in ("ard", "isotropic"):
            raise ValueError(f"unknown kernel {self.kernel!r}; expected 'ard' or 'isotropic'")
        logY = np.where(ok, np.log(np.where(ok, Y, 1.0)), 0.0)
        self.gp_ = BatchedGPRegressor(kernel=self.kernel, rng=self.rng).fit(X, logY, mask=ok)
        self.X_train_, self.Y_train_, self.mask_ = X, np.where(ok, Y, np.nan), ok
        self.mode_switch_found_ = False
        self._set_hull()
        return self

    def _set_hull(self) -> None:
        from scipy.spatial import Delaunay

        X = self.X_train_
        self._lo, self._hi = X.min(axis=0), X.max(axis=0)
        self._hull = None
        span = np.where(self._hi > self._lo, self._hi - self._lo, 1.0)
        if X.shape[1] <= 4 and X.shape[0] > X.shape[1] + 1:
            try:
                self._hull = Delaunay((X - self._lo) / span)
            except Exception:  # degenerate (coplanar) inputs: fall back to the bounding box
                self._hull = None

    def _require_fitted(self) -> None:
        if not hasattr(self, "gp_"):
            raise ValueError("the pose model is not fitted yet; call fit() first")

    def extrapolating(self, X) -> np.ndarray:
        """(n,) True where a pose lies outside the training inputs' convex hull (or box)."""
        self._require_fitted()
        X = self._check_X(X)
        span = np.where(self._hi > self._lo, self._hi - self._lo, 1.0)
        outside_box = np.any((X < self._lo - 1e-9 * span) | (X > self._hi + 1e-9 * span), axis=1)
        if self._hull is None:
            return outside_box
        return outside_box | (self._hull.find_simplex((X - self._lo) / span, tol=1e-9) < 0)

    def predict(self, X, return_std: bool = False):
        """(n, 3 n_directions) SI outputs [fn_hz, stiffness_n_per_m, damping_ns_per_m] per direction."""
        self._require_fitted()
        X = self._check_X(X)
        mu, sd = self.gp_.predict(X, return_std=True)
        mean = np.exp(mu)
        return (mean, mean * sd) if return_std else mean

    def mode_switch_probability(self, X):
        """None: this model has no mode-switch classifier."""
        return None

    def modes(self, X) -> list[dict]:
        """Per pose: direction -> dict of ModalParameters and standard deviations."""
        from ..modal import ModalParameters

        mean, std = self.predict(X, return_std=True)
        extra = self.extrapolating(X)
        out = []
        for i in range(mean.shape[0]):
            row = {}
            for j, d in enumerate(self.directions):
                fn, k, c = mean[i, 3 * j : 3 * j + 3]
                row[d] = {
                    "parameters": ModalParameters.from_fn_k_c(fn, k, c),
                    "fn_std_hz": std[i, 3 * j], "stiffness_std_n_per_m": std[i, 3 * j + 1],
                    "damping_std_ns_per_m": std[i, 3 * j + 2], "extrapolating": bool(extra[i]),
                    "high_mode_probability": None,
                }  # fmt: skip
            out.append(row)
        return out

    # -------------------------------------------------------------- persistence (no pickle)
    def save(self, path) -> None:
        """HDF5: format tag + version, inputs (names, units), training data, hyperparameters."""
        import h5py

        from .. import __version__
        from ..io.provenance import set_units, write_provenance

        self._require_fitted()
        hp = self.gp_.hyperparameters_
        with h5py.File(path, "w") as h5:
            h5.attrs["format"] = _FORMAT
            h5.attrs["version"] = 1
            h5.attrs["model"] = "TablePoseModel"
            h5.attrs["robovib_version"] = __version__
            h5.attrs["input_names"] = json.dumps(list(self.input_names))
            h5.attrs["input_units"] = json.dumps([_input_unit(n) for n in self.input_names])
            h5.attrs["directions"] = json.dumps(list(self.directions))
            h5.attrs["output_names"] = json.dumps(self.output_names_)
            h5.attrs["output_units"] = "SI: Hz, N/m, N*s/m; GPs on the natural log of each"
            h5.attrs["kernel"] = self.kernel
            h5.attrs["mode_switch"] = str(self.mode_switch)
            h5.attrs["mode_switch_found"] = False
            in_units = ", ".join(_input_unit(n) for n in self.input_names)
            set_units(h5.create_dataset("X_train", data=self.X_train_), in_units)
            set_units(
                h5.create_dataset("Y_train", data=np.nan_to_num(self.Y_train_)),
                "SI per column (see output_names): Hz, N/m, N s/m",
            )
            set_units(h5.create_dataset("mask", data=self.mask_), "1")
            g = h5.create_group("hyperparameters")
            for name in ("signal_std", "length_scales", "noise_std", "mean"):
                set_units(
                    g.create_dataset(name, data=np.asarray(getattr(hp, name))),
                    "1 (log of the SI outputs; length scales in the input units)",
                )
            write_provenance(h5)

    @classmethod
    def load(cls, path) -> TablePoseModel:
        """Rebuild a saved model exactly (stored hyperparameters, no re-optimisation)."""
        import h5py

        path = Path(path)
        try:
            h5 = h5py.File(path, "r")
        except OSError as exc:
            raise ValueError(f"{path}: not a readable HDF5 file ({exc})") from None
        with h5:
            if h5.attrs.get("format") != _FORMAT or int(h5.attrs.get("version", -1)) != 1:
                raise ValueError(f"{path}: not a robovib pose model (format {_FORMAT!r} v1)")
            model = cls(
                input_names=tuple(json.loads(h5.attrs["input_names"])),
                directions=tuple(json.loads(h5.attrs["directions"])),
                kernel=str(h5.attrs["kernel"]),
                mode_switch=str(h5.attrs["mode_switch"]),
            )
            X, Y, mask = h5["X_train"][()], h5["Y_train"][()], h5["mask"][()].astype(bool)
            hp = GPHyperparameters(
                **{k: h5["hyperparameters"][k][()] for k in h5["hyperparameters"]}
            )
        logY = np.where(mask, np.log(np.where(mask, Y, 1.0)), 0.0)
        model.gp_ = BatchedGPRegressor(
            kernel=model.kernel, optimizer=None, initial_hyperparameters=hp
        ).fit(X, logY, mask=mask)
        model.X_train_, model.Y_train_, model.mask_ = X, np.where(mask, Y, np.nan), mask
        model.mode_switch_found_ = False
        model._set_hull()
        return model


def _pose_model_class():
    try:
        from ..gp import PoseModalModel  # engineer "gp": the shared interface

        return PoseModalModel
    except ImportError:
        return TablePoseModel


@dataclass(frozen=True)
class PoseModelFit:
    """A fitted pose model with its grouped-by-pose cross-validation.

    Attributes
    ----------
    model
        The fitted model (``PoseModalModel`` interface).
    cv_table
        DataFrame, one row per output: ``output``, ``n``, ``rmse`` (output units),
        ``relative_rmse_pct`` (of the mean), ``r2``, ``mean_std_ratio`` (mean |error|/std).
    X, Y, groups
        Training data (SI outputs) and pose group of each row.
    excluded
        ``(modal.csv row, reason)`` of rows left out (fit flags).
    """

    model: object
    cv_table: object
    X: np.ndarray
    Y: np.ndarray
    groups: np.ndarray
    excluded: tuple = field(default=())


def _training_table(table, inputs, directions, use_flagged):
    excluded = []
    if not use_flagged and "flags" in table.columns:
        flags = table["flags"].fillna("").astype(str)
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


def _cv(model_cls, params, X, Y, groups, n_folds):
    import pandas as pd

    n_groups = np.unique(groups).size
    k = min(n_folds, n_groups)
    if k < 2:
        raise ValueError(f"cross-validation needs at least 2 poses, got {n_groups}")
    order = np.random.default_rng(0).permutation(np.unique(groups))
    fold_of_group = {g: i % k for i, g in enumerate(order)}
    fold = np.array([fold_of_group[g] for g in groups])
    pred = np.full_like(Y, np.nan)
    std = np.full_like(Y, np.nan)
    for f in range(k):
        tr, te = fold != f, fold == f
        m = model_cls(**params).fit(X[tr], Y[tr])
        pred[te], std[te] = m.predict(X[te], return_std=True)
    names = (
        model_cls(**params).output_names_ if hasattr(model_cls(**params), "output_names_") else None
    )
    rows = []
    for j in range(Y.shape[1]):
        ok = np.isfinite(Y[:, j]) & np.isfinite(pred[:, j])
        y, p, s = Y[ok, j], pred[ok, j], std[ok, j]
        err = p - y
        ss = np.sum((y - y.mean()) ** 2)
        rows.append({
            "output": names[j] if names else str(j), "n": int(ok.sum()),
            "rmse": float(np.sqrt(np.mean(err**2))) if ok.any() else np.nan,
            "relative_rmse_pct": float(100 * np.sqrt(np.mean(err**2)) / np.mean(y)) if ok.any() else np.nan,
            "r2": float(1 - np.sum(err**2) / ss) if ss > 0 else np.nan,
            "mean_abs_error_over_std": float(np.mean(np.abs(err) / np.maximum(s, 1e-300))) if ok.any() else np.nan,
        })  # fmt: skip
    return pd.DataFrame(rows), k


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
) -> PoseModelFit:
    """Fit the pose model of every output of a campaign's ``modal.csv``.

    Parameters
    ----------
    modal_csv
        Path to ``modal.csv`` or a DataFrame with its columns.
    inputs
        Pose columns used as model inputs (units in the names).
    kernel
        ``"ard"`` or ``"isotropic"``.
    directions
        Directions modelled (default: those in the table, x/y/z order).
    mode_switch
        Passed to the pose model.
    n_folds
        Folds of the grouped-by-pose cross-validation.
    use_flagged
        Also use rows whose fit is flagged (band edge, residual, coherence).

    Returns
    -------
    PoseModelFit

    Raises
    ------
    ValueError
        Missing columns, unknown inputs, fewer than 2 poses.
    """
    import pandas as pd

    table = modal_csv if isinstance(modal_csv, pd.DataFrame) else pd.read_csv(modal_csv)
    inputs = tuple(inputs)
    missing = [c for c in (*inputs, "direction", *_OUTPUTS) if c not in table.columns]
    if missing:
        raise ValueError(f"modal table lacks column(s) {', '.join(missing)}")
    if not inputs:
        raise ValueError("give at least one input column")
    if directions is None:
        directions = tuple(d for d in ("x", "y", "z") if d in set(table["direction"]))
    X, Y, groups, excluded = _training_table(table, inputs, tuple(directions), use_flagged)
    cls = _pose_model_class()
    params = dict(input_names=inputs, directions=tuple(directions), kernel=kernel,
                  mode_switch=mode_switch, rng=rng)  # fmt: skip
    cv_table, k = _cv(cls, params, X, Y, groups, n_folds)
    model = cls(**params).fit(X, Y, groups=groups)
    model.cv_table_ = cv_table
    model.provenance_ = {
        "source": str(modal_csv) if not isinstance(modal_csv, pd.DataFrame) else "DataFrame",
        "n_rows": len(table),
        "n_training_rows": len(X),
        "n_poses": int(np.unique(groups).size),
        "cv_folds": int(k),
        "cv": "k-fold grouped by pose (replicates left out together)",
        "excluded_rows": [list(e) for e in excluded],
    }
    return PoseModelFit(model, cv_table, X, Y, groups, excluded)


def save_pose_model(fit: PoseModelFit, path) -> None:
    """Save the model (its own HDF5 format) plus the CV table and provenance, atomically."""
    import h5py

    from ..io import atomic_path

    with atomic_path(path) as tmp:
        fit.model.save(tmp)
        with h5py.File(tmp, "a") as h5:
            g = h5.require_group("campaign")
            g.attrs["provenance"] = json.dumps(fit.model.provenance_)
            cv = fit.cv_table
            g.attrs["cv_columns"] = json.dumps(list(cv.columns))
            g.create_dataset("cv_output", data=np.array(cv["output"].astype(str), dtype="S"))
            for c in cv.columns:
                if c != "output":
                    g.create_dataset(f"cv_{c}", data=cv[c].to_numpy(float))


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
    """

    poses: np.ndarray
    indices: np.ndarray
    variance_reduction: np.ndarray
    total_variance_before: float


def _posterior_cov(gp: BatchedGPRegressor, Xc: np.ndarray):
    """Posterior covariance (B, m, m) at Xc and noise variances (B,), in the GP's target units."""
    hp = gp.hyperparameters_
    X, mask = gp.X_train_, gp.mask_
    out = []
    for b in range(hp.signal_std.size):
        sf2 = float(hp.signal_std[b]) ** 2
        ls = np.asarray(hp.length_scales[b], float)

        def k(a, c, sf2=sf2, ls=ls):
            d = (a[:, None, :] - c[None, :, :]) / ls
            return sf2 * np.exp(-0.5 * np.sum(d * d, axis=-1))

        Xb = X[mask[:, b]]
        kxx = k(Xb, Xb) + (float(hp.noise_std[b]) ** 2 + 1e-10 * sf2) * np.eye(len(Xb))
        kcx = k(Xc, Xb)
        sol = np.linalg.solve(kxx, kcx.T)
        out.append(k(Xc, Xc) - kcx @ sol)
    return (
        np.array(out),
        np.asarray(hp.noise_std, float) ** 2,
        np.asarray(hp.signal_std, float) ** 2,
    )


def next_poses(model, candidates, k: int = 5) -> NextPoses:
    """The ``k`` candidate poses whose measurement most reduces the integrated variance.

    Parameters
    ----------
    model
        A fitted pose model exposing its GP as ``gp_`` (:class:`TablePoseModel`).
    candidates
        (m, n_inputs) array, or a DataFrame with the model's input columns.
    k
        Poses to choose (1 <= k <= m).

    Returns
    -------
    NextPoses

    Raises
    ------
    ValueError
        Missing input columns, bad ``k``, an unfitted model.
    """
    names = tuple(model.input_names)
    if hasattr(candidates, "columns"):
        missing = [c for c in names if c not in candidates.columns]
        if missing:
            raise ValueError(f"candidates lack the model's input column(s) {', '.join(missing)}")
        candidates = candidates[list(names)].to_numpy(float)
    C = np.atleast_2d(np.asarray(candidates, float))
    if C.ndim != 2 or C.shape[1] != len(names):
        raise ValueError(f"candidates must be (m, {len(names)}) = {names}, got {C.shape}")
    if not np.all(np.isfinite(C)):
        raise ValueError("candidates contain NaN or inf")
    if not 1 <= int(k) <= len(C):
        raise ValueError(f"k must be in [1, {len(C)}], got {k}")
    gp = getattr(model, "gp_", None)
    if gp is None:
        raise ValueError("next_poses needs a fitted pose model with a GP (attribute gp_)")
    cov, noise, prior = _posterior_cov(gp, C)
    cov = cov / prior[:, None, None]
    noise = noise / prior
    before = float(np.sum(np.trace(cov, axis1=1, axis2=2)))
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
    return NextPoses(C[idx], idx, np.array(gains), before)
