"""Exact zero-order-hold stepping of single-degree-of-freedom modes.

Each mode ``m x'' + c x' + k x = F`` with the force held over a step ``h`` advances exactly::

    [x, v]_{i+1} = Phi [x, v]_i + Gamma F_i
    Phi   = e^{-s h} [[cos + s/wd sin,  sin/wd], [-wn^2/wd sin,  cos - s/wd sin]]
    Gamma = (1/k) [1 - Phi_11 - 2 s Phi_01,  wn^2 Phi_01]

(``s = zeta wn``, ``wd = wn sqrt(1 - zeta^2)``, ``cos = cos(wd h)``, ``sin = sin(wd h)``;
``Gamma = A^-1 (Phi - I) B``). Used by the time-domain milling simulation
(:mod:`robovib.milling.time_domain`) and the virtual robot's dynamics (:mod:`robovib.sim.dynamics`).
"""

from __future__ import annotations

import numpy as np

__all__ = ["zoh_transition"]


def zoh_transition(fn_hz, stiffness_n_per_m, damping_ratio, dt_s: float):
    """Per-sample Phi (4 components, each shape like the inputs) and Gamma (2 components).

    Returns ``(p00, p01, p10, p11, g0, g1)``; underdamped modes only (zeta < 1).

    Parameters
    ----------
    fn_hz, stiffness_n_per_m, damping_ratio : array_like
        Mode parameters per sample (same shape).
    dt_s : float
        Sample period [s].

    Returns
    -------
    p00, p01, p10, p11, g0, g1 : numpy.ndarray
        Transition matrix and input vector entries, shaped like the inputs.
    """
    fn = np.asarray(fn_hz, float)
    k = np.asarray(stiffness_n_per_m, float)
    z = np.asarray(damping_ratio, float)
    if np.any(fn <= 0) or np.any(k <= 0) or np.any(z < 0) or np.any(z >= 1):
        raise ValueError("modes need fn > 0, k > 0 and 0 <= zeta < 1 (underdamped)")
    wn = 2 * np.pi * fn
    s = z * wn
    wd = wn * np.sqrt(1 - z**2)
    e = np.exp(-s * dt_s)
    c, sn = np.cos(wd * dt_s), np.sin(wd * dt_s)
    p00 = e * (c + s / wd * sn)
    p01 = e * sn / wd
    p10 = -e * wn**2 / wd * sn
    p11 = e * (c - s / wd * sn)
    g0 = (1 - p11 - 2 * s * p01) / k
    g1 = wn**2 * p01 / k
    return p00, p01, p10, p11, g0, g1
