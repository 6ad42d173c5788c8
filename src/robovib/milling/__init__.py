"""Milling: mechanistic cutting forces (shared with the virtual robot), vibration prediction at a
pose (:mod:`~robovib.milling.prediction`, :mod:`~robovib.milling.at_pose`) and chatter
stability (:mod:`~robovib.milling.stability`)."""

from .forces import (
    ACETAL,
    ALUMINIUM_7075,
    CuttingCoefficients,
    CuttingConditions,
    MillingTool,
    engagement_angles,
    milling_forces,
)

__all__ = [
    "ACETAL",
    "ALUMINIUM_7075",
    "CuttingCoefficients",
    "CuttingConditions",
    "MillingTool",
    "engagement_angles",
    "milling_forces",
]
