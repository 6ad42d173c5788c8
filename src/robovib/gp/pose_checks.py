"""What a pose-model file must hold, checked before anything is fitted or predicted (NumPy only).

:func:`check_pose_tree` checks every member a reader uses — presence, type, shape against the
model's own inputs and outputs, finiteness, and the size a model can have
(:data:`MAX_TRAINING_POINTS`, :data:`MAX_INPUTS`) — before anything is fitted or factorised, so
a damaged or hand-made file ends in one line naming the file and the member, never in a NumPy
error from deep inside a reader or a GP of 10⁹ points. (What is read at all is bounded by the
file's size on disk: :func:`robovib.files.h5safe.scan`.)
"""

from __future__ import annotations

import json
import re

import numpy as np

from ..files.h5format import H5Tree, as_text
from ..files.h5safe import FileContentError

__all__ = ["MAX_INPUTS", "MAX_TRAINING_POINTS", "TreeChecker", "check_pose_tree"]

#: Most training points a pose model may hold: a GP keeps an n x n factor per output, so 20 000
#: points already need 3.2 GB per output. A file claiming more is not a model.
MAX_TRAINING_POINTS = 20_000
#: Most pose inputs (columns of X) a pose model may have.
MAX_INPUTS = 64
_KINDS = ("BatchedGPRegressor", "ModeSwitchingGPRegressor")
_SWITCH_ATTRS = ("direction", "found", "assumed", "threshold_hz", "delta_bic", "ashman_d",
                 "gap_sigma", "n_low", "n_high", "reason")  # fmt: skip


class TreeChecker:
    """Checks of the members of an :class:`~robovib.files.h5format.H5Tree`, each failing with a
    :class:`~robovib.files.h5safe.FileContentError` that names the file and the member.

    The methods share their parameters: ``tree`` (the group read into memory), ``name`` (the
    member or attribute in it) and ``member`` (the group's path in the file, for the message).

    Parameters
    ----------
    path : str or pathlib.Path
        The file the tree was read from.
    """

    def __init__(self, path) -> None:
        self.path = path

    def fail(self, member: str | None, problem: str):
        """Raise the error for ``member`` (a path in the file) and ``problem`` (words).

        Parameters
        ----------
        member : str or None
            Path of the member in the file.
        problem : str
            What is wrong.
        """
        raise FileContentError(self.path, problem, member)

    def group(self, tree, name: str, member: str) -> H5Tree:
        """The subgroup ``name`` (refused when missing or a dataset).

        Parameters
        ----------
        tree : H5Tree
            The group holding it.
        name : str
            Its name.
        member : str
            Its path in the file.

        Returns
        -------
        H5Tree
            The subgroup.
        """
        if name not in tree:
            self.fail(member, "group is missing")
        g = tree[name]
        if not isinstance(g, H5Tree):
            self.fail(member, "is a dataset where a group was expected")
        return g

    def attr(self, tree, name: str, member: str):
        """The attribute ``name`` (refused when missing).

        Parameters
        ----------
        tree : H5Tree
            The group holding it.
        name : str
            The attribute.
        member : str
            The group's path in the file.

        Returns
        -------
        object
            The value as h5py gives it.
        """
        if name not in tree.attrs:
            self.fail(member or "/", f"attribute '{name}' is missing")
        return tree.attrs[name]

    def text(self, tree, name: str, member: str) -> str:
        """The text attribute ``name`` (refused when missing or not text).

        Parameters
        ----------
        tree, name, member
            As :meth:`attr`: the group, the attribute and the group's path in the file.

        Returns
        -------
        str
            The text.
        """
        v = self.attr(tree, name, member)
        if not isinstance(v, str | bytes):
            self.fail(member or "/", f"attribute '{name}' is not text")
        return as_text(v)

    def number(self, tree, name: str, member: str, *, integer: bool = False) -> float:
        """The single finite number (or integer) attribute ``name``.

        Parameters
        ----------
        tree, name, member
            As :meth:`attr`: the group, the attribute and the group's path in the file.
        integer : bool
            Require an integer.

        Returns
        -------
        float or int
            The number.
        """
        v = np.asarray(self.attr(tree, name, member))
        ok = v.ndim == 0 and v.dtype.kind in ("biu" if integer else "biuf")
        if not ok or (v.dtype.kind == "f" and not np.isfinite(v)):
            what = "an integer" if integer else "a finite number"
            self.fail(member or "/", f"attribute '{name}' is not {what}")
        return v.item()

    def ints(self, tree, name: str, member: str) -> np.ndarray:
        """The attribute ``name`` as a list of integers.

        Parameters
        ----------
        tree, name, member
            As :meth:`attr`: the group, the attribute and the group's path in the file.

        Returns
        -------
        numpy.ndarray
            (n,) integers.
        """
        v = np.asarray(self.attr(tree, name, member))
        if v.ndim != 1 or v.dtype.kind not in "iu":
            self.fail(member or "/", f"attribute '{name}' is not a list of integers")
        return v

    def array(
        self,
        tree,
        name: str,
        member: str,
        *,
        kind: str,
        shape: tuple,
        finite: bool = False,
        positive: bool = False,
        optional: bool = False,
    ):
        """The dataset ``name``, checked for element kind, shape and values.

        Parameters
        ----------
        tree : H5Tree
            The group holding it.
        name : str
            The dataset.
        member : str
            The group's path in the file.
        kind : str
            Accepted NumPy kinds (``"f"``, ``"iu"``, ``"biu"``...).
        shape : tuple
            Expected shape; None for an axis of any length.
        finite : bool
            Refuse NaN and inf.
        positive : bool
            Refuse values <= 0.
        optional : bool
            Return None when missing instead of refusing.

        Returns
        -------
        numpy.ndarray or None
            The data.
        """
        where = f"{member}/{name}" if member else name
        if name not in tree:
            if optional:
                return None
            self.fail(where, "dataset is missing")
        v = tree[name]
        if isinstance(v, H5Tree):
            self.fail(where, "is a group where a dataset was expected")
        v = np.asarray(v)
        if v.dtype.kind not in kind:
            names = {"b": "booleans", "i": "integers", "u": "integers", "f": "real numbers"}
            want = " or ".join(dict.fromkeys(names.get(k, k) for k in kind))
            self.fail(where, f"holds {v.dtype} values, expected {want}")
        if v.ndim != len(shape) or any(
            s is not None and s != n for s, n in zip(shape, v.shape, strict=False)
        ):
            want = "(" + ", ".join("any" if s is None else str(s) for s in shape) + ")"
            self.fail(where, f"has shape {v.shape}, expected {want}")
        if finite and v.dtype.kind == "f" and not np.all(np.isfinite(v)):
            self.fail(where, "holds NaN or infinite values")
        if positive and not np.all(v > 0):
            self.fail(where, "holds values that are not positive")
        return v


def check_pose_tree(tree: H5Tree, path) -> None:
    """Check every member a pose-model reader uses (see the module docstring).

    Parameters
    ----------
    tree : robovib.files.h5format.H5Tree
        The file read by :func:`robovib.gp.pose_file.read_pose_file`.
    path : str or pathlib.Path
        The file (for the message).

    Raises
    ------
    FileContentError
        The first member that is missing, of the wrong type or shape, or not finite.
    """
    c = TreeChecker(path)
    try:
        params = json.loads(c.text(tree, "params_json", ""))
    except (json.JSONDecodeError, UnicodeDecodeError):
        c.fail("/", "attribute 'params_json' is not valid JSON")
    if not isinstance(params, dict):
        c.fail("/", "attribute 'params_json' is not a JSON object")
    names, dirs = params.get("input_names"), params.get("directions")
    if not (isinstance(names, list) and names and all(isinstance(n, str) for n in names)):
        c.fail("/", "attribute 'params_json' has no list of input_names")
    if not (
        isinstance(dirs, list)
        and dirs
        and all(isinstance(d, str) and re.fullmatch(r"[xyz]\d*", d) for d in dirs)
    ):
        c.fail(
            "/",
            "attribute 'params_json' has no list of directions among x, y, z (or mode ids "
            "x1, x2, ...)",
        )
    if len(set(dirs)) != len(dirs) or len(set(names)) != len(names):
        c.fail("/", "attribute 'params_json' repeats an input name or a direction")
    for key in ("robovib_version", "created_utc"):
        c.text(tree, key, "")
    d, m = len(names), 3 * len(dirs)
    if d > MAX_INPUTS:
        c.fail("/", f"{d} inputs; a pose model has at most {MAX_INPUTS}")
    t = c.group(tree, "training", "training")
    X = c.array(t, "X", "training", kind="f", shape=(None, d), finite=True)
    n = _check_size(c, X, "training/X")
    Y = c.array(t, "Y", "training", kind="f", shape=(n, m))
    mask = c.array(t, "mask", "training", kind="biu", shape=(n, m)).astype(bool)
    if not np.all(np.isfinite(Y[mask])):
        c.fail("training/Y", "holds NaN or infinite values where training/mask marks data")
    c.array(t, "groups", "training", kind="iu", shape=(n,), optional=True)
    ms = c.group(tree, "mode_switches", "mode_switches")
    for direction in dirs:
        g = c.group(ms, direction, f"mode_switches/{direction}")
        for key in _SWITCH_ATTRS:
            c.attr(g, key, f"mode_switches/{direction}")
    est = c.group(tree, "estimators", "estimators")
    if len(est) == 0:
        c.fail("estimators", "holds no estimators")
    covered = []
    for i in range(len(est)):
        member = f"estimators/{i}"
        g = c.group(est, str(i), member)
        kind = c.text(g, "kind", member)
        if kind not in _KINDS:
            c.fail(member, f"unknown estimator kind {kind!r}")
        cols = c.ints(g, "columns", member)
        if cols.size == 0 or np.any(cols < 0) or np.any(cols >= m):
            c.fail(member, f"attribute 'columns' is not a list of output columns 0 to {m - 1}")
        covered.extend(cols.tolist())
        if kind == "BatchedGPRegressor":
            _check_regressor(c, g, member, d, cols.size)
        else:
            _check_switching(c, g, member, d, cols.size)
    if sorted(covered) != list(range(m)):
        c.fail("estimators", f"their columns do not cover the {m} outputs once each")
    if "calibration" in tree:
        _check_calibration(c, c.group(tree, "calibration", "calibration"), m)
    if "cv" in tree:
        cv = c.group(tree, "cv", "cv")
        for key in cv:  # a figure per output, or one number (e.g. grouped, n_splits)
            one = np.ndim(cv[key]) == 0 and not isinstance(cv[key], H5Tree)
            c.array(cv, key, "cv", kind="biuf", shape=() if one else (m,))
    c.group(tree, "provenance", "provenance")


def _check_size(c: TreeChecker, X: np.ndarray, member: str) -> int:
    n = X.shape[0]
    if n == 0:
        c.fail(member, "holds no training points")
    if n > MAX_TRAINING_POINTS:
        c.fail(member, f"{n} training points; a pose model holds at most {MAX_TRAINING_POINTS}")
    return n


def _check_regressor(c: TreeChecker, g, member: str, d: int, n_out: int) -> None:
    for key in ("kernel", "optimizer"):
        c.text(g, key, member)
    for key in ("n_noise_groups", "n_restarts", "rng"):
        c.number(g, key, member, integer=True)
    X = c.array(g, "X", member, kind="f", shape=(None, d), finite=True)
    n = _check_size(c, X, f"{member}/X")
    Y = c.array(g, "Y", member, kind="f", shape=(n, n_out))
    mask = c.array(g, "mask", member, kind="biu", shape=(n, n_out)).astype(bool)
    if not np.all(np.isfinite(Y[mask])):
        c.fail(f"{member}/Y", "holds NaN or infinite values where mask marks data")
    c.array(g, "groups", member, kind="iu", shape=(n,))
    c.array(g, "signal_std", member, kind="f", shape=(n_out,), finite=True, positive=True)
    ls = c.array(g, "length_scales", member, kind="f", shape=(n_out, None), finite=True,
                 positive=True)  # fmt: skip
    if ls.shape[1] not in (1, d):
        c.fail(f"{member}/length_scales", f"has shape {ls.shape}, expected ({n_out}, 1 or {d})")
    noise_shape = (n_out,) if np.ndim(g.get("noise_std", 0.0)) < 2 else (n_out, None)
    noise = c.array(g, "noise_std", member, kind="f", shape=noise_shape, finite=True)
    if np.any(noise < 0):
        c.fail(f"{member}/noise_std", "holds negative values")
    c.array(g, "mean", member, kind="f", shape=(n_out,), finite=True)
    for key in ("n_iter", "n_iter_total"):
        c.array(g, key, member, kind="iu", shape=(n_out,))
    c.array(g, "converged", member, kind="biu", shape=(n_out,))
    c.array(g, "log_marginal_likelihood", member, kind="f", shape=(n_out,))
    for key, size in (("x_loc", d), ("x_scale", d), ("y_loc", n_out), ("y_scale", n_out)):
        c.array(g, f"scaler_{key}", member, kind="f", shape=(size,), finite=True, optional=True)


def _check_switching(c: TreeChecker, g, member: str, d: int, n_out: int) -> None:
    for key in ("indicator_output", "n_noise_groups", "n_high", "rng"):
        c.number(g, key, member, integer=True)
    c.number(g, "threshold", member)
    for key in ("kernel", "classifier_features"):
        c.text(g, key, member)
    sw = c.ints(g, "switching_outputs", member)
    if np.any(sw < 0) or np.any(sw >= n_out):
        c.fail(member, f"attribute 'switching_outputs' is not a list of columns 0 to {n_out - 1}")
    ind = int(g.attrs["indicator_output"])
    if not 0 <= ind < n_out:
        c.fail(member, f"attribute 'indicator_output' is not a column 0 to {n_out - 1}")
    _check_regressor(c, c.group(g, "low", f"{member}/low"), f"{member}/low", d, n_out)
    if "high" in g:
        _check_regressor(c, c.group(g, "high", f"{member}/high"), f"{member}/high", d, sw.size)
    c.array(g, "high_mean", member, kind="f", shape=(None,), finite=True, optional=True)
    if "classifier" in g:
        cm = f"{member}/classifier"
        cl = c.group(g, "classifier", cm)
        Xc = c.array(cl, "X", cm, kind="f", shape=(None, d), finite=True)
        y = c.array(cl, "y", cm, kind="biu", shape=(Xc.shape[0],))
        if np.any((y != 0) & (y != 1)):
            c.fail(f"{cm}/y", "holds class labels other than 0 and 1")
        c.array(cl, "kernel_theta", cm, kind="f", shape=(None,), finite=True)
        c.array(cl, "x_loc", cm, kind="f", shape=(d,), finite=True)
        c.array(cl, "x_scale", cm, kind="f", shape=(d,), finite=True, positive=True)


def _check_calibration(c: TreeChecker, g, m: int) -> None:
    member = "calibration"
    names = np.asarray(c.attr(g, "output_names", member))
    if names.ndim != 1 or names.size != m or names.dtype.kind not in "OSU":
        c.fail(member, f"attribute 'output_names' does not name the {m} outputs")
    cov = np.asarray(c.attr(g, "covariance", member))
    if cov.ndim != 1 or cov.dtype.kind not in "OSU":
        c.fail(member, "attribute 'covariance' is not a list of covariance names")
    levels = np.asarray(c.attr(g, "levels", member))
    if levels.ndim != 1 or levels.dtype.kind not in "f" or not np.all(np.isfinite(levels)):
        c.fail(member, "attribute 'levels' is not a list of probabilities")
    for key in ("n_folds", "n_poses"):
        c.number(g, key, member, integer=True)
    scale = c.array(g, "scale", member, kind="f", shape=(m, None), finite=True, positive=True)
    c.array(g, "dof", member, kind="f", shape=scale.shape)
    for key in ("gamma", "ref_std", "mode_logit"):
        c.array(g, key, member, kind="f", shape=scale.shape, optional=True)
    for key in ("n", "nlpd", "rmse"):
        c.array(g, key, member, kind="biuf", shape=(m,))
    for key in ("coverage", "coverage_uncalibrated"):
        c.array(g, key, member, kind="f", shape=(m, levels.size))
    c.array(g, "pit", member, kind="f", shape=(None, m), optional=True)
    lpd = c.group(g, "lpd_by_covariance", f"{member}/lpd_by_covariance")
    for key in lpd:
        c.array(lpd, key, f"{member}/lpd_by_covariance", kind="f", shape=(m,))
