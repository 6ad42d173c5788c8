"""Loop analysis of the run-time controllers: closed-loop matrices, learning-loop radii,
sensitivities and the tuned state-feedback design (thesis ch. 4 and beyond).

The controllers themselves are in :mod:`robovib.control.controllers` and
:mod:`robovib.control.adaptive`; the Kalman filter design is beside the LQR
(:func:`robovib.control.lqr.design_kalman`); :func:`~robovib.control.lqr.spectral_radius` is
the one stability measure.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from ..modal.parameters import ModalParameters
from .lqr import continuous_model, design_delay_aware_lqr, discretize, spectral_radius

if TYPE_CHECKING:
    from .lqr import KalmanDesign

__all__ = [
    "delay_aware_gains",
    "design_tuned_state_feedback",
    "implemented_loop_matrix",
    "lqg_loop_matrix",
    "modal_correction_frf",
    "repetitive_loop_radius",
    "state_feedback_sensitivity",
]


def implemented_loop_matrix(
    mode: ModalParameters | Sequence[ModalParameters],
    gains: Sequence[float],
    period_s: float = 0.004,
    delay_steps: int = 8,
    *,
    velocity: str = "difference",
    plant_delay_steps: int | None = None,
    actuator_gain: float = 1.0,
) -> np.ndarray:
    """Closed-loop matrix of a plant under ``u = -(g0 x + g1 v + g[2:] u_hist)`` with delay.

    The loop as run: the command-rate model (exact ZOH) of one mode or of a sum of modes (the
    tip displacement is their sum; a correction enters each mode like a force ``k_s u``,
    ``k_s = 1 / sum(1 / k_r)``, as in :mod:`robovib.sim.plant`), the correction applied
    ``delay_steps`` periods late, and the velocity either by backward difference over one
    period (``"difference"``, the thesis' implementation: the state gets ``x_{k-1}``) or exact
    (``"exact"``). ``gains`` has 2 entries ([w1, w2]) or 2 + ``delay_steps`` (delay-aware).
    State ``[modes' (x, v)..., (x_{k-1}), u_{k-1}, ..., u_{k-d}]``. Stable iff the spectral
    radius < 1.

    Parameters
    ----------
    mode : ModalParameters or sequence of ModalParameters
        One mode or a sum of modes.
    gains : sequence of float
        ``[g0, g1, g2 ...]``.
    period_s : float
        Command period [s].
    delay_steps : int
        Transport delay in command periods.
    velocity : str
        How the velocity is obtained (``"difference"``: backward difference).
    plant_delay_steps : int or None
        The *true* transport delay in command periods, when it differs from the
        ``delay_steps`` the gains were designed for (the controller still feeds back its
        last ``delay_steps`` commands; the plant gets the command ``plant_delay_steps``
        periods late). None: ``delay_steps``.
    actuator_gain : float
        The robot applies ``actuator_gain`` x the commanded correction (an actuator-gain
        error: ``1 + actuator_gain_pct / 100`` of :class:`~robovib.sim.CutDisturbances`);
        the controller's own command history holds the commanded values. Finite, > 0.

    Returns
    -------
    numpy.ndarray
        The closed-loop state matrix over one command period.
    """
    modes = [mode] if isinstance(mode, ModalParameters) else list(mode)
    g = np.asarray(gains, float)
    d = int(delay_steps)
    if g.size not in (2, 2 + d):
        raise ValueError(f"gains must have 2 or 2 + delay_steps = {2 + d} entries, got {g.size}")
    if velocity not in ("difference", "exact"):
        raise ValueError(f"unknown velocity {velocity!r}; expected 'difference' or 'exact'")
    k_s = 1.0 / sum(1.0 / m.stiffness_n_per_m for m in modes)
    nm = 2 * len(modes)
    ad = np.zeros((nm, nm))
    bd = np.zeros((nm, 1))
    for i, m in enumerate(modes):
        a, b = continuous_model(m)
        ai, bi = discretize(a, b * (k_s / m.stiffness_n_per_m), period_s)
        ad[2 * i : 2 * i + 2, 2 * i : 2 * i + 2] = ai
        bd[2 * i : 2 * i + 2] = bi
    cx = np.zeros(nm)
    cx[0::2] = 1.0  # tip displacement
    cv = np.zeros(nm)
    cv[1::2] = 1.0  # tip velocity
    hist = g[2:] if g.size > 2 else np.zeros(d)
    diff = velocity == "difference"
    true_d = d if plant_delay_steps is None else int(plant_delay_steps)
    if true_d < 0:
        raise ValueError(f"plant_delay_steps must be >= 0, got {plant_delay_steps!r}")
    if not (np.isfinite(actuator_gain) and actuator_gain > 0):
        raise ValueError(f"actuator_gain must be finite and > 0, got {actuator_gain!r}")
    bd = bd * float(actuator_gain)  # what reaches the plant; the history keeps the command
    length = max(d, true_d)  # commands kept in the state
    n = nm + int(diff) + length
    big = np.zeros((n, n))
    big[:nm, :nm] = ad
    h0 = nm + int(diff)  # index of u_{k-1}
    row = np.zeros(n)  # u_k as a row over the state
    if diff:
        row[:nm] = -(g[0] + g[1] / period_s) * cx
        row[nm] = g[1] / period_s
        big[nm, :nm] = cx
    else:
        row[:nm] = -g[0] * cx - g[1] * cv
    row[h0 : h0 + d] = -hist
    if true_d == 0:
        big[:nm, :] += bd @ row[None, :]
    else:
        big[:nm, h0 + true_d - 1] += bd[:, 0]
    if length == 0:
        return big
    big[h0, :] = row
    for i in range(1, length):
        big[h0 + i, h0 + i - 1] = 1.0
    return big


def repetitive_loop_radius(
    ratio: complex, gain: float, delay_cycles: int, window_cycles: int
) -> float:
    """Spectral radius of the phasor learning loop of :class:`RepetitiveFeedback` at one harmonic.

    Per command cycle ``U_{n+1} = U_n - gain (D + ratio * mean(U_{n-m}, ..., U_{n-m-L+1}))``
    with ``ratio = P_true / P_model`` at the harmonic, ``m = delay_cycles`` (the transport
    delay) and ``L = window_cycles`` (the DFT window of one excitation period). The
    characteristic polynomial ``z^M (z - 1) + (gain ratio / L) sum_q z^{M-q}``
    (``M = m + L - 1``) has all roots inside the unit circle iff the learning converges.

    Parameters
    ----------
    ratio : complex
        ``P_true / P_model`` at the harmonic.
    gain : float
        Learning gain.
    delay_cycles : int
        Transport delay in command cycles.
    window_cycles : int
        DFT window in command cycles.

    Returns
    -------
    float
        Largest root magnitude of the characteristic polynomial.
    """
    m, L = int(delay_cycles), max(1, int(window_cycles))
    big_m = m + L - 1
    coeffs = np.zeros(big_m + 2, complex)  # highest power first: z^{M+1}
    coeffs[0] = 1.0
    coeffs[1] = -1.0
    for q in range(m, m + L):
        coeffs[1 + q] += gain * ratio / L
    return float(np.max(np.abs(np.roots(coeffs))))


def modal_correction_frf(modes: Sequence[ModalParameters], frequency_hz) -> np.ndarray:
    """Correction-to-tip FRF of a sum of modes (a held correction moves the tip by itself).

    ``sum_r (k_s / k_r) wn_r^2 / (wn_r^2 - w^2 + 2 j zeta_r wn_r w)``, ``k_s = 1 / sum(1 / k_r)``.

    Parameters
    ----------
    modes : sequence of ModalParameters
        The modes.
    frequency_hz : array_like
        Frequencies [Hz].

    Returns
    -------
    numpy.ndarray
        Complex tip displacement per correction [m/m].
    """
    w = 2 * np.pi * np.asarray(frequency_hz, float)
    k_s = 1.0 / sum(1.0 / m.stiffness_n_per_m for m in modes)
    out = np.zeros(w.shape, complex)
    for m in modes:
        wn, z = m.omega_n, m.damping_ratio
        out += (k_s / m.stiffness_n_per_m) * wn**2 / (wn**2 - w**2 + 2j * z * wn * w)
    return out


def lqg_loop_matrix(
    plant: Sequence[ModalParameters],
    gains: Sequence[float],
    kalman: KalmanDesign,
    period_s: float = 0.004,
    dt_s: float = 1e-3,
    delay_samples: int = 32,
) -> np.ndarray:
    """Monodromy matrix (one command period) of :class:`DelayAwareFeedback` with its Kalman filter.

    The loop exactly as run: the true ``plant`` (a sum of modes, corrections entering through
    the static stiffness) at the sensor rate, the Kalman filter updated with every tracker
    sample and fed with the corrections ``delay_samples`` late, the delay-aware gains
    ``[K_x, K_v, K_u1..K_ud]`` applied at each command instant. The period map is built by
    propagating the basis of the state ``[plant (x, v per mode), filter prior (2),
    u_{k-1} .. u_{k-d-1}]`` through the samples of one period. Stable iff its spectral
    radius < 1. Needs ``delay_samples`` to be a whole number of command periods.

    Parameters
    ----------
    plant : sequence of ModalParameters
        The true modes.
    gains : sequence of float
        Delay-aware gains ``[K_x, K_v, K_u1..K_ud]``.
    kalman : KalmanDesign
        The filter.
    period_s, dt_s : float
        Command and sensor periods [s].
    delay_samples : int
        Transport delay in sensor samples.

    Returns
    -------
    numpy.ndarray
        The period map (its spectral radius < 1: stable).
    """
    every = round(period_s / dt_s)
    if delay_samples % every:
        raise ValueError("delay_samples must be a whole number of command periods")
    d = delay_samples // every
    g = np.asarray(gains, float)
    if g.size != 2 + d:
        raise ValueError(f"gains must have 2 + d = {2 + d} entries, got {g.size}")
    modes = list(plant)
    k_s = 1.0 / sum(1.0 / m.stiffness_n_per_m for m in modes)
    nm = 2 * len(modes)
    a1 = np.zeros((nm, nm))
    b1 = np.zeros(nm)
    for i, m in enumerate(modes):
        a, b = continuous_model(m)
        ai, bi = discretize(a, b * (k_s / m.stiffness_n_per_m), dt_s)
        a1[2 * i : 2 * i + 2, 2 * i : 2 * i + 2] = ai
        b1[2 * i : 2 * i + 2] = bi[:, 0]
    n = nm + 2 + d + 1
    z = np.eye(n)  # every basis vector at once, one per column
    p, prior, buf = z[:nm], z[nm : nm + 2], z[nm + 2 :]
    for o in range(every):
        y = p[0::2].sum(axis=0)
        post = prior + kalman.gain[:, None] * (y - prior[0])[None, :]
        if o == 0:
            u = -(g[0] * post[0] + g[1] * post[1] + g[2:] @ buf[:d])
            buf = np.vstack([u[None, :], buf[:-1]])
        applied = buf[-1]
        prior = kalman.phi @ post + kalman.gamma_u[:, None] * applied[None, :]
        p = a1 @ p + b1[:, None] * applied[None, :]
    return np.vstack([p, prior, buf])


def state_feedback_sensitivity(
    mode: ModalParameters,
    gains: Sequence[float],
    frequency_hz,
    period_s: float = 0.004,
    delay_s: float = 0.032,
) -> np.ndarray:
    """|S| = |1 / (1 + P C)| of ``u = -(w1 x + w2 v)`` with the delay: closed / open amplitude.

    ``P`` the mode's correction-to-tip FRF, ``C = (w1 + w2 (1 - e^{-sT}) / T) e^{-s (delay +
    T / 2)}`` (backward difference over the command period ``T``, the zero-order hold as half a
    period of delay): the sampled loop's response to a disturbance well below the 125 Hz
    Nyquist frequency.

    Parameters
    ----------
    mode : ModalParameters
        The mode.
    gains : sequence of float
        ``[w1, w2]``.
    frequency_hz : array_like
        Frequencies [Hz].
    period_s, delay_s : float
        Command period and transport delay [s].

    Returns
    -------
    numpy.ndarray
        |S| at each frequency.
    """
    s = 2j * np.pi * np.asarray(frequency_hz, float)
    p = modal_correction_frf([mode], np.asarray(frequency_hz, float))
    c = (gains[0] + gains[1] * (1 - np.exp(-s * period_s)) / period_s) * np.exp(
        -s * (delay_s + period_s / 2)
    )
    return np.abs(1.0 / (1.0 + p * c))


def design_tuned_state_feedback(
    plants: Sequence[Sequence[ModalParameters]],
    nominal: ModalParameters,
    frequency_hz: float,
    *,
    period_s: float = 0.004,
    delay_s: float = 0.032,
    w1_range=(-1.5, 1.5),
    w2_range=(-0.06, 0.06),
    n_grid: int = 31,
    max_harmonic_gain: float = 1.1,
    max_radius: float = 0.995,
) -> tuple[np.ndarray, float, float]:
    """[w1, w2] tuned to one disturbance frequency instead of by LQR (the thesis' structure).

    Over a ``n_grid`` x ``n_grid`` grid: the gains with the smallest nominal
    :func:`state_feedback_sensitivity` at ``frequency_hz`` among those whose loop is stable
    for every plant in ``plants`` with a decay margin (spectral radius of
    :func:`implemented_loop_matrix` < ``max_radius``) and that amplify the 2nd and 3rd
    harmonics by at most ``max_harmonic_gain``. With 32 ms of delay the best gains at 8 Hz are *negative* (the delay turns the phase by ~100°).

    Parameters
    ----------
    plants : sequence of sequence of ModalParameters
        True plants (sums of modes) the loop must be stable for.
    nominal : ModalParameters
        The mode the sensitivity is computed for.
    frequency_hz : float
        The disturbance frequency [Hz].
    period_s, delay_s : float
        Command period and transport delay [s].
    w1_range, w2_range : tuple of float
        Grid ranges of the gains.
    n_grid : int
        Grid points per gain.
    max_harmonic_gain : float
        Largest |S| allowed at the 2nd and 3rd harmonics.
    max_radius : float
        Largest spectral radius allowed (decay margin).

    Returns
    -------
    gains : numpy.ndarray
        (2,) ``[w1, w2]`` (zeros when no grid point beats the open loop).
    sensitivity : float
        |S| at ``frequency_hz``.
    radius : float
        Worst spectral radius over ``plants``.
    """
    d = round(delay_s / period_s)
    best = (np.zeros(2), 1.0, max(spectral_radius(implemented_loop_matrix(p, (0.0, 0.0), period_s, d)) for p in plants))  # fmt: skip
    f = frequency_hz * np.array([1.0, 2.0, 3.0])
    for w1 in np.linspace(*w1_range, n_grid):
        for w2 in np.linspace(*w2_range, n_grid):
            sens = state_feedback_sensitivity(nominal, (w1, w2), f, period_s, delay_s)
            if sens[0] >= best[1] or np.max(sens[1:]) > max_harmonic_gain:
                continue
            rho = 0.0
            for p in plants:
                rho = max(rho, spectral_radius(implemented_loop_matrix(p, (w1, w2), period_s, d)))
                if rho >= max_radius:
                    break
            if rho < max_radius:
                best = (np.array([w1, w2]), float(sens[0]), rho)
    return best


def delay_aware_gains(
    mode: ModalParameters, r: float, period_s: float, delay_s: float
) -> np.ndarray:
    """Delay-aware LQR gains (2 + d,) with thesis Q and ``R = r`` (see ``design_delay_aware_lqr``).

    Parameters
    ----------
    mode : ModalParameters
        The (model) mode.
    r : float
        Control weight R.
    period_s : float
        Command period [s].
    delay_s : float
        Transport delay [s] (whole periods).

    Returns
    -------
    numpy.ndarray
        (2 + d,) gains on ``[x, v, u_1 .. u_d]``.
    """
    return design_delay_aware_lqr(mode, period_s, delay_s, r=[[r]]).gains
