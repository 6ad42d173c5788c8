"""The hybrid (EMA + OMA) studies on the virtual robot, one module each.

* :mod:`.study` — the chapter-5 study: EMA calibration, OMA updating, validation (thesis
  Table 12/13 and §5.4.1 analogues over seeds);
* :mod:`.oma_settings` — the study over OMA estimator settings;
* :mod:`.background` — the study over background force levels, and its table;
* :mod:`.workspace` — the whole-workspace FRF model at unseen poses;
* :mod:`.next_poses` — where to hammer next along the path;
* :mod:`.options` — the studies' settings as typed (seeds, background levels).

Every name is importable from ``robovib.studies.hybrid`` as before.
"""

from ...campaign.plot import plot_next_poses
from ...campaign.selection import NextPoses
from .background import background_study, background_table
from .next_poses import propose_next_poses
from .oma_settings import OMASettingsResult, oma_settings_study
from .options import parse_backgrounds, parse_seeds
from .study import (
    BACKGROUND_EVIDENCE,
    MODELS,
    HybridStudyResult,
    StudyData,
    ema_frf_on_grid,
    hybrid_study,
    study_data,
)
from .workspace import WorkspaceStudyResult, workspace_study

__all__ = [
    "BACKGROUND_EVIDENCE",
    "MODELS",
    "HybridStudyResult",
    "NextPoses",
    "OMASettingsResult",
    "StudyData",
    "WorkspaceStudyResult",
    "background_study",
    "background_table",
    "ema_frf_on_grid",
    "hybrid_study",
    "oma_settings_study",
    "parse_backgrounds",
    "parse_seeds",
    "plot_next_poses",
    "propose_next_poses",
    "study_data",
    "workspace_study",
]
