"""Hybrid EMA + OMA statistical model of the robot FRF with Bayesian updating (thesis ch. 5)."""

from .model import UPDATE_MODES, FRFPoseModel, UpdateReport
from .oma import OMAQualityWarning, OMASegment, oma_frfs

__all__ = [
    "UPDATE_MODES",
    "FRFPoseModel",
    "OMAQualityWarning",
    "OMASegment",
    "UpdateReport",
    "oma_frfs",
]
