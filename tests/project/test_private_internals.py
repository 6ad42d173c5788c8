"""robovib uses no private module of Typer or rich (issue 41): a release may change them silently.

No exception is left: ``cli/_coerce.py`` (the light converter that keeps Pydantic out of a
command run) overrides click's public ``process_value`` and reads the command functions' own
annotations; ``tests/cli/test_cli_coerce.py`` checks it against Typer's own converter.
"""

from __future__ import annotations

import re
from pathlib import Path

SRC = Path(__file__).resolve().parents[2] / "src" / "robovib"
#: ``typer._x`` / ``rich._x`` modules, Typer's vendored click, rich's private table cells.
_PRIVATE = re.compile(r"\b(?:typer|rich)(?:\.\w+)*\._\w+|\b_click\b|\._cells\b|_runtime_param\b")
ALLOWED: set[str] = set()


def private_uses(source: str) -> list[str]:
    """Private Typer/rich names used by ``source`` (comments and docstrings included)."""
    return sorted(set(_PRIVATE.findall(source)))


def test_planted_private_uses_are_found():
    planted = "from typer._click.globals import x\nn = col._cells\nimport rich._loop\n"
    assert private_uses(planted) == ["._cells", "rich._loop", "typer._click"]
    assert private_uses("from typer import _click") == ["_click"]
    assert private_uses("import typer\nfrom rich.table import Table\ncol.cells\n") == []


def test_no_private_typer_or_rich_in_robovib():
    found = {
        rel: bad
        for path in sorted(SRC.rglob("*.py"))
        if (rel := path.relative_to(SRC).as_posix()) not in ALLOWED
        and (bad := private_uses(path.read_text(encoding="utf-8")))
    }
    assert not found, found
