"""Model your own robot: hammer campaign -> FRFs -> modal table -> pose model -> next poses.

* :func:`read_manifest` — the campaign manifest (one row per recording x direction, with pose);
* :func:`process_campaign` — every row to FRFs and a dominant mode (process pool), written
  atomically to ``frfs.h5``, ``modal.csv`` and ``campaign.json``;
* :func:`fit_pose_model_from_table` — the pose model of every output from ``modal.csv``, with
  a cross-validation table grouped by pose;
* :func:`fit_multimode_pose_model` — every tracked mode (``modes.csv``, written when
  ``ProcessingSettings.modes_band_hz`` is set) as a pose model (issue 29);
* :func:`next_poses` — where to hammer next (largest integrated variance reduction).
"""

from .manifest import (
    JOINT_COLUMNS,
    OPTIONAL_POSE_COLUMNS,
    POSE_COLUMNS,
    CampaignRow,
    read_manifest,
)
from .model import (
    NextPoses,
    PoseModelFit,
    PosePrediction,
    fit_pose_model_from_table,
    load_pose_model,
    mode_switches_found,
    next_poses,
    predict_at,
    save_pose_model,
)
from .multimode import fit_multimode_pose_model, track_modes
from .plot import plot_next_poses
from .process import CampaignResult, ProcessingSettings, process_campaign, process_row

__all__ = [
    "JOINT_COLUMNS",
    "OPTIONAL_POSE_COLUMNS",
    "POSE_COLUMNS",
    "CampaignResult",
    "CampaignRow",
    "NextPoses",
    "PoseModelFit",
    "PosePrediction",
    "ProcessingSettings",
    "fit_multimode_pose_model",
    "fit_pose_model_from_table",
    "load_pose_model",
    "mode_switches_found",
    "next_poses",
    "plot_next_poses",
    "predict_at",
    "process_campaign",
    "process_row",
    "read_manifest",
    "save_pose_model",
    "track_modes",
]
