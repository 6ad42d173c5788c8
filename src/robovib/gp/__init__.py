"""Gaussian-process regression of pose-dependent quantities (thesis §3.3, Eq. 6-10, 33-36)."""

from .chapter3_model import fit_chapter3_model, get_chapter3_model, load_chapter3_model
from .mode_switch import ModeSwitchingGPRegressor
from .pose_model import ModeSwitchDetection, PoseModalModel, PoseMode, detect_mode_switch
from .regressor import BatchedGPRegressor, GPHyperparameters, GPNumericalError, JitterWarning

__all__ = [
    "BatchedGPRegressor",
    "GPHyperparameters",
    "GPNumericalError",
    "JitterWarning",
    "ModeSwitchDetection",
    "ModeSwitchingGPRegressor",
    "PoseModalModel",
    "PoseMode",
    "detect_mode_switch",
    "fit_chapter3_model",
    "get_chapter3_model",
    "load_chapter3_model",
]
