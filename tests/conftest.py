"""Session-wide fixtures: the fitted chapter-3 model and the virtual robot, built once."""

from __future__ import annotations

import functools

import pytest


@pytest.fixture(scope="session")
def chapter3_factory():
    """``fit_chapter3_model`` memoised over its arguments for the whole session."""
    from robovib.gp.study import fit_chapter3_model

    return functools.lru_cache(maxsize=None)(fit_chapter3_model)


@pytest.fixture(scope="session")
def chapter3_model(chapter3_factory):
    """The default chapter-3 pose model (ARD kernel, mode switch classified, rng 0)."""
    return chapter3_factory()


@pytest.fixture(scope="session")
def virtual_robot():
    """The default virtual robot of :mod:`robovib.sim`."""
    from robovib.sim import VirtualRobot

    return VirtualRobot()
