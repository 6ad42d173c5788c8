"""Where to hammer next along the chapter-4 path (virtual EMA, one FRF pose model)."""

from __future__ import annotations

import numpy as np

from ...campaign.selection import NextPoses
from ...hybrid.model import FRFPoseModel
from ...sim import (
    PATH_LENGTH_M,
    VirtualRobot,
)
from .study import ema_frf_on_grid

__all__ = [
    "propose_next_poses",
]


def propose_next_poses(tested_s_m, k: int = 3, direction: str = "x", rng=0) -> NextPoses:
    """Where to hammer next along the chapter-4 path: largest integrated variance reduction.

    Virtual EMA FRFs (2-40 Hz, 1 Hz grid) at ``tested_s_m`` [m] train an
    :class:`~robovib.hybrid.FRFPoseModel`; :meth:`~robovib.hybrid.FRFPoseModel.next_poses`
    (:func:`robovib.campaign.next_poses`) picks ``k`` of 50 candidates along the path. Draw
    the result with :func:`robovib.campaign.plot_next_poses`.

    Parameters
    ----------
    tested_s_m : array_like
        Tested path coordinates [m].
    k : int
        Poses to propose.
    direction : {"x", "y", "z"}
        Direction of the FRFs.
    rng : int
        Seed of the virtual EMA and the model.

    Returns
    -------
    NextPoses
        The proposed coordinates (``poses[:, 0]`` [m]), the candidates with their variance
        and the tested coordinates (``training_poses[:, 0]``).

    Raises
    ------
    ValueError
        Bad direction, ``k`` or path coordinates.
    """
    tested = np.asarray(tested_s_m, float).ravel()
    robot = VirtualRobot()
    grid = np.arange(2.0, 40.0, 1.0)
    gen = np.random.default_rng(rng)
    frfs = np.array([ema_frf_on_grid(robot, s, direction, grid, gen) for s in tested])
    model = FRFPoseModel(grid, rng=rng).fit(tested, frfs)
    return model.next_poses(np.linspace(0, PATH_LENGTH_M, 50), k=k)
