"""Analytical model of the KUKA KR500-3 (thesis §3.4): kinematics, stiffness, mass, eigenfrequencies."""

from .kinematics import (
    DH_TABLE,
    JOINT_LIMITS_DEG,
    KR500,
    KUKA_SIGNS,
    IKError,
    euler_zyx,
    tool_down_orientation,
)

__all__ = [
    "DH_TABLE",
    "JOINT_LIMITS_DEG",
    "KR500",
    "KUKA_SIGNS",
    "IKError",
    "euler_zyx",
    "tool_down_orientation",
]
