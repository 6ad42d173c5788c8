"""Self-contained HTML reports to hand on: tables, figures, settings and provenance in one page.

``robovib.report`` sits at the top of the data flow (like the CLI): it may run studies and read any
result, and nothing in the library imports it.
"""

from .html import Report, ReportSection, file_sha256, render_html, write_report
from .kinds import (
    chapter3_report,
    chapter3_study_report,
    control_report,
    control_study_report,
    lobes_report,
    lobes_study_report,
    model_report,
    result_report,
)

__all__ = [
    "Report",
    "ReportSection",
    "chapter3_report",
    "chapter3_study_report",
    "control_report",
    "control_study_report",
    "file_sha256",
    "lobes_report",
    "lobes_study_report",
    "model_report",
    "render_html",
    "result_report",
    "write_report",
]
