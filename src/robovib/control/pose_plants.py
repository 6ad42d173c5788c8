"""The plants a pose-model controller design must hold on (thesis ch. 4).

A pose model over the path coordinate (:class:`robovib.gp.PoseModalModel` with
``input_names=("s_m",)``) gives the dominant mode at a path distance (:func:`path_mode`, the
posterior mean, Eq. 9) and the corners of its band (:func:`path_band`, Eq. 10);
:func:`plant_set` adds the unmodelled second modes of :data:`SECOND_MODE_HYPOTHESES`. The
robust and tuned designs of :mod:`robovib.control.design` are checked on these.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ..modal.parameters import ModalParameters

if TYPE_CHECKING:
    from ..gp import PoseModalModel

__all__ = ["SECOND_MODE_HYPOTHESES", "path_band", "path_mode", "plant_set"]


def path_mode(model: PoseModalModel, s_m: float, direction: str) -> ModalParameters:
    """Mean dominant mode of ``direction`` at path distance ``s_m`` [m].

    Parameters
    ----------
    model
        A path model over ``input_names=("s_m",)`` (e.g. :func:`robovib.sim.path_modal_model`).
    s_m
        Path distance [m].
    direction
        One of the model's directions.

    Returns
    -------
    ModalParameters
        The posterior-mean mode (thesis Eq. 9) at ``s_m``.
    """
    return model.modes(np.array([[float(s_m)]]))[0][direction].parameters


def path_band(
    model: PoseModalModel, s_m: float, direction: str, z_score: float = 1.96
) -> list[ModalParameters]:
    """The 8 corners of the GP band at ``s_m`` [m]: mean ± ``z_score`` std in fn, k and c.

    Corners are clipped to fn >= 0.1 Hz, k >= 1 kN/m, c >= 0 and a damping ratio in
    [0.001, 0.95].

    Parameters
    ----------
    model
        A path model over ``input_names=("s_m",)`` (e.g. :func:`robovib.sim.path_modal_model`).
    s_m
        Path distance [m].
    direction
        One of the model's directions.
    z_score
        Half-width of the band in predictive standard deviations (Eq. 10); 1.96: 95 %.

    Returns
    -------
    list of ModalParameters
        The 8 corner modes (every sign combination of fn, k and c).
    """
    pm = model.modes(np.array([[float(s_m)]]))[0][direction]
    p = pm.parameters
    out = []
    for sf in (-1, 1):
        for sk in (-1, 1):
            for sc in (-1, 1):
                fn = max(p.natural_frequency_hz + sf * z_score * pm.fn_std_hz, 0.1)
                k = max(p.stiffness_n_per_m + sk * z_score * pm.stiffness_std_n_per_m, 1e3)
                c = max(p.damping_ns_per_m + sc * z_score * pm.damping_std_ns_per_m, 0.0)
                m = ModalParameters.from_fn_k_c(fn, k, c)
                zeta = min(max(m.damping_ratio, 1e-3), 0.95)
                out.append(ModalParameters(fn, k, zeta))
    return out


#: Unmodelled-dynamics hypotheses of the robust design: a second mode at (fn ratio, k ratio,
#: zeta) relative to the dominant one. The hammer-test FRFs along the path show a second,
#: lighter-damped mode at 2-3 x the dominant frequency that the dominant-mode GP drops; a
#: design checked only on the dominant mode goes unstable on it with 32 ms of delay.
SECOND_MODE_HYPOTHESES = ((2.0, 5.0, 0.03), (2.0, 20.0, 0.03), (3.0, 5.0, 0.03), (3.0, 20.0, 0.03))


def plant_set(
    model: PoseModalModel, s_m: float, direction: str, second_modes: bool = True
) -> list[list[ModalParameters]]:
    """Plants the robust design must hold on: nominal (first) + band corners (x second modes).

    Parameters
    ----------
    model
        A path model (``input_names=("s_m",)``).
    s_m
        Path distance [m].
    direction
        One of the model's directions.
    second_modes
        Also each single-mode plant with each :data:`SECOND_MODE_HYPOTHESES` second mode.

    Returns
    -------
    list of list of ModalParameters
        Each plant as its modes: first the nominal mode alone, then the 8 band corners
        (:func:`path_band`), then (``second_modes``) each of those 9 with each second mode.
    """
    singles = [path_mode(model, s_m, direction), *path_band(model, s_m, direction)]
    out = [[m] for m in singles]
    if second_modes:
        for m in singles:
            for fr, kr, z in SECOND_MODE_HYPOTHESES:
                out.append(
                    [m, ModalParameters(fr * m.natural_frequency_hz, kr * m.stiffness_n_per_m, z)]
                )
    return out
