"""Data flows one way: no core package imports the simulator or the thesis studies."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "src" / "robovib"
CORE = ("frf", "modal", "gp", "robot", "milling", "control", "hybrid", "io")
FORBIDDEN = ("sim", "studies")

# Known violators, being moved to robovib.studies by other engineers ("control", "hybrid").
# The lead empties this list when those branches are merged; do not add to it.
ALLOWED: set[str] = set()


def _imported_modules(source: str, package: list[str]) -> list[str]:
    """Absolute names of the modules imported by ``source`` living in ``package``."""
    names = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            names += [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package[: len(package) - node.level + 1]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            names.append(mod)
            # "from .. import sim" imports the subpackage itself.
            names += [f"{mod}.{a.name}" for a in node.names]
    return names


def _violations(source: str, package: list[str]) -> list[str]:
    bad = []
    for name in _imported_modules(source, package):
        parts = name.split(".")
        if len(parts) >= 2 and parts[0] == "robovib" and parts[1] in FORBIDDEN:
            bad.append(name)
    return bad


def _package_of(path: Path) -> list[str]:
    return ["robovib", *path.relative_to(SRC).parent.parts]


@pytest.mark.parametrize("package", CORE)
def test_core_packages_do_not_import_sim_or_studies(package):
    offenders = {}
    for path in sorted((SRC / package).rglob("*.py")):
        rel = path.relative_to(SRC).as_posix()
        bad = _violations(path.read_text(encoding="utf-8"), _package_of(path))
        if bad and rel not in ALLOWED:
            offenders[rel] = sorted(set(bad))
    assert not offenders, f"core modules importing sim/studies: {offenders}"


def test_allow_list_entries_exist_and_still_violate():
    # A stale entry would hide a future violation in a file of the same name.
    for rel in ALLOWED:
        path = SRC / rel
        if path.exists():
            source = path.read_text(encoding="utf-8")
            assert _violations(source, _package_of(path)), (
                f"{rel} no longer imports sim/studies: remove it from ALLOWED"
            )


def test_the_checker_sees_relative_and_absolute_imports():
    cases = {
        "from ..sim import truth\n": True,
        "from .. import studies\n": True,
        "import robovib.sim.truth\n": True,
        "from robovib.studies.chapter3 import chapter3_study\n": True,
        "from ..datasets import load_table_a1\n": False,
        "from .regressor import BatchedGPRegressor\n": False,
    }
    for code, violates in cases.items():
        assert bool(_violations(code, ["robovib", "gp"])) is violates, code
