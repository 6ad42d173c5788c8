"""Hybrid EMA + OMA statistical model of the robot FRF with Bayesian updating (thesis ch. 5)."""

from .model import FRFPoseModel, UpdateReport, frfs_on_grid
from .oma import OMASegment, oma_frfs

__all__ = ["FRFPoseModel", "OMASegment", "UpdateReport", "frfs_on_grid", "oma_frfs"]
