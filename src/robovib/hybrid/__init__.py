"""Hybrid EMA + OMA statistical model of the robot FRF with Bayesian updating (thesis ch. 5)."""

from .frf_prediction import (
    INPUT_SETS,
    FRFPrediction,
    fit_frf_model,
    flagged_fraction,
    frf_pose,
    frfs_on_grid,
    frfs_on_path_grid,
    oma_frfs_with_path,
    plot_frf_prediction,
    predict_frf_at,
)
from .model import UPDATE_MODES, FRFPoseModel, UpdateReport, frequency_grid
from .oma import OMAQualityWarning, OMASegment, debiased_coherence, h1_random_error, oma_frfs

__all__ = [
    "INPUT_SETS",
    "UPDATE_MODES",
    "FRFPoseModel",
    "FRFPrediction",
    "OMAQualityWarning",
    "OMASegment",
    "UpdateReport",
    "debiased_coherence",
    "fit_frf_model",
    "flagged_fraction",
    "frequency_grid",
    "frf_pose",
    "frfs_on_grid",
    "frfs_on_path_grid",
    "h1_random_error",
    "oma_frfs",
    "oma_frfs_with_path",
    "plot_frf_prediction",
    "predict_frf_at",
]
