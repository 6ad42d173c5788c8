"""Data flows one way: no core package imports the simulator, the studies, the report or the CLI,
and the packages import each other without a circle (function-level imports included)."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[2] / "src" / "robovib"
#: The application layers: everything else is core and may not import them.
APPLICATION = ("cli", "studies", "sim", "report")
CORE = tuple(
    sorted(p.name for p in SRC.iterdir() if p.is_dir() and (p / "__init__.py").exists()
           and p.name not in APPLICATION)
)  # fmt: skip
FORBIDDEN = ("sim", "studies", "report", "cli")


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
        if bad:
            offenders[rel] = sorted(set(bad))
    assert not offenders, f"core modules importing {FORBIDDEN}: {offenders}"


def test_top_level_modules_are_core():
    """``robovib/__init__.py`` and the shared helpers (``_linalg``, ``_lazy``...) sit below every
    package, so they import no application layer either."""
    offenders = {
        path.name: bad
        for path in sorted(SRC.glob("*.py"))
        if (bad := _violations(path.read_text(encoding="utf-8"), ["robovib"]))
    }
    assert not offenders, f"top-level modules importing {FORBIDDEN}: {offenders}"
    assert _violations("def f():\n    from .studies import hybrid\n", ["robovib"]) == [
        "robovib.studies",
        "robovib.studies.hybrid",
    ]


def test_core_list_covers_the_packages():
    assert {"frf", "modal", "gp", "io", "milling", "control", "hybrid", "campaign", "datasets",
            "robot"} <= set(CORE)  # fmt: skip


def package_graph(root: Path = SRC) -> dict[str, set[str]]:
    """Package -> packages of robovib it imports, at any depth of the code (function-level
    imports included: a circle hidden inside a function is still a circle)."""
    graph: dict[str, set[str]] = {}
    for path in root.rglob("*.py"):
        rel = path.relative_to(root)
        if len(rel.parts) < 2:
            continue
        pkg = rel.parts[0]
        for name in _imported_modules(path.read_text(encoding="utf-8"), _package_of_in(path, root)):
            parts = name.split(".")
            if len(parts) >= 2 and parts[0] == "robovib" and (root / parts[1]).is_dir():
                if parts[1] != pkg:
                    graph.setdefault(pkg, set()).add(parts[1])
    return graph


def _package_of_in(path: Path, root: Path) -> list[str]:
    return ["robovib", *path.relative_to(root).parent.parts]


def cycles(graph: dict[str, set[str]]) -> list[tuple[str, str]]:
    """Edges (a, b) of the graph that lie on a circle (b reaches a)."""

    def reach(a: str) -> set[str]:
        seen, stack = set(), [a]
        while stack:
            for nxt in graph.get(stack.pop(), ()):
                if nxt not in seen:
                    seen.add(nxt)
                    stack.append(nxt)
        return seen

    return sorted((a, b) for a, nbrs in graph.items() for b in nbrs if a in reach(b))


def test_no_circle_between_packages():
    assert cycles(package_graph()) == []


def module_graph(root: Path = SRC) -> dict[str, set[str]]:
    """Module -> modules of robovib it imports (function-level imports included), inside and
    across packages; an import of a package's ``__init__`` from inside it is left out."""
    graph: dict[str, set[str]] = {}
    for path in root.rglob("*.py"):
        rel = path.relative_to(root)
        mod = ".".join(["robovib", *rel.with_suffix("").parts]).removesuffix(".__init__")
        for name in _imported_modules(path.read_text(encoding="utf-8"), _package_of_in(path, root)):
            parts = name.split(".")
            while len(parts) > 1:  # the module, not the name imported from it
                where = root.joinpath(*parts[1:])
                if where.with_suffix(".py").exists() or (where / "__init__.py").exists():
                    break
                parts = parts[:-1]
            target = ".".join(parts)
            if len(parts) > 1 and target != mod and not mod.startswith(target + "."):
                graph.setdefault(mod, set()).add(target)
    return graph


def test_no_circle_between_modules():
    """No two modules of robovib reach each other, through imports at any depth of the code."""
    assert cycles(module_graph()) == []


def test_module_circle_check_fails_on_a_planted_circle(tmp_path):
    """Two modules of one package importing each other, one inside a function, form a circle."""
    pkg = tmp_path / "robovib" / "hybrid"
    pkg.mkdir(parents=True)
    (pkg / "__init__.py").write_text("from .model import M\n")
    (pkg / "model.py").write_text("def fit():\n    from .workflow import grid\n")
    (pkg / "workflow.py").write_text("from .model import M\nfrom . import model\n")
    found = set(cycles(module_graph(tmp_path / "robovib")))
    assert found == {
        ("robovib.hybrid.model", "robovib.hybrid.workflow"),
        ("robovib.hybrid.workflow", "robovib.hybrid.model"),
    }


def test_report_reads_results_not_studies():
    """The report renders results; running a study and reporting it is the studies' job
    (``robovib.studies.reports``), so the arrow runs studies -> report only."""
    graph = package_graph()
    assert "studies" not in graph.get("report", set())
    assert "report" in graph.get("studies", set())


def test_layer_checks_fail_on_planted_violations(tmp_path):
    """The checks can fail: a planted upward import and a planted circle are both found."""
    root = tmp_path / "robovib"
    for pkg, code in {
        "gp": "def f():\n    from ..studies import chapter3\n",  # upward, inside a function
        "io": "def g():\n    from ..frf import FRF\n",
        "frf": "def h():\n    from ..io import read_frfs\n",  # frf <-> io circle
        "studies": "",
    }.items():
        (root / pkg).mkdir(parents=True)
        (root / pkg / "__init__.py").write_text("")
        (root / pkg / "mod.py").write_text(code)
    up = _violations((root / "gp" / "mod.py").read_text(), ["robovib", "gp"])
    assert up == ["robovib.studies", "robovib.studies.chapter3"]
    assert set(cycles(package_graph(root))) == {("frf", "io"), ("io", "frf")}


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


#: The floors of the house, ground floor first: a package imports only from floors below its
#: own. The plumbing (``files``) is at the bottom and imports no other robovib package.
FLOORS = (
    ("files",),
    ("frf", "datasets", "robot"),
    ("modal",),
    ("io", "gp"),
    ("control", "milling", "campaign"),
    ("hybrid",),
    ("report", "sim"),
    ("studies",),
    ("cli",),
)


def upward_imports(graph: dict[str, set[str]]) -> list[tuple[str, str]]:
    """Edges (a, b) where package ``a`` imports ``b`` on its own floor or a higher one."""
    floor = {pkg: level for level, pkgs in enumerate(FLOORS) for pkg in pkgs}
    return sorted((a, b) for a, nbrs in graph.items() for b in nbrs if floor[b] >= floor[a])


def test_every_package_has_a_floor():
    packages = {p.name for p in SRC.iterdir() if p.is_dir() and (p / "__init__.py").exists()}
    assert packages == {pkg for pkgs in FLOORS for pkg in pkgs}


def test_no_import_from_a_lower_floor_to_a_higher_one():
    assert upward_imports(package_graph()) == []


def test_the_plumbing_imports_no_other_package():
    assert package_graph().get("files", set()) == set()


def test_the_floor_check_fails_on_a_planted_upward_import():
    assert upward_imports({"files": {"io"}, "gp": {"files"}}) == [("files", "io")]
    assert upward_imports({"io": {"gp"}}) == [("io", "gp")]  # same floor is not allowed
