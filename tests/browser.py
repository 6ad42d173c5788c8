"""Open a report in real headless Chromium (Debian's package, driven by Playwright)."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import pytest

ARTIFACTS = Path(os.environ.get("ROBOVIB_ARTIFACTS", Path(__file__).parents[1] / "artifacts"))


def chromium_path() -> str:
    """Path of the Chromium binary; skips locally when absent, fails in CI (CI=true)."""
    for name in ("chromium", "chromium-browser", "google-chrome"):
        found = shutil.which(name)
        if found:
            return found
    if os.environ.get("CI"):
        pytest.fail("Chromium is not installed; .ci/run installs Debian's chromium package")
    pytest.skip("Chromium is not installed (apt-get install chromium)")


def inspect_page(html_path: Path, screenshot_name: str) -> dict:
    """Load the page; return console errors, figure sizes and the screenshot path."""
    from playwright import sync_api  # a declared test dependency: never skipped

    executable = chromium_path()
    ARTIFACTS.mkdir(parents=True, exist_ok=True)
    shot = ARTIFACTS / screenshot_name
    errors: list[str] = []
    with sync_api.sync_playwright() as pw:
        browser = pw.chromium.launch(
            executable_path=executable, headless=True, args=["--no-sandbox"]
        )
        try:
            page = browser.new_page(viewport={"width": 1280, "height": 900})
            page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
            page.on("pageerror", lambda exc: errors.append(str(exc)))
            page.goto(html_path.resolve().as_uri(), wait_until="load")
            figures = page.evaluate(
                """Array.from(document.images).map(i => {
                    const r = i.getBoundingClientRect();
                    return {alt: i.alt, natural_width: i.naturalWidth,
                            natural_height: i.naturalHeight, width: r.width, height: r.height};
                })"""
            )
            title = page.title()
            tables = page.evaluate("document.querySelectorAll('table').length")
            # Tables running off the page at 1280 px: the table (or its scrolling box) ends
            # beyond the body's content box, or the page itself scrolls sideways.
            overflowing = page.evaluate(
                """(() => {
                    const body = document.body.getBoundingClientRect();
                    const bad = Array.from(document.querySelectorAll('table')).filter(t => {
                        const w = t.parentElement.classList.contains('table-wrap')
                            ? t.parentElement : t;
                        return w.getBoundingClientRect().right > body.right + 1;
                    }).map(t => t.caption ? t.caption.textContent : '(no caption)');
                    if (document.documentElement.scrollWidth > window.innerWidth + 1)
                        bad.push('the page scrolls sideways');
                    return bad;
                })()"""
            )
            page.screenshot(path=str(shot), full_page=True)
        finally:
            browser.close()
    return {"errors": errors, "figures": figures, "title": title, "tables": tables, "shot": shot,
            "overflowing_tables": overflowing}  # fmt: skip


def assert_page_ok(html_path: Path, screenshot_name: str, min_figures: int = 1) -> dict:
    """The page loads without console errors and every figure has a non-zero size."""
    info = inspect_page(html_path, screenshot_name)
    assert info["errors"] == [], info["errors"]
    assert len(info["figures"]) >= min_figures, info["figures"]
    for fig in info["figures"]:
        assert fig["natural_width"] > 0 and fig["natural_height"] > 0, fig
        assert fig["width"] > 0 and fig["height"] > 0, fig
    assert info["tables"] >= 1
    assert info["overflowing_tables"] == [], (
        f"tables wider than the page: {info['overflowing_tables']}"
    )
    assert info["shot"].stat().st_size > 0
    return info
