"""HDF5 reading/writing of the GP estimators and :class:`~robovib.gp.PoseModalModel` (no pickle).

What is stored is what defines the fitted state: training data, mask, noise groups,
hyperparameters in data units, scalers (a record), optimiser statistics and,
for a mode switch, the classifier's training data and fitted kernel hyperparameters. Loading
re-creates every estimator with its stored hyperparameters held fixed (``optimizer=None``) on
the stored data, which reproduces the posterior exactly (no optimisation, no randomness).

Layout of a ``robovib.PoseModalModel`` file (format version 1)::

    /                 attrs: format, format_version, robovib_version, created_utc, params_json,
                      input_names, input_units, output_names, output_units
    /training         X (attr units), Y (NaN = missing; attr units), mask, [groups]
    /mode_switches/<direction>   attrs: the ModeSwitchDetection fields
    /estimators/<i>   attrs kind, columns; a regressor or a mode-switching regressor group
    /cv               [optional] one dataset per figure, (n_outputs,); attrs
    /provenance       attrs (source, command, script, ...)
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from .. import __version__
from ..files.h5format import as_text, write_header
from ..files.h5safe import USERBLOCK_SIZE, seal, seal_file
from .calibration import read_calibration, write_calibration
from .mode_switch import ModeSwitchDetection, ModeSwitchingGPRegressor, symmetric_rz_features
from .pose_file import FORMAT, FORMAT_VERSION, _RzCos2, read_pose_file
from .regressor import BatchedGPRegressor, GPHyperparameters

_REG_PARAMS = ("kernel", "mean", "normalize", "max_iter", "gtol", "n_noise_groups", "covariance")
# Files written before a parameter existed read with its default.
_REG_DEFAULTS = {"covariance": "se"}


# ---------------------------------------------------------------------------- regressor
def write_regressor(group, gp: BatchedGPRegressor) -> None:
    """Store a fitted :class:`BatchedGPRegressor` in an h5py group."""
    gp._require_fitted()
    if getattr(gp, "_squeeze", False):
        raise ValueError("only regressors fitted on a 2-D Y can be saved")
    for p in _REG_PARAMS:
        group.attrs[p] = getattr(gp, p)
    group.attrs["optimizer"] = "none" if gp.optimizer is None else gp.optimizer
    group.attrs["n_restarts"] = -1 if gp.n_restarts is None else int(gp.n_restarts)
    group.attrs["rng"] = int(gp.rng) if isinstance(gp.rng, int | np.integer) else -1
    hp = gp.hyperparameters_
    groups = getattr(gp, "_active_groups", None)
    data = {
        "X": gp.X_train_,
        "Y": gp.Y_train_,
        "mask": gp.mask_,
        "groups": np.zeros(gp.X_train_.shape[0], int) if groups is None else groups,
        "signal_std": hp.signal_std,
        "length_scales": hp.length_scales,
        "noise_std": hp.noise_std,
        "mean": hp.mean,
        "n_iter": gp.n_iter_,
        "n_iter_total": getattr(gp, "n_iter_total_", gp.n_iter_),
        "converged": getattr(gp, "converged_", np.ones(gp.n_outputs_, bool)),
        "log_marginal_likelihood": gp.log_marginal_likelihood_value_,
    }
    for name in ("_x_loc", "_x_scale", "_y_loc", "_y_scale"):
        if getattr(gp, name, None) is not None:
            data[f"scaler{name}"] = getattr(gp, name)
    units = {
        "X": "input units",
        "Y": "output units",
        "signal_std": "output units",
        "noise_std": "output units",
        "mean": "output units",
        "length_scales": "input units",
        "log_marginal_likelihood": "log density in output units",
    }
    for name, value in data.items():
        ds = group.create_dataset(name, data=np.asarray(value))
        if name in units:
            ds.attrs["units"] = units[name]


def read_regressor(group) -> BatchedGPRegressor:
    """Re-create a fitted :class:`BatchedGPRegressor` from :func:`write_regressor`'s group."""
    a = group.attrs
    d = {k: group[k][()] for k in group}
    hp = GPHyperparameters(
        signal_std=d["signal_std"],
        length_scales=d["length_scales"],
        noise_std=d["noise_std"],
        mean=d["mean"],
    )
    raw = {p: a[p] if p in a else _REG_DEFAULTS[p] for p in _REG_PARAMS}
    params = {p: v.item() if hasattr(v, "item") else v for p, v in raw.items()}
    params = {k: (str(v) if isinstance(v, str | bytes) else v) for k, v in params.items()}
    gp = BatchedGPRegressor(
        **params, optimizer=None, initial_hyperparameters=hp, n_restarts=0, rng=None
    )
    n_groups = int(params["n_noise_groups"])
    mask = d["mask"].astype(bool)
    gp.fit(
        d["X"],
        np.where(mask, d["Y"], 0.0),
        mask=mask,
        groups=d["groups"].astype(int) if n_groups > 1 else None,
    )
    # The stored scalers are a record only: after an update they are those of the first fit,
    # while the reload standardises with all data. The posterior does not depend on the
    # scaling (hyperparameters are held fixed in data units), only round-off does.
    optimizer = str(a["optimizer"])
    n_restarts, rng = int(a["n_restarts"]), int(a["rng"])
    gp.set_params(
        optimizer=None if optimizer == "none" else optimizer,
        initial_hyperparameters=None,
        n_restarts=None if n_restarts < 0 else n_restarts,
        rng=None if rng < 0 else rng,
    )
    gp.n_iter_ = d["n_iter"]
    gp.n_iter_total_ = d["n_iter_total"]
    gp.converged_ = d["converged"].astype(bool)
    gp.log_marginal_likelihood_value_ = d["log_marginal_likelihood"]
    return gp


# ---------------------------------------------------------------------------- mode switch
def _features_tag(features) -> str:
    if features is None:
        return "none"
    if features is symmetric_rz_features:
        return "rz_cos2:2"
    if isinstance(features, _RzCos2):
        return f"rz_cos2:{int(features.index)}"
    raise ValueError(
        f"cannot save classifier_features={features!r}: only None, symmetric_rz_features or "
        "the rz_deg cos(2 Rz) map of PoseModalModel can be stored"
    )


def _features_from_tag(tag: str):
    if tag == "none":
        return None
    kind, index = tag.split(":")
    if kind != "rz_cos2":
        raise ValueError(f"unknown classifier feature map {tag!r}")
    return _RzCos2(int(index))


def write_mode_switching(group, model: ModeSwitchingGPRegressor) -> None:
    """Store a fitted :class:`ModeSwitchingGPRegressor` in an h5py group."""
    model._require_fitted()
    a = group.attrs
    a["switching_outputs"] = np.asarray(model.switching_outputs, int)
    a["indicator_output"] = int(model.indicator_output)
    a["threshold"] = float(model.threshold)
    a["classifier_features"] = _features_tag(model.classifier_features)
    a["kernel"] = model.kernel
    a["covariance"] = model.covariance
    a["rng"] = int(model.rng) if isinstance(model.rng, int | np.integer) else -1
    a["n_noise_groups"] = int(model.n_noise_groups)
    a["n_high"] = int(model.n_high_)
    a["all_high"] = bool(model._all_high)
    write_regressor(group.create_group("low"), model.low_model_)
    if model.high_model_ is not None:
        write_regressor(group.create_group("high"), model.high_model_)
    if model._high_mean is not None:
        group.create_dataset("high_mean", data=model._high_mean)
    if model.classifier_ is not None:
        base = model.classifier_.base_estimator_
        c = group.create_group("classifier")
        c.create_dataset("X", data=base.X_train_)
        c.create_dataset("y", data=np.asarray(base.y_train_, int))
        c.create_dataset("kernel_theta", data=base.kernel_.theta)
        c.create_dataset("x_loc", data=model._x_loc)
        c.create_dataset("x_scale", data=model._x_scale)
        c.attrs["kernel"] = repr(base.kernel_)
        c.attrs["units"] = "standardised classifier features"


def _classifier(X, y, theta):
    from sklearn.gaussian_process import GaussianProcessClassifier
    from sklearn.gaussian_process.kernels import RBF
    from sklearn.gaussian_process.kernels import ConstantKernel as C

    kernel = (C(1.0) * RBF(np.ones(X.shape[1]))).clone_with_theta(theta)
    return GaussianProcessClassifier(kernel, optimizer=None).fit(X, y.astype(bool))


def read_mode_switching(group) -> ModeSwitchingGPRegressor:
    """Re-create a fitted :class:`ModeSwitchingGPRegressor` (classifier refitted, optimizer=None)."""
    a = group.attrs
    rng = int(a["rng"])
    model = ModeSwitchingGPRegressor(
        switching_outputs=tuple(int(i) for i in a["switching_outputs"]),
        indicator_output=int(a["indicator_output"]),
        threshold=float(a["threshold"]),
        classifier_features=_features_from_tag(str(a["classifier_features"])),
        kernel=str(a["kernel"]),
        covariance=as_text(a["covariance"]) if "covariance" in a else "se",
        rng=None if rng < 0 else rng,
        n_noise_groups=int(a["n_noise_groups"]),
    )
    model.low_model_ = read_regressor(group["low"])
    model.high_model_ = read_regressor(group["high"]) if "high" in group else None
    model._high_mean = group["high_mean"][()] if "high_mean" in group else None
    model.n_high_ = int(a["n_high"])
    model._all_high = bool(a["all_high"])
    model._switching = np.asarray(model.switching_outputs, int)
    model.classifier_ = None
    if "classifier" in group:
        c = group["classifier"]
        model._x_loc, model._x_scale = c["x_loc"][()], c["x_scale"][()]
        model.classifier_ = _classifier(c["X"][()], c["y"][()], c["kernel_theta"][()])
    return model


# ---------------------------------------------------------------------------- pose model
def write_pose_model(model, path, *, cv=None, provenance=None) -> None:
    import h5py

    with h5py.File(path, "w", userblock_size=USERBLOCK_SIZE) as h5:
        write_header(h5, FORMAT, FORMAT_VERSION)
        a = h5.attrs
        a["params_json"] = _params_json(model)
        a["input_names"] = list(model.input_names_)
        a["input_units"] = list(model.input_units_)
        a["output_names"] = list(model.output_names_)
        a["output_units"] = list(model.output_units_)
        t = h5.create_group("training")
        t.create_dataset("X", data=model.X_train_).attrs["units"] = list(model.input_units_)
        t.create_dataset("Y", data=model.Y_train_).attrs["units"] = list(model.output_units_)
        t.create_dataset("mask", data=model.mask_)
        if model.groups_ is not None:
            t.create_dataset("groups", data=model.groups_)
        ms = h5.create_group("mode_switches")
        for d, det in model.mode_switches_.items():
            g = ms.create_group(d)
            for k, v in det.to_dict().items():
                g.attrs[k] = v
            g.attrs["threshold_units"] = "Hz"
        est = h5.create_group("estimators")
        for i, (e, cols) in enumerate(
            zip(model.estimators_, model.estimator_columns_, strict=True)
        ):
            g = est.create_group(str(i))
            g.attrs["columns"] = np.asarray(cols, int)
            g.attrs["input_units"] = list(model.input_units_)
            g.attrs["output_units"] = [model.output_units_[c] for c in cols]
            if isinstance(e, ModeSwitchingGPRegressor):
                g.attrs["kind"] = "ModeSwitchingGPRegressor"
                write_mode_switching(g, e)
            else:
                g.attrs["kind"] = "BatchedGPRegressor"
                write_regressor(g, e)
        cal = getattr(model, "calibration_", None)
        if cal is not None:
            write_calibration(h5.create_group("calibration"), cal)
        if cv is not None:
            c = h5.create_group("cv")
            figures = _cv_figures(cv)
            for k, v in figures.items():
                if isinstance(v, bool | str | int | float):
                    c.attrs[k] = v
                else:
                    c.create_dataset(k, data=np.asarray(v, float))
            c.attrs["output_names"] = list(model.output_names_)
        p = h5.create_group("provenance")
        p.attrs["robovib_version"] = __version__
        for k, v in (provenance or {}).items():
            p.attrs[str(k)] = v if isinstance(v, int | float | str | bool) else json.dumps(v)
        seal(h5)
    seal_file(path)


def _params_json(model) -> str:
    ms = model.mode_switch
    rng = model.rng if isinstance(model.rng, int | np.integer) or model.rng is None else None
    return json.dumps(
        {
            "input_names": list(model.input_names),
            "directions": list(model.directions),
            "kernel": model.kernel,
            "mode_switch": dict(ms) if isinstance(ms, Mapping) else ms,
            "rng": None if rng is None else int(rng),
            "rz_symmetric": bool(model.rz_symmetric),
            "covariance": model.covariance,
            "calibrate": bool(model.calibrate),
            "calibration_folds": int(model.calibration_folds),
        }
    )


def _cv_figures(cv) -> dict:
    if isinstance(cv, Mapping):
        return dict(cv)
    return {"r2": cv.r2, "r2_corr": cv.r2_corr, "rmse": cv.rmse, "grouped": bool(cv.grouped)}


def read_pose_model(cls, path):

    path = Path(path)
    tree, version = read_pose_file(path)
    a = tree.attrs
    params = json.loads(as_text(a["params_json"]))
    params["input_names"] = tuple(params["input_names"])
    params["directions"] = tuple(params["directions"])
    model = cls(**params)
    names, dirs = model._check_params()
    t = tree["training"]
    X, Y, mask = t["X"][()], t["Y"][()], t["mask"][()].astype(bool)
    groups = t["groups"][()].astype(int) if "groups" in t else None
    switches = {}
    for d in dirs:
        g = tree["mode_switches"][d].attrs
        switches[d] = ModeSwitchDetection(
            direction=as_text(g["direction"]),
            found=bool(g["found"]),
            assumed=bool(g["assumed"]),
            threshold_hz=float(g["threshold_hz"]),
            delta_bic=float(g["delta_bic"]),
            ashman_d=float(g["ashman_d"]),
            gap_sigma=float(g["gap_sigma"]),
            n_low=int(g["n_low"]),
            n_high=int(g["n_high"]),
            reason=as_text(g["reason"]),
        )
    estimators, columns = [], []
    for i in range(len(tree["estimators"])):
        g = tree["estimators"][str(i)]
        kind = as_text(g.attrs["kind"])
        if kind == "BatchedGPRegressor":
            estimators.append(read_regressor(g))
        elif kind == "ModeSwitchingGPRegressor":
            estimators.append(read_mode_switching(g))
        else:
            raise ValueError(f"{path}: unknown estimator kind {kind!r}")
        columns.append(np.asarray(g.attrs["columns"], int))
    model.mode_switches_ = switches
    model.estimators_, model.estimator_columns_ = estimators, columns
    model._set_fitted(names, dirs, X, Y, mask, groups)
    model.calibration_ = read_calibration(tree["calibration"]) if "calibration" in tree else None
    model.covariances_ = (
        model.calibration_.covariance
        if model.calibration_ is not None
        else tuple(
            getattr(e, "covariance", "se")
            for e, cols in zip(estimators, columns, strict=True)
            for _ in cols
        )
    )
    if "cv" in tree:
        c = tree["cv"]
        cv = {k: c[k][()] for k in c}
        cv.update({k: v for k, v in c.attrs.items() if k != "output_names"})
        model.cv_ = cv
    model.provenance_ = {
        k: as_text(v) if isinstance(v, bytes) else v for k, v in tree["provenance"].attrs.items()
    }
    model.file_attrs_ = {
        "robovib_version": as_text(a["robovib_version"]),
        "created_utc": as_text(a["created_utc"]),
        "format_version": version,
        # "verified", or "none stored" (written before robovib sealed its files)
        "content_sha256": tree.checksum,
    }
    return model
