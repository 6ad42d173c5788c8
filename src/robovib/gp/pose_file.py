"""What a pose-model file is, whoever reads it (NumPy only).

A :class:`~robovib.gp.PoseModalModel` file is written and read in full by
:mod:`robovib.gp._h5` (scikit-learn estimators re-created) and read for prediction only by
:class:`~robovib.gp.saved_model.PosePredictor` (no scikit-learn). Both, and the model itself,
take from here what defines the file: its format tag and version, the classifier feature map
stored by tag, and the check of a loaded model's inputs. Nothing here imports the readers,
so they import it without a circle.
"""

from __future__ import annotations

import numpy as np

from ..files.h5format import (
    POSE_MODEL_FORMAT,
    POSE_MODEL_FORMAT_VERSION,
    H5Tree,
    open_verified,
    read_tree,
)

__all__ = ["FORMAT", "FORMAT_VERSION", "read_pose_file", "require_pose_inputs"]

#: Format tag and version of pose-model files (:meth:`PoseModalModel.save` writes them); owned by
#: :mod:`robovib.files.h5format` beside the other tags, kept here under their former names.
FORMAT = POSE_MODEL_FORMAT
FORMAT_VERSION = POSE_MODEL_FORMAT_VERSION


def read_pose_file(path) -> tuple[H5Tree, int]:
    """Open a pose-model file, check its tag and version, and read it whole into memory.

    The one reader of the file; :func:`robovib.gp.PoseModalModel.load` (scikit-learn
    estimators) and :class:`robovib.gp.saved_model.PosePredictor` (NumPy ones) interpret what it
    returns.

    Parameters
    ----------
    path : str or pathlib.Path
        The file (:meth:`robovib.gp.PoseModalModel.save`).

    Returns
    -------
    tree : robovib.files.h5format.H5Tree
        Root attributes and every group and dataset, as plain dicts and arrays.
    format_version : int
        The file's layout version.

    Raises
    ------
    ValueError
        Not a readable HDF5 file, not a pose model, or a newer format version.
    robovib.files.h5safe.FileContentError
        The file reaches outside itself, does not match its checksum, or a member is missing,
        of the wrong type or shape, or not finite (:mod:`robovib.gp.pose_checks`).
    """
    from .pose_checks import check_pose_tree

    h5, _, version, _ = open_verified(path, {FORMAT: FORMAT_VERSION}, read_whole=True)
    with h5:
        tree = read_tree(h5, path)  # links, storage, checksum checked as it reads
    check_pose_tree(tree, path)
    return tree, version


class _RzCos2:
    """Classifier features with ``rz_deg`` replaced by cos(2 Rz): Rz and Rz + 180° coincide.

    Stored in a file as the tag ``rz_cos2:<index>``.
    """

    def __init__(self, index: int) -> None:
        self.index = index

    def __call__(self, X: np.ndarray) -> np.ndarray:
        X = np.array(X, float)
        X[:, self.index] = np.cos(np.radians(2.0 * X[:, self.index]))
        return X


def require_pose_inputs(model, path, require_inputs) -> None:
    """Refuse a loaded pose model whose inputs are not the ones the caller needs.

    Parameters
    ----------
    model
        A loaded pose model (``input_names``).
    path
        Its file, for the message.
    require_inputs : sequence of str or None
        The input names needed (None: any).

    Raises
    ------
    ValueError
        Other inputs than required.
    """
    if require_inputs is not None and tuple(model.input_names) != tuple(require_inputs):
        raise ValueError(
            f"{path}: this command needs a pose model with inputs {', '.join(require_inputs)}; "
            f"the model has {', '.join(model.input_names)}"
        )
