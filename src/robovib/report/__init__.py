"""Self-contained HTML reports to hand on: tables, figures, settings and provenance in one page.

``robovib.report`` sits at the top of the data flow (like the CLI): it may run studies and read any
result, and nothing in the library imports it.
"""

from .html import Report, ReportSection, file_sha256, render_html, write_report
from .kinds import chapter3_report, result_report

__all__ = [
    "Report",
    "ReportSection",
    "chapter3_report",
    "file_sha256",
    "render_html",
    "result_report",
    "write_report",
]
