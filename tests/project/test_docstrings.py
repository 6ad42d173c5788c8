"""numpydoc check of every public name of the package, and of the README's entry points.

``test_every_public_name`` walks every module of ``robovib`` (not ``robovib.cli``: its command
functions document their options in Typer's ``help=``, checked by the CLI tests) and every
public name in it (in ``__all__``, or else not starting with ``_`` and defined there), with
the public methods of each class. It fails on PR01 (parameter not documented; a dataclass may
document its fields under Attributes), PR02 (unknown parameter documented), PR10 (missing
space around the colon of ``name : type``) and RT01 (no Returns section where a value is
returned). Names that still fail are listed in ``docstring_gaps.txt`` (issue 23): a listed name
that passes, or no longer exists, fails the test too, so the list can only shrink.

The README's entry points (``ENTRY_POINTS``) also need an Examples section whose doctests run;
every name the README's Python blocks import must be one of them.
No docstring in the package points outside the repository (``shared/`` notes, the thesis
file) instead of ``docs/``.
"""

from __future__ import annotations

import pathlib
import re

import pytest
from numpydoc.validate import validate

ENTRY_POINTS = [
    "robovib.datasets.load_table_a1",
    "robovib.datasets.modal_output_columns",
    "robovib.datasets.pose_columns",
    "robovib.datasets.example_path",
    "robovib.io.read_frf_csv",
    "robovib.campaign.save_pose_model",
    "robovib.sim.simulate_campaign",
    "robovib.gp.BatchedGPRegressor",
    "robovib.gp.BatchedGPRegressor.fit",
    "robovib.gp.BatchedGPRegressor.predict",
    "robovib.gp.PoseModalModel",
    "robovib.gp.PoseModalModel.fit",
    "robovib.gp.PoseModalModel.predict",
    "robovib.gp.PoseModalModel.modes",
    "robovib.gp.PoseModalModel.save",
    "robovib.gp.PoseModalModel.load",
    "robovib.gp.load_chapter3_model",
    "robovib.frf.impact_frf",
    "robovib.frf.estimate_frf",
    "robovib.modal.fit_dominant_mode",
    "robovib.modal.fit_modes",
    "robovib.io.read_recording_uff",
    "robovib.io.read_recording_csv",
    "robovib.campaign.process_campaign",
    "robovib.campaign.fit_pose_model_from_table",
    "robovib.campaign.next_poses",
    "robovib.milling.at_pose.predict_at_pose",
    "robovib.milling.stability.stability_lobes",
    "robovib.milling.sdm.sdm_lobes",
    "robovib.milling.maps.workspace_lobe_map",
    "robovib.control.design_lqr",
    "robovib.control.schedule.schedule_gains",
    "robovib.hybrid.FRFPoseModel",
    "robovib.hybrid.oma_frfs",
    "robovib.sim.simulate_hammer_test",
    "robovib.robot.KR500.fk",
    "robovib.robot.dynamics.cartesian_stiffness",
]
PARAMETER_CODES = {"PR01", "PR02", "PR10", "RT01"}


@pytest.mark.parametrize("name", ENTRY_POINTS)
def test_parameters_and_returns_documented(name):
    result = validate(name)
    errors = [f"{code}: {msg}" for code, msg in result["errors"] if code in PARAMETER_CODES]
    assert not errors, f"{name} ({result['file']}:{result['file_line']}): " + "; ".join(errors)
    assert "EX01" not in {code for code, _ in result["errors"]}, f"{name}: no Examples section"


GAPS_FILE = pathlib.Path(__file__).with_name("docstring_gaps.txt")


def _public_names() -> list[str]:
    """Every public function, class and class method of ``robovib`` (not ``robovib.cli``)."""
    import importlib
    import inspect
    import pkgutil

    import robovib

    modules = ["robovib"] + [
        m.name
        for m in pkgutil.walk_packages(robovib.__path__, "robovib.")
        if not any(part.startswith("_") for part in m.name.split(".")[1:])
        and not m.name.startswith("robovib.cli")
    ]
    names = set()
    for module_name in modules:
        module = importlib.import_module(module_name)
        listed = getattr(module, "__all__", None)
        candidates = listed if listed is not None else [n for n in vars(module) if n[0] != "_"]
        for n in candidates:
            obj = getattr(module, n, None)
            if not (inspect.isfunction(obj) or inspect.isclass(obj)):
                continue
            home = getattr(obj, "__module__", "") or ""
            if not home.startswith("robovib") or (listed is None and home != module_name):
                continue
            qualified = f"{home}.{obj.__qualname__}"
            names.add(qualified)
            if inspect.isclass(obj):
                names.update(
                    f"{qualified}.{a}"
                    for a, v in vars(obj).items()
                    if a[0] != "_"
                    and (isinstance(v, (staticmethod, classmethod)) or inspect.isfunction(v))
                )
    return sorted(names)


def _object(name: str):
    import importlib

    parts = name.split(".")
    for i in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:i]))
        except ImportError:
            continue
        for part in parts[i:]:
            obj = getattr(obj, part)
        return obj
    raise ImportError(name)


def _parameter_errors(name: str) -> list[str]:
    import inspect

    from numpydoc.docscrape import ClassDoc

    result = validate(name)
    errors = [f"{code}: {msg}" for code, msg in result["errors"] if code in PARAMETER_CODES]
    obj = _object(name)
    if inspect.isclass(obj):  # a dataclass documents its fields under Attributes
        doc = ClassDoc(obj)
        documented = {
            n.strip().lstrip("*")
            for p in [*doc["Parameters"], *doc["Attributes"]]
            for n in p.name.split(",")
        }
        try:
            params = set(inspect.signature(obj).parameters) - {"self", "args", "kwargs"}
        except ValueError:  # no Python signature (an exception type)
            params = set()
        missing = sorted(params - documented)
        errors = [e for e in errors if not e.startswith("PR01")]
        errors += [f"PR01: parameters {missing} not documented"] if missing else []
    return errors


def test_every_public_name():
    names = _public_names()
    assert len(names) > 400  # the walk finds the package, not a handful of names
    gaps = {ln.strip() for ln in GAPS_FILE.read_text().splitlines() if ln.strip()[:1] not in "#"}
    failing = {}
    for name in names:
        errors = _parameter_errors(name)
        if errors:
            failing[name] = errors
    new = {n: e for n, e in failing.items() if n not in gaps}
    assert not new, "undocumented parameters/returns: " + "; ".join(
        f"{n}: {' '.join(e)}" for n, e in sorted(new.items())
    )
    fixed = sorted(gaps - set(failing))
    assert not fixed, f"documented now (or gone): remove from {GAPS_FILE.name}: {fixed}"


def test_gap_check_can_fail():
    """The check flags a planted undocumented parameter and a missing Returns section."""
    errors = _parameter_errors("tests_planted_docstring.undocumented")
    assert any(e.startswith("PR01") for e in errors) and any(e.startswith("RT01") for e in errors)


def test_docstrings_point_inside_the_repository():
    import robovib

    root = pathlib.Path(robovib.__file__).parent
    bad = [
        f"{f.relative_to(root)}:{i}"
        for f in root.rglob("*.py")
        for i, line in enumerate(f.read_text().splitlines(), 1)
        if re.search(r"\.\./shared|shared/notes|thesis-notes|seed/thesis\.md", line)
    ]
    assert not bad, f"references outside the repository (point to docs/ instead): {bad}"


def _resolve(name: str):
    import importlib

    module, _, attr = name.rpartition(".")
    try:
        return getattr(importlib.import_module(module), attr)
    except ImportError:
        parent, _, cls = module.rpartition(".")
        return getattr(getattr(importlib.import_module(parent), cls), attr)


@pytest.mark.parametrize("name", ENTRY_POINTS)
def test_examples_run(name):
    """The Examples of each entry point run and print what they claim (doctest)."""
    import doctest

    tests = [
        t for t in doctest.DocTestFinder(recurse=False).find(_resolve(name), name) if t.examples
    ]
    assert tests, f"{name}: no doctest examples"
    for t in tests:
        runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS)
        runner.run(t, out=lambda s: None)
        assert runner.failures == 0, f"{name}: {runner.failures} failing example(s)"


README = pathlib.Path(__file__).resolve().parents[2] / "README.md"


def readme_imports(text: str) -> set[str]:
    """``robovib.<module>.<name>`` of every name a ```python block of ``text`` imports."""
    import ast

    names = set()
    for block in re.findall(r"```python\n(.*?)```", text, flags=re.S):
        for node in ast.walk(ast.parse(block)):
            if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("robovib"):
                names |= {f"{node.module}.{a.name}" for a in node.names}
    return names


def test_entry_points_cover_the_readme():
    """Every name the README's Python blocks import is an entry point (so has an Example)."""
    imported = readme_imports(README.read_text(encoding="utf-8"))
    assert len(imported) >= 5, imported  # the README's blocks were found
    missing = sorted(imported - set(ENTRY_POINTS))
    assert not missing, f"README names without an entry in ENTRY_POINTS: {missing}"


def test_readme_import_check_can_fail():
    planted = "text\n```python\nfrom robovib.gp import A, B\nimport numpy\n```\n```bash\nx\n```\n"
    assert readme_imports(planted) == {"robovib.gp.A", "robovib.gp.B"}
