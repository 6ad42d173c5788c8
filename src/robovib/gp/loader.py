"""The one loader of a pose-model file: :func:`load_pose_model` (NumPy only until it needs more).

Kept apart from :mod:`robovib.gp.contract` (what a pose model gives), which both model classes
import, so that neither module imports the other.
"""

from __future__ import annotations

from .pose_file import require_pose_inputs

__all__ = ["load_pose_model"]


def load_pose_model(path, require_inputs=None, *, predict_only: bool = False):
    """The one loader of a pose-model file (``robovib.PoseModalModel`` HDF5, no pickle).

    Parameters
    ----------
    path : str or os.PathLike
        The model file (``model fit``, :meth:`PoseModalModel.save`): a dominant-mode or a
        multi-mode model, or the chapter-3 model.
    require_inputs : sequence of str, optional
        The input names the caller needs (e.g. ``("x_mm", "y_mm", "rz_deg")``).
    predict_only : bool
        ``True``: a :class:`~robovib.gp.saved_model.PosePredictor` (NumPy and h5py only, starts in
        milliseconds; the full model only where the stored covariance needed jitter).
        ``False``: the :class:`~robovib.gp.PoseModalModel` (scikit-learn; refit, update, save).
        Both honour :class:`PoseModel` with the same numbers.

    Returns
    -------
    PoseModalModel or PosePredictor

    Raises
    ------
    ValueError
        Not a readable HDF5 file, not a robovib pose model, a newer format, or other inputs
        than required.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> from robovib.gp import load_chapter3_model, load_pose_model
    >>> path = load_chapter3_model().save(pathlib.Path(tempfile.mkdtemp()) / "m.h5")
    >>> load_pose_model(path, require_inputs=("x_mm", "y_mm", "rz_deg")).input_names
    ('x_mm', 'y_mm', 'rz_deg')
    >>> load_pose_model(path, predict_only=True).kind
    'dominant-mode'
    """
    if predict_only:  # the fast reader, the full model only where it must
        from .saved_model import load_pose_predictor

        return load_pose_predictor(path, require_inputs)
    from .pose_model import PoseModalModel

    model = PoseModalModel.load(path)
    require_pose_inputs(model, path, require_inputs)
    return model
