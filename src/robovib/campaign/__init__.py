"""Model your own robot: hammer campaign -> FRFs -> modal table -> pose model -> next poses.

* :func:`read_manifest` — the campaign manifest (one row per recording x direction, with pose);
* :func:`process_campaign` — every row to FRFs and a dominant mode (process pool), written
  atomically to ``frfs.h5``, ``modal.csv`` and ``campaign.json``;
* :func:`fit_pose_model_from_table` — the pose model of every output from ``modal.csv``, with
  a cross-validation table grouped by pose;
* :func:`fit_multimode_pose_model` — every tracked mode (``modes.csv``, written when
  ``ProcessingSettings.modes_band_hz`` is set) as a pose model (issue 29);
* :func:`next_poses` — where to hammer next (largest integrated variance reduction).

Names are imported on first use (PEP 562): ``robovib model next-poses`` reads a saved model
without scikit-learn (:mod:`robovib.campaign.selection`).
"""

from .._lazy import lazy_exports

_WHERE = {
    "CampaignResult": "process",
    "CampaignRow": "manifest",
    "JOINT_COLUMNS": "manifest",
    "NextPoses": "selection",
    "OPTIONAL_POSE_COLUMNS": "manifest",
    "POSE_COLUMNS": "manifest",
    "PoseModelFit": "model",
    "PosePrediction": "model",
    "ProcessingSettings": "process",
    "fit_campaign_table": "multimode",
    "fit_multimode_pose_model": "multimode",
    "track_modes": "multimode",
    "fit_pose_model_from_table": "model",
    "load_pose_model": "model",
    "mode_switches_found": "model",
    "next_poses": "selection",
    "plot_next_poses": "plot",
    "predict_at": "model",
    "process_campaign": "process",
    "process_row": "process",
    "read_manifest": "manifest",
    "save_pose_model": "model",
}

__all__ = sorted(_WHERE)


__getattr__, __dir__ = lazy_exports(__name__, _WHERE)
