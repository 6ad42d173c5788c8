"""numpydoc check of the public entry points the README lists (parameters and returns).

Fails on PR01 (parameter not documented), PR02 (unknown parameter documented), PR10 (missing
space around the colon of ``name : type``) and RT01 (no Returns section where a value is
returned). Also: every entry point has an Examples section and no docstring in the package
points outside the repository (``shared/`` notes, the thesis file) instead of ``docs/``.
"""

from __future__ import annotations

import pathlib
import re

import pytest

validate = pytest.importorskip("numpydoc.validate").validate

ENTRY_POINTS = [
    "robovib.datasets.load_table_a1",
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
    "robovib.milling.workflow.predict_at_pose",
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
