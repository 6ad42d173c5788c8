"""The chapter-4 path model of the virtual robot: a virtual EMA along the path and a GP over it.

:func:`path_modal_model` hammers the virtual robot at points along the chapter-4 path
(thesis: 20 points 56 mm apart), fits the dominant mode of each point's FRF and fits a GP over
the path distance: the pose model every controller of :mod:`robovib.control.design` is designed
from (the truth stays hidden from the design). :func:`virtual_path_modes` reads its modes.
"""

from __future__ import annotations

import numpy as np

from ..control.pose_plants import path_mode
from ..frf.impact import impact_frf
from ..gp import PoseModalModel
from ..modal.parameters import ModalParameters
from ..modal.sdof import fit_dominant_mode
from .experiments import simulate_hammer_test
from .truth import PATH_LENGTH_M, VirtualRobot

__all__ = ["path_modal_model", "virtual_path_modes"]


def path_modal_model(
    robot: VirtualRobot,
    directions=("x", "z"),
    n_points: int = 20,
    *,
    sample_rate_hz: float = 2048.0,
    n_hits: int = 3,
    rng=0,
) -> PoseModalModel:
    """EMA at ``n_points`` along the chapter-4 path (virtual hammer tests) and a GP over s.

    Each point's FRF (:func:`robovib.frf.impact_frf`, up to 100 Hz) gives the dominant mode
    (:func:`robovib.modal.fit_dominant_mode`); a GP per output (thesis Eq. 9-10) interpolates
    them over the path distance. Read the model with
    :func:`robovib.control.pose_plants.path_mode` and
    :func:`~robovib.control.pose_plants.path_band`.

    Parameters
    ----------
    robot
        The virtual robot hammered (:class:`robovib.sim.VirtualRobot`).
    directions
        Directions of the hammer tests and of the model (``"x"``, ``"y"``, ``"z"``).
    n_points
        Test points, evenly spaced over the path ``[0, PATH_LENGTH_M]`` [m].
    sample_rate_hz
        Sample rate of the virtual hammer tests [Hz].
    n_hits
        Hits averaged per test point.
    rng
        Seed or generator of the test noise and of the GP optimiser restarts.

    Returns
    -------
    PoseModalModel
        Fitted, ``input_names=("s_m",)`` (path distance [m]), the dominant mode per direction
        (fn [Hz], k [N/m], c [N s/m]).
    """
    s = np.linspace(0.0, PATH_LENGTH_M, n_points)
    gen = np.random.default_rng(rng)
    cols = []
    for d in directions:
        rows = []
        for si in s:
            rec = simulate_hammer_test(robot, si, d, domain="path", n_hits=n_hits, sample_rate_hz=sample_rate_hz,
                                       duration_s=4.0, rng=gen)  # fmt: skip
            fit = fit_dominant_mode(
                impact_frf(rec.forces, rec.responses, rec.sample_rate_hz, f_max_hz=100).frf
            )
            p = fit.parameters
            rows.append([p.natural_frequency_hz, p.stiffness_n_per_m, p.damping_ns_per_m])
        cols.append(np.array(rows))
    model = PoseModalModel(input_names=("s_m",), directions=tuple(directions), kernel="isotropic",
                           mode_switch=False, rng=rng)  # fmt: skip
    return model.fit(s[:, None], np.hstack(cols))


def virtual_path_modes(
    robot: VirtualRobot | None = None, direction: str = "x", n_points: int = 20, rng=0
) -> tuple[np.ndarray, list[ModalParameters]]:
    """Dominant modes along the chapter-4 path from a virtual EMA (:func:`path_modal_model`).

    Parameters
    ----------
    robot
        The virtual robot (default: a new :class:`robovib.sim.VirtualRobot`).
    direction
        Direction of the hammer tests.
    n_points
        Coordinates returned, evenly spaced over 0.335-1.235 m.
    rng
        Seed of the virtual EMA.

    Returns
    -------
    s_m
        (n_points,) path coordinates [m], 0.335-1.235 m.
    modes
        One :class:`ModalParameters` per coordinate in ``direction``.
    """
    model = path_modal_model(robot or VirtualRobot(), directions=(direction,), rng=rng)
    s = np.linspace(0.335, 1.235, n_points)
    return s, [path_mode(model, si, direction) for si in s]
