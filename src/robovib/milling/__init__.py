"""Milling: mechanistic cutting forces (shared with the virtual robot) and vibration prediction."""

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
