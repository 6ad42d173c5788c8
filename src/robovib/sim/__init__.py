"""The virtual robot: a synthetic, pose-dependent KR500-3 lab (hammer tests, milling, offset mass).

See :mod:`robovib.sim.truth` for exactly how the ground truth is built (a plausible synthetic
robot fitted to the thesis' data, not a claim about the real one), and
:mod:`robovib.sim.family` for the family of other robots (``VirtualRobot.variant(seed)``):
robots robovib has never seen, for checking a method beyond the one robot it was tuned on. The path model of the
virtual EMA (:mod:`robovib.sim.path_model`, which needs the GP and the FRF estimators) is
imported on first use.
"""

from .._lazy import lazy_exports
from .campaign import LAYOUTS, SimulatedCampaign, simulate_campaign, truth_table
from .disturbances import DISTURBANCE_UNITS, REALISTIC_LEVELS, CutDisturbances
from .dynamics import affine_scan, modal_response, zoh_transition
from .experiments import (
    LinearMove,
    MotionRecord,
    default_path_move,
    offset_mass_force,
    simulate_hammer_test,
    simulate_milling,
    simulate_offset_mass,
)
from .family import RobotDraw, draw_robot, tooth_passing_speeds_rpm
from .plant import ACTUATORS, PURE_DELAY, CommandChannel, ConstantModesRobot, run_closed_loop
from .regenerative import RegenerativeCut, simulate_regenerative_cut, simulated_stability_limit
from .truth import (
    PATH_LENGTH_M,
    POSITION_1_S_M,
    POSITION_2_S_M,
    WORKSPACE_BOUNDS,
    ModeSet,
    PathTruth,
    VirtualRobot,
    WorkspaceTruth,
)

__all__ = [
    "ACTUATORS",
    "DISTURBANCE_UNITS",
    "LAYOUTS",
    "PATH_LENGTH_M",
    "POSITION_1_S_M",
    "POSITION_2_S_M",
    "PURE_DELAY",
    "REALISTIC_LEVELS",
    "WORKSPACE_BOUNDS",
    "CommandChannel",
    "ConstantModesRobot",
    "CutDisturbances",
    "LinearMove",
    "ModeSet",
    "MotionRecord",
    "PathTruth",
    "RegenerativeCut",
    "RobotDraw",
    "SimulatedCampaign",
    "VirtualRobot",
    "WorkspaceTruth",
    "affine_scan",
    "default_path_move",
    "draw_robot",
    "modal_response",
    "offset_mass_force",
    "path_modal_model",
    "run_closed_loop",
    "simulate_campaign",
    "simulate_hammer_test",
    "simulate_milling",
    "simulate_offset_mass",
    "simulate_regenerative_cut",
    "simulated_stability_limit",
    "tooth_passing_speeds_rpm",
    "truth_table",
    "virtual_path_modes",
    "zoh_transition",
]

#: Names imported on first use (PEP 562): the GP and FRF estimation they need are heavy.
_LAZY = {"path_modal_model": "path_model", "virtual_path_modes": "path_model"}

__getattr__, __dir__ = lazy_exports(__name__, _LAZY)
