"""Gaussian-process regression of pose-dependent quantities (thesis §3.3, Eq. 6-10, 33-36).

Names are imported on first use (PEP 562): ``from robovib.gp.saved_model import ...`` (NumPy only)
does not pay for scikit-learn, which the estimators need.
"""

from .._lazy import lazy_exports

_WHERE = {
    "BandCalibration": "calibration",
    "COVARIANCES": "covariances",
    "ModalPredictive": "bands",
    "BatchedGPRegressor": "regressor",
    "GPHyperparameters": "regressor",
    "GPNumericalError": "regressor",
    "JitterWarning": "regressor",
    "ModeSwitchDetection": "mode_switch",
    "ModeSwitchingGPRegressor": "mode_switch",
    "PoseModalModel": "pose_model",
    "PoseMode": "dominant_modes",
    "PosePredictor": "saved_model",
    "detect_mode_switch": "mode_switch",
    "fit_chapter3_model": "chapter3_model",
    "get_chapter3_model": "chapter3_model",
    "load_chapter3_model": "chapter3_model",
    "load_chapter3_predictor": "chapter3_model",
    "load_pose_predictor": "saved_model",
    "load_pose_model": "loader",
    "PoseModel": "contract",
    "pick_mode": "contract",
    "plot_calibration": "plot",
}

__all__ = sorted(_WHERE)


__getattr__, __dir__ = lazy_exports(__name__, _WHERE)
