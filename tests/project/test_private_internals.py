"""robovib uses no private module of Typer or rich (issue 41): a release may change them silently.

One documented exception is left: ``cli/_coerce.py`` gives Typer 0.2x's parameters a light
converter (Pydantic costs ~0.13 s of CPU per command, which puts the pose commands above 2x
``robovib --help``); Typer is pinned below 0.30 and ``tests/cli/test_cli_coerce.py`` checks the
converter against Typer's own, failing (never skipping) when Typer moves.
"""

from __future__ import annotations

import re
from pathlib import Path

SRC = Path(__file__).resolve().parents[2] / "src" / "robovib"
#: ``typer._x`` / ``rich._x`` modules, Typer's vendored click, rich's private table cells.
_PRIVATE = re.compile(r"\b(?:typer|rich)(?:\.\w+)*\._\w+|\b_click\b|\._cells\b|_runtime_param\b")
ALLOWED = {"cli/_coerce.py"}


def private_uses(source: str) -> list[str]:
    """Private Typer/rich names used by ``source`` (comments and docstrings included)."""
    return sorted(set(_PRIVATE.findall(source)))


def test_planted_private_uses_are_found():
    planted = "from typer._click.globals import x\nn = col._cells\nimport rich._loop\n"
    assert private_uses(planted) == ["._cells", "rich._loop", "typer._click"]
    assert private_uses("from typer import _click") == ["_click"]
    assert private_uses("import typer\nfrom rich.table import Table\ncol.cells\n") == []


def test_no_private_typer_or_rich_outside_the_documented_exception():
    found = {
        rel: bad
        for path in sorted(SRC.rglob("*.py"))
        if (rel := path.relative_to(SRC).as_posix()) not in ALLOWED
        and (bad := private_uses(path.read_text(encoding="utf-8")))
    }
    assert not found, found
