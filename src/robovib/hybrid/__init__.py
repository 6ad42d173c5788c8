"""Hybrid EMA + OMA statistical model of the robot FRF with Bayesian updating (thesis ch. 5)."""

from .model import FRFPoseModel, UpdateReport, frfs_on_grid
from .oma import OMASegment, oma_frfs
from .workflow import (
    FRFPrediction,
    frfs_on_path_grid,
    oma_frfs_with_path,
    plot_frf_prediction,
    predict_frf_at,
)

__all__ = [
    "FRFPoseModel",
    "FRFPrediction",
    "OMASegment",
    "UpdateReport",
    "frfs_on_grid",
    "frfs_on_path_grid",
    "oma_frfs",
    "oma_frfs_with_path",
    "plot_frf_prediction",
    "predict_frf_at",
]
