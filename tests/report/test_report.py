"""HTML reports: self-contained, and checked in a real headless browser."""

from __future__ import annotations

import re

import matplotlib
import numpy as np
import pandas as pd
import pytest
from browser import assert_page_ok

from robovib.report import Report, ReportSection, render_html, write_report

matplotlib.use("Agg")


def _figure():
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(4, 3))
    ax.plot(np.arange(5), np.arange(5) ** 2)
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel("compliance [m/N]")
    return fig


def test_render_is_self_contained_and_escapes_text():
    frame = pd.DataFrame({"fn_hz": [16.5, np.nan]}, index=pd.Index(["x", "<y>"], name="dir"))
    report = Report(
        "T <1>",
        (
            ReportSection(
                "S", paragraphs=("a < b",), tables=(("tab", frame),), figures=(("f", _figure()),)
            ),
        ),
        settings={"kernel": "ard"},
        provenance={"command": "robovib test"},
    )
    text = render_html(report)
    assert "T &lt;1&gt;" in text and "a &lt; b" in text and "&lt;y&gt;" in text
    assert "data:image/png;base64," in text
    # no external resource of any kind
    assert not re.search(r"""(src|href)=['"](https?:|//)""", text)
    assert "robovib_version" in text and "robovib test" in text


@pytest.mark.browser
def test_write_is_atomic_and_page_loads_in_browser(tmp_path):
    frame = pd.DataFrame({"fn_hz": [16.5, 22.0]})
    report = Report(
        "ok", (ReportSection("S", tables=(("t", frame),), figures=(("f", _figure()),)),)
    )
    path = write_report(report, tmp_path / "r.html")
    assert [p.name for p in tmp_path.iterdir()] == ["r.html"]
    info = assert_page_ok(path, "report_minimal.png")
    assert info["title"] == "ok"


def test_result_report_rejects_objects_without_a_table():
    from robovib.report import result_report

    with pytest.raises(TypeError, match="to_frame"):
        result_report("x", object())
