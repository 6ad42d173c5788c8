"""The chapter-3 pose model of Table A1 as a :class:`~robovib.gp.PoseModalModel` (SI).

:func:`fit_chapter3_model` fits it; :func:`load_chapter3_model` loads the fitted copy shipped as
package data (``robovib/datasets/data/chapter3_model.h5``, written by
``scripts/build_chapter3_model.py`` and checked against a fresh fit by the tests), so that pose
commands answer without refitting.

It is a *dominant-mode* model (one mode per direction, as the thesis measured): lobes from it
miss the secondary modes (e.g. the virtual robot's ~43 and ~63.5 Hz X modes and ~22 Hz Y mode),
which can move the stability limit by tens of percent. A campaign processed with every mode
(``campaign process --modes-band``) gives a multi-mode model instead
(:func:`robovib.campaign.fit_multimode_pose_model`, issue 29).
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Literal

import numpy as np

if TYPE_CHECKING:  # imported where used: the predictor path must not import scikit-learn/pandas
    from .pose_model import PoseModalModel
    from .saved_model import PosePredictor

__all__ = [
    "CHAPTER3_INPUTS",
    "chapter3_model_path",
    "chapter3_training_data",
    "fit_chapter3_model",
    "get_chapter3_model",
    "load_chapter3_model",
    "load_chapter3_predictor",
    "workspace_predictor",
]

#: Inputs of the chapter-3 model (Z = 325 mm, Rx = Ry = 0 throughout Table A1).
CHAPTER3_INPUTS = ("x_mm", "y_mm", "rz_deg")
_FILE = "chapter3_model.h5"


def chapter3_training_data(
    stiffness_reading: Literal["corrected", "printed"] = "corrected",
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Table A1 as (X (180, 3) [mm, mm, deg], Y (180, 9) SI, groups (180,) test number).

    ``Y`` columns: fn [Hz], k [N/m], c [N·s/m] for X, Y, Z; NaN where a cell is missing.

    Parameters
    ----------
    stiffness_reading : {"corrected", "printed"}
        Reading of Table A1's shifted stiffness cells.

    Returns
    -------
    X : numpy.ndarray
        (180, 3) poses [mm, mm, deg].
    Y : numpy.ndarray
        (180, 9) modal outputs, SI.
    groups : numpy.ndarray
        (180,) test number of each row.
    """
    from ..datasets import load_table_a1, modal_output_columns, pose_columns

    a1 = load_table_a1(units="si", stiffness_reading=stiffness_reading)
    X = a1[pose_columns("si")].to_numpy() * [1e3, 1e3, 1.0]
    Y = a1[modal_output_columns("si")].to_numpy()
    return X, Y, a1["test"].to_numpy()


def fit_chapter3_model(
    kernel: Literal["isotropic", "ard"] = "ard",
    mode_switch: str | bool = "auto",
    stiffness_reading: Literal["corrected", "printed"] = "corrected",
    rng: int | np.random.Generator | None = 0,
    calibrate: bool = True,
) -> PoseModalModel:
    """Fit the 9-output pose model of Table A1 over (x_mm, y_mm, rz_deg), outputs in SI.

    Parameters
    ----------
    kernel : {"ard", "isotropic"}
        The length scales (not the covariance family): one per input (``"ard"``, default) or
        one shared by all inputs (``"isotropic"``, thesis Eq. 7).
    mode_switch
        ``"auto"`` (default: detects the ~63 Hz X-mode switch), ``True`` or ``False`` (the
        thesis' one smooth GP per output); see :class:`PoseModalModel`.
    stiffness_reading
        Reading of Table A1's shifted stiffness cells (:func:`robovib.datasets.load_table_a1`).
    rng
        Seed of the optimiser restarts and the classifier.
    calibrate
        Calibrate the bands by grouped CV (:mod:`robovib.gp.calibration`; the thesis' SE
        kernel is kept); ``False``: the plain GP posterior, as the thesis.

    Returns
    -------
    PoseModalModel
        Fitted; the mode classifier sees cos(2 Rz) (Rz and Rz + 180° are the same arm
        configuration).
    """
    from .pose_model import PoseModalModel

    X, Y, _ = chapter3_training_data(stiffness_reading)
    model = PoseModalModel(
        input_names=CHAPTER3_INPUTS,
        directions=("x", "y", "z"),
        kernel=kernel,
        mode_switch=mode_switch,
        rng=rng,
        rz_symmetric=True,
        calibrate=calibrate,
    )
    return model.fit(X, Y)


def chapter3_model_path() -> Path:
    """Path of the shipped chapter-3 model file (package data).

    Returns
    -------
    pathlib.Path
        The HDF5 file.

    Raises
    ------
    FileNotFoundError
        If the package data is missing (run ``python scripts/build_chapter3_model.py``).
    """
    # Next to this package rather than importlib.resources.files("robovib.datasets"), which
    # would import robovib.datasets (pandas, ~0.2 s) before a prediction.
    path = Path(__file__).resolve().parent.parent / "datasets" / "data" / _FILE
    if not path.is_file():
        raise FileNotFoundError(
            f"{path}: shipped chapter-3 model missing; run scripts/build_chapter3_model.py"
        )
    return path


def load_chapter3_model() -> PoseModalModel:
    """The fitted chapter-3 model shipped with robovib (``fit_chapter3_model()`` defaults).

    Returns
    -------
    PoseModalModel
        Loaded from package data in milliseconds, no refit.

    Raises
    ------
    FileNotFoundError
        If the package data is missing (run ``python scripts/build_chapter3_model.py``).

    See ``docs/methods.md`` section 3 and ``docs/data.md`` (Table A1).

    Examples
    --------
    >>> from robovib.gp import load_chapter3_model
    >>> load_chapter3_model().input_names
    ('x_mm', 'y_mm', 'rz_deg')
    """
    from .pose_model import PoseModalModel

    return PoseModalModel.load(chapter3_model_path())


def load_chapter3_predictor() -> PosePredictor:
    """The shipped chapter-3 model as a :class:`~robovib.gp.saved_model.PosePredictor`.

    Predictions equal :func:`load_chapter3_model`'s (to ~1e-12) without importing scikit-learn:
    what ``robovib gpr predict`` uses to answer in well under a second.

    Returns
    -------
    PosePredictor
        The model, ready to predict.

    Raises
    ------
    FileNotFoundError
        If the package data is missing (run ``python scripts/build_chapter3_model.py``).
    """
    from .saved_model import load_pose_predictor

    return load_pose_predictor(chapter3_model_path())


def get_chapter3_model(
    kernel: Literal["isotropic", "ard"] = "ard",
    mode_switch: str | bool = "auto",
    rng: int | None = 0,
) -> PoseModalModel:
    """The chapter-3 model for these settings: the shipped copy when they are its settings.

    Parameters
    ----------
    kernel, mode_switch, rng
        As :func:`fit_chapter3_model` (corrected stiffness reading).

    Returns
    -------
    PoseModalModel
        :func:`load_chapter3_model` (milliseconds) for the defaults (``"ard"``, ``"auto"``,
        0), else a fresh :func:`fit_chapter3_model` (seconds).
    """
    if kernel == "ard" and mode_switch == "auto" and rng == 0 and not isinstance(rng, bool):
        try:
            return load_chapter3_model()
        except FileNotFoundError:
            pass
    return fit_chapter3_model(kernel=kernel, mode_switch=mode_switch, rng=rng)


def workspace_predictor(
    path: str | Path | None = None, *, seed: int = 0, require_inputs=CHAPTER3_INPUTS
) -> PosePredictor | PoseModalModel:
    """The pose model to predict with: a saved model, or the thesis' chapter-3 model.

    A saved model is read as a :class:`~robovib.gp.saved_model.PosePredictor` (NumPy and h5py
    only, the same predictions as the full model): a prediction at one pose starts in well
    under a second. Only a chapter-3 model with another optimiser ``seed`` is refitted
    (scikit-learn, seconds).

    Parameters
    ----------
    path
        A model file from ``robovib model fit`` / :meth:`PoseModalModel.save`; None: the
        shipped chapter-3 model.
    seed
        Optimiser seed of the chapter-3 model (0: the shipped copy).
    require_inputs
        Input names a saved model must have (units in the names); None: any.

    Returns
    -------
    PosePredictor or PoseModalModel
        A predictor (saved or shipped model), or a refitted chapter-3 model.

    Raises
    ------
    ValueError, OSError
        A file that is not a pose model, or one without ``require_inputs``.
    """
    if path is None:
        if seed == 0:
            try:
                return load_chapter3_predictor()
            except FileNotFoundError:
                pass
        return get_chapter3_model(rng=seed)
    from .saved_model import load_pose_predictor

    return load_pose_predictor(path, require_inputs=require_inputs)
