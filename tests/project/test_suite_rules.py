"""Rules of the test suite itself (issue 41): a declared dependency is imported, never skipped."""

from __future__ import annotations

import re
import tomllib
from importlib import metadata
from pathlib import Path

ROOT = Path(__file__).parents[2]
_SKIP = re.compile(r"importorskip\(\s*[\"']([\w.]+)[\"']")


def _declared_modules() -> set[str]:
    """Top-level import names of the core dependencies and the ``test`` extra."""
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    requirements = [*project["dependencies"], *project["optional-dependencies"]["test"]]
    names = {
        re.match(r"[A-Za-z0-9_.-]+", r).group().lower().replace("_", "-") for r in requirements
    }
    modules = set()
    for module, dists in metadata.packages_distributions().items():
        if any(d.lower().replace("_", "-") in names for d in dists):
            modules.add(module)
    return modules


def skipped_declared_imports(source: str, declared: set[str]) -> list[str]:
    """Modules of ``declared`` that ``source`` imports through ``pytest.importorskip``."""
    return [m for m in _SKIP.findall(source) if m.split(".")[0] in declared]


def test_no_importorskip_of_a_declared_dependency():
    declared = _declared_modules()
    assert {"numpy", "pyuff", "control", "matplotlib", "sdypy"} <= declared, declared
    call = "pytest." + "importorskip"  # split, so that this file does not match itself
    planted = f'pyuff = {call}("pyuff")\nx = {call}("not_declared")'
    assert skipped_declared_imports(planted, declared) == ["pyuff"]
    found = {
        path.name: bad
        for path in sorted((ROOT / "tests").rglob("*.py"))
        if (bad := skipped_declared_imports(path.read_text(), declared))
    }
    assert not found, f"import declared dependencies directly (a missing one must fail): {found}"


def test_markers_are_strict_and_registered():
    options = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["pytest"]["ini_options"]
    assert "--strict-markers" in options["addopts"]
    registered = {m.split(":")[0] for m in options["markers"]}
    assert {"slow", "browser", "oracle"} <= registered


_TEST_IMPORT = re.compile(r"^\s*(?:from|import)\s+(?:tests\.)?(test_\w+)", re.MULTILINE)


def imported_test_modules(source: str) -> list[str]:
    """Test modules that ``source`` imports (shared code belongs in ``tests/helpers.py``)."""
    return _TEST_IMPORT.findall(source)


def test_no_test_module_imports_another():
    """A test folder must run alone: importing a test module of another folder works only when
    that folder happened to be collected first."""
    assert imported_test_modules("from test_cli_smoke import x\nimport helpers\n") == [
        "test_cli_smoke"
    ]
    assert imported_test_modules("    from tests.test_multimode import t\n") == ["test_multimode"]
    found = {
        path.name: bad
        for path in sorted((ROOT / "tests").rglob("*.py"))
        if (bad := imported_test_modules(path.read_text()))
    }
    assert not found, f"move shared code to tests/helpers.py: {found}"
