"""Self-contained HTML reports: tables, figures, settings and provenance in one file.

A report is built from plain values — pandas DataFrames for tables, matplotlib Figures for plots,
dicts for settings — so every kind of result (a study, a pose model, lobes, a control run) renders
the same way. Figures are embedded as base64 PNG, so the page needs no other file and no network.
"""

from __future__ import annotations

import base64
import datetime as _dt
import hashlib
import html
import io
import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pandas as pd

__all__ = ["Report", "ReportSection", "file_sha256", "render_html", "write_report"]

_STYLE = """
body{font-family:system-ui,-apple-system,Segoe UI,Roboto,sans-serif;margin:2rem auto;max-width:72rem;
 padding:0 1rem;color:#1b1f24;line-height:1.45}
h1{font-size:1.6rem;border-bottom:2px solid #0b5394;padding-bottom:.3rem}
h2{font-size:1.25rem;margin-top:2rem;color:#0b5394}
.table-wrap{max-width:100%;overflow-x:auto}
table{border-collapse:collapse;margin:.8rem 0;font-size:.88rem}
th,td{border:1px solid #c9d1d9;padding:.25rem .55rem;text-align:right}
th{background:#eef3f8}td:first-child,th:first-child{text-align:left}
th{max-width:11rem;overflow-wrap:anywhere;vertical-align:bottom}
figure{margin:1rem 0}figure img{max-width:100%;height:auto;border:1px solid #e1e4e8}
figcaption,caption{font-size:.85rem;color:#57606a;caption-side:top;text-align:left;padding:.2rem 0}
.note{background:#fff8c5;border-left:4px solid #d4a72c;padding:.4rem .8rem}
dl{display:grid;grid-template-columns:max-content auto;gap:.2rem 1rem;font-size:.88rem}
dt{font-weight:600}dd{margin:0;font-family:ui-monospace,monospace;word-break:break-all}
"""


@dataclass(frozen=True)
class ReportSection:
    """One titled part of a report.

    Parameters
    ----------
    title
        Section heading.
    paragraphs
        Plain-text paragraphs (escaped; no HTML).
    tables
        ``(caption, DataFrame)`` pairs; column names should carry their units.
    figures
        ``(caption, matplotlib.figure.Figure)`` pairs.
    notes
        Highlighted remarks (flags, warnings, what a number does not mean).
    """

    title: str
    paragraphs: Sequence[str] = ()
    tables: Sequence[tuple[str, pd.DataFrame]] = ()
    figures: Sequence[tuple[str, Any]] = ()
    notes: Sequence[str] = ()


@dataclass(frozen=True)
class Report:
    """A report: title, sections, the settings that produced it and its provenance.

    Attributes
    ----------
    title
        Page title.
    sections
        The :class:`ReportSection` in page order.
    settings
        Settings that produced the results, shown at the end.
    provenance
        Where the results come from (command, input files and their SHA-256).
    """

    title: str
    sections: Sequence[ReportSection]
    settings: Mapping[str, Any] = field(default_factory=dict)
    provenance: Mapping[str, Any] = field(default_factory=dict)


def file_sha256(path: str | Path) -> str:
    """SHA-256 of a file, for the provenance of inputs.

    Parameters
    ----------
    path : str or pathlib.Path
        The file.

    Returns
    -------
    str
        Hex digest.
    """
    digest = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def _figure_png(figure, dpi: int = 110) -> str:
    buf = io.BytesIO()
    figure.savefig(buf, format="png", dpi=dpi, bbox_inches="tight")
    return base64.b64encode(buf.getvalue()).decode("ascii")


def _table_html(caption: str, frame: pd.DataFrame) -> str:
    body = frame.to_html(
        index=frame.index.name is not None or not isinstance(frame.index, pd.RangeIndex),
        border=0,
        float_format=lambda v: f"{v:.4g}",
        na_rep="–",
        escape=True,
    )
    table = (
        body.replace("<table", f"<table><caption>{html.escape(caption)}</caption", 1)
        .replace("<table><caption", "<table class='data'><caption", 1)
        .replace('</caption class="dataframe">', "</caption>")
    )
    # A wide table scrolls inside its own box instead of running off the page.
    return f"<div class='table-wrap'>{table}</div>"


def _value_text(value: Any) -> str:
    if isinstance(value, (dict, list, tuple)):
        return json.dumps(value, default=str)
    return str(value)


def _definition_list(items: Mapping[str, Any]) -> str:
    rows = "".join(
        f"<dt>{html.escape(str(k))}</dt><dd>{html.escape(_value_text(v))}</dd>"
        for k, v in items.items()
    )
    return f"<dl>{rows}</dl>"


def render_html(report: Report) -> str:
    """The report as one self-contained HTML document (no external resources).

    Parameters
    ----------
    report : Report
        The report.

    Returns
    -------
    str
        The HTML (figures embedded as PNG data).
    """
    from .. import __version__

    parts = [
        "<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'>",
        f"<title>{html.escape(report.title)}</title><style>{_STYLE}</style></head><body>",
        f"<h1>{html.escape(report.title)}</h1>",
    ]
    for section in report.sections:
        parts.append(f"<section><h2>{html.escape(section.title)}</h2>")
        parts.extend(f"<p>{html.escape(p)}</p>" for p in section.paragraphs)
        parts.extend(f"<p class='note'>{html.escape(n)}</p>" for n in section.notes)
        for caption, frame in section.tables:
            parts.append(_table_html(caption, frame))
        for caption, figure in section.figures:
            width, height = (int(v * 110) for v in figure.get_size_inches())
            parts.append(
                f"<figure><img alt='{html.escape(caption)}' width='{width}' height='{height}' "
                f"src='data:image/png;base64,{_figure_png(figure)}'>"
                f"<figcaption>{html.escape(caption)}</figcaption></figure>"
            )
        parts.append("</section>")
    provenance = {
        "robovib_version": __version__,
        "created_utc": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
        **report.provenance,
    }
    parts.append("<section><h2>Settings</h2>" + _definition_list(report.settings) + "</section>")
    parts.append("<section><h2>Provenance</h2>" + _definition_list(provenance) + "</section>")
    parts.append("</body></html>")
    return "".join(parts)


def write_report(report: Report, path: str | Path, *, inputs=(), force: bool = False) -> Path:
    """Write the report's HTML atomically (temporary file in the target folder, then rename).

    ``path`` must not be one of ``inputs`` unless ``force`` (:func:`robovib.io.atomic_output`).

    Parameters
    ----------
    report : Report
        The report.
    path : str or pathlib.Path
        The ``.html`` file to write.
    inputs : sequence of path
        Files the report was made from (never overwritten unless ``force``).
    force : bool
        Allow ``path`` to be one of ``inputs``.

    Returns
    -------
    pathlib.Path
        The file written.
    """
    from ..files.safe_write import atomic_output

    path = Path(path)
    text = render_html(report)
    with atomic_output(path, inputs=inputs, force=force) as tmp:
        tmp.write_text(text, encoding="utf-8")
    return path
