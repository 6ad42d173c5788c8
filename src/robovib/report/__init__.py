"""Self-contained HTML reports to hand on: tables, figures, settings and provenance in one page.

``robovib.report`` sits at the top of the data flow (like the CLI): it reads results (studies',
models', runs') and never runs a study — :mod:`robovib.studies.reports` composes a study with its
report; nothing in the core library imports it.
"""

from .html import Report, ReportSection, file_sha256, render_html, write_report
from .kinds import (
    chapter3_report,
    control_report,
    lobes_report,
    lobes_study_report,
    model_report,
    result_report,
)

__all__ = [
    "Report",
    "ReportSection",
    "chapter3_report",
    "control_report",
    "file_sha256",
    "lobes_report",
    "lobes_study_report",
    "model_report",
    "render_html",
    "result_report",
    "write_report",
]
