"""The HDF5 file of an :class:`~robovib.hybrid.FRFPoseModel` (format version 2; reads 1 and 2).

Layout: the header of :mod:`robovib.files.h5format` (``format``, ``format_version``,
``robovib_version``, ``created_utc``, ``units``); attributes ``kernel``, ``input_names``,
``direction``, ``compliance_unit``, ``frequency_unit``, ``groups``, ``targets`` and
``provenance/<key>``; one dataset per array of :data:`_DATASET_UNITS`, each with its
``units``. The GP's state (``theta``, ``x_loc``, ``x_scale``, ``y_loc``, ``y_scale``,
``groups``) comes from, and goes back through, :mod:`robovib.gp._state`: loading re-creates
the posterior exactly (no optimisation, no randomness). No pickle.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..files.h5format import FRF_POSE_MODEL_FORMAT
from ..gp._state import regressor_from_scaled_state, scaled_state

__all__ = ["load_frf_pose_model", "save_frf_pose_model"]

#: Units of the datasets of a saved model (compliance targets scaled to um/N).
_DATASET_UNITS = {
    "frequency_hz": "Hz", "X_train": "input units (input_names)", "Y_train": "um/N", "mask": "1",
    "groups": "1 (0=EMA, 1=OMA)", "theta": "1 (log hyperparameters, scaled)",
    "x_loc": "input units", "x_scale": "input units", "y_loc": "um/N", "y_scale": "um/N",
    "pose_lo": "input units", "pose_hi": "input units",
}  # fmt: skip
_FORMAT = FRF_POSE_MODEL_FORMAT
_VERSION = 2


def save_frf_pose_model(
    model, path, *, provenance: dict | None = None, inputs=(), force: bool = False
) -> None:
    """Write a fitted model in this module's layout, atomically (:meth:`FRFPoseModel.save`).

    Parameters
    ----------
    model
        The fitted :class:`~robovib.hybrid.FRFPoseModel`.
    path, provenance, inputs, force
        As :meth:`FRFPoseModel.save <robovib.hybrid.FRFPoseModel.save>`.
    """
    import h5py

    from ..files.h5format import write_header
    from ..files.h5safe import USERBLOCK_SIZE, seal, seal_file
    from ..files.provenance import set_units, write_provenance
    from ..files.safe_write import atomic_output

    gp = model.gp_
    state = scaled_state(gp)
    with atomic_output(path, inputs=inputs, force=force) as tmp:
        with h5py.File(tmp, "w", userblock_size=USERBLOCK_SIZE) as h5:
            write_header(
                h5, _FORMAT, _VERSION,
                units="frequency_hz Hz; targets and noise um/N (Re, Im of compliance); inputs "
                "in the units of input_names; every dataset's unit in its 'units' attribute",
            )  # fmt: skip
            h5.attrs["kernel"] = model.kernel
            h5.attrs["input_names"] = list(model.input_names)
            h5.attrs["direction"] = getattr(model, "direction_", None) or ""
            h5.attrs["compliance_unit"] = "um/N"
            h5.attrs["frequency_unit"] = "Hz"
            h5.attrs["groups"] = "0=EMA,1=OMA"
            h5.attrs["targets"] = "columns: Re of n_f bins, then Im of n_f bins"
            for key, value in (provenance or {}).items():
                h5.attrs[f"provenance/{key}"] = value
            for name, value in {
                "frequency_hz": model.frequency_hz_, "X_train": gp.X_train_,
                "Y_train": np.nan_to_num(gp.Y_train_), "mask": gp.mask_,
                "groups": state["groups"], "theta": state["theta"], "x_loc": state["x_loc"],
                "x_scale": state["x_scale"], "y_loc": state["y_loc"], "y_scale": state["y_scale"],
                "pose_lo": model.pose_range_[0], "pose_hi": model.pose_range_[1],
            }.items():  # fmt: skip
                set_units(
                    h5.create_dataset(name, data=value), _DATASET_UNITS.get(name, "input units")
                )
            write_provenance(h5, inputs=inputs)
            seal(h5)
        seal_file(tmp)


def load_frf_pose_model(model_class, path):
    """The model in ``path`` (versions 1 and 2), each member checked before use.

    Parameters
    ----------
    model_class
        The class to build (:class:`~robovib.hybrid.FRFPoseModel` or a subclass).
    path
        A file written by :func:`save_frf_pose_model`.

    Returns
    -------
    FRFPoseModel
        Fitted: the GP re-created exactly from its stored state (no optimisation).

    Raises
    ------
    ValueError
        As :meth:`FRFPoseModel.load <robovib.hybrid.FRFPoseModel.load>`.
    """
    from ..files.h5format import open_verified, read_tree

    path = Path(path)
    h5, _, _, _ = open_verified(
        path, {_FORMAT: _VERSION}, what="robovib FRF pose model", read_whole=True
    )
    with h5:
        tree = read_tree(h5, path)  # links, storage and checksum checked as it reads
    d, kernel, direction, names = _checked_model_tree(tree, path)
    model = model_class(d["frequency_hz"], kernel=kernel, input_names=names)
    try:
        gp = regressor_from_scaled_state(
            d, d["X_train"], d["Y_train"], d["mask"].astype(bool), kernel=kernel, n_noise_groups=2
        )
    except (ValueError, np.linalg.LinAlgError):
        from ..files.h5safe import FileContentError

        raise FileContentError(
            path,
            "the stored GP (theta, X_train, Y_train) cannot be factorised: the file is "
            "damaged or was not written by robovib",
        ) from None
    model.gp_ = gp
    model.frequency_hz_ = np.asarray(d["frequency_hz"], float)
    model.pose_range_ = (d["pose_lo"], d["pose_hi"])
    model.direction_ = direction
    model.n_features_in_ = len(names)
    return model


def _checked_model_tree(tree, path):
    """The datasets and attributes of a hybrid model file, each checked for type, shape and
    finiteness (one-line errors naming the file and the member)."""
    from ..files.h5format import as_text
    from ..gp.pose_checks import MAX_TRAINING_POINTS, TreeChecker

    c = TreeChecker(path)
    kernel = c.text(tree, "kernel", "")
    if kernel not in ("ard", "isotropic"):
        c.fail("/", f"attribute 'kernel' is {kernel!r}, expected 'ard' or 'isotropic'")
    direction = as_text(tree.attrs.get("direction", "")) or None
    if direction not in (None, "x", "y", "z"):
        c.fail("/", f"attribute 'direction' is {direction!r}, expected x, y, z or empty")
    raw_names = np.asarray(tree.attrs.get("input_names", ["s_m"]))
    if raw_names.ndim != 1 or raw_names.size == 0 or raw_names.dtype.kind not in "OSU":
        c.fail("/", "attribute 'input_names' is not a list of names")
    names = tuple(as_text(v) for v in raw_names.tolist())
    n_in = len(names)
    f = c.array(tree, "frequency_hz", "", kind="iuf", shape=(None,), finite=True)
    if f.size < 2 or np.any(np.diff(f) <= 0):
        c.fail("frequency_hz", "is not an increasing axis of at least 2 bins")
    n_out = 2 * f.size
    X = c.array(tree, "X_train", "", kind="f", shape=(None, n_in), finite=True)
    n = X.shape[0]
    if not 1 <= n <= MAX_TRAINING_POINTS:
        c.fail("X_train", f"{n} training points; a model holds 1 to {MAX_TRAINING_POINTS}")
    d = {"frequency_hz": f, "X_train": X}
    d["Y_train"] = c.array(tree, "Y_train", "", kind="f", shape=(n, n_out), finite=True)
    d["mask"] = c.array(tree, "mask", "", kind="biu", shape=(n, n_out))
    groups = c.array(tree, "groups", "", kind="iu", shape=(n,))
    if np.any((groups != 0) & (groups != 1)):
        c.fail("groups", "holds noise groups other than 0 (EMA) and 1 (OMA)")
    d["groups"] = groups
    theta = c.array(tree, "theta", "", kind="f", shape=(n_out, None), finite=True)
    if theta.shape[1] - 3 not in (1, n_in):
        c.fail("theta", f"has shape {theta.shape}, expected ({n_out}, {n_in + 3} or 4)")
    d["theta"] = theta
    for key, size, positive in (("x_loc", n_in, False), ("x_scale", n_in, True),
                                ("y_loc", n_out, False), ("y_scale", n_out, True),
                                ("pose_lo", n_in, False), ("pose_hi", n_in, False)):  # fmt: skip
        d[key] = c.array(tree, key, "", kind="f", shape=(size,), finite=True, positive=positive)
    return d, kernel, direction, names
