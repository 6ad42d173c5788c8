"""Session-wide fixtures: the fitted chapter-3 model and the virtual robot, built once."""

from __future__ import annotations

import functools

import pytest


@pytest.fixture(scope="session")
def chapter3_factory():
    """:func:`robovib.gp.fit_chapter3_model` (SI PoseModalModel) memoised for the session."""
    from robovib.gp import fit_chapter3_model

    return functools.lru_cache(maxsize=None)(fit_chapter3_model)


@pytest.fixture(scope="session")
def chapter3_regressor_factory():
    """The thesis-unit chapter-3 regressor (``gpr predict``, the study) memoised for the session."""
    from robovib.studies.chapter3 import fit_chapter3_regressor

    return functools.lru_cache(maxsize=None)(fit_chapter3_regressor)


@pytest.fixture(scope="session")
def chapter3_model(chapter3_factory):
    """The default chapter-3 pose model (ARD kernel, mode switch detected, rng 0), fitted."""
    return chapter3_factory()


@pytest.fixture(scope="session")
def virtual_robot():
    """The default virtual robot of :mod:`robovib.sim`."""
    from robovib.sim import VirtualRobot

    return VirtualRobot()
