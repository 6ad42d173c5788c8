"""Regenerative milling on the virtual robot: the chip thickness remembers the previous tooth.

At a fixed pose (a short cut, so the modes do not change), each flute ``j`` at the immersion
angle ``phi_j`` (the convention of :mod:`robovib.milling.forces`) removes the chip::

    h_j(t) = f_z sin(phi_j) + (x(t) - x(t - tau)) sin(phi_j) + (y(t) - y(t - tau)) cos(phi_j)

``tau = 60 / (N n)`` (tooth period), ``x`` feed and ``y`` normal tool-tip displacement. The
edge forces are ``F_t = a (K_tc h + K_te)``, ``F_r = a (K_rc h + K_re)`` where the flute is in
the engagement and ``h > 0`` (it leaves the cut otherwise: the nonlinearity that bounds chatter),
projected as in :func:`robovib.milling.forces.milling_forces`. The helix is ignored (as in
:mod:`robovib.milling.sdm`). The modes of each direction advance exactly over each step
(:func:`robovib.sim.dynamics.zoh_transition`) with the force held; the step is ``tau /
steps_per_tooth`` so the delayed displacement is a stored sample.

Chatter indicator: the motion is sampled once per tooth period (a Poincaré section). A stable
cut settles on the tooth-periodic forced vibration, so successive samples stop changing and their
differences decay like ``|mu|^k`` (``mu`` the critical Floquet multiplier); chatter makes them grow
until the tool leaves the cut, where they stay. ``growth`` is the RMS of those differences over the
last 15 % of the periods divided by that over 5-20 %; ``chatter = growth > 0.5`` (a stable cut's
differences fall by orders of magnitude; a chattering one grows or stays saturated).
``decay_rate_per_period`` is the slope of ``log`` of the differences over the second half: in the
linear regime it is ``log |mu|`` of the critical multiplier (compared with the semi-discretization
in the tests). The spectral fraction of vibration energy away from the tooth-passing harmonics
(last half of the record) and the strongest off-harmonic frequency are reported too.

The comparison with linear stability theory holds while the tool stays in the cut in a stable
cut: with large edge forces (``K_te``) or a compliant robot the forced vibration alone can exceed
the feed per tooth, the flute then loses contact and the cut is nonlinear even below the limit.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..milling.forces import CuttingCoefficients, CuttingConditions, MillingTool, engagement_angles
from ..modal.parameters import ModalParameters
from .dynamics import zoh_transition

__all__ = ["RegenerativeCut", "simulate_regenerative_cut", "simulated_stability_limit"]


@dataclass(frozen=True)
class RegenerativeCut:
    """A simulated cut at one pose for a batch of axial depths.

        ``displacement_m`` (b, n, 2) feed/normal tool-tip displacement, ``force_n`` (b, n, 2),
        ``growth`` (b,) Poincaré-difference growth ratio, ``decay_rate_per_period`` (b,) their
    log-slope, ``chatter`` (b,) bool,
        ``off_harmonic_fraction`` (b,) energy fraction away from tooth-passing harmonics,
        ``chatter_hz`` (b,) strongest off-harmonic frequency.

    Attributes
    ----------
    time_s
        (n,) times [s].
    depth_m
        (b,) axial depths [m].
    displacement_m, force_n
        (b, n, 2) feed/normal tool-tip displacement [m] and force [N].
    growth
        (b,) Poincaré-difference growth ratio.
    decay_rate_per_period
        (b,) its log-slope per tooth period.
    chatter
        (b,) chatter found.
    off_harmonic_fraction
        (b,) energy fraction away from the tooth-passing harmonics.
    chatter_hz
        (b,) strongest off-harmonic frequency [Hz].
    tooth_passing_hz
        Tooth-passing frequency [Hz].
    """

    time_s: np.ndarray
    depth_m: np.ndarray
    displacement_m: np.ndarray
    force_n: np.ndarray
    growth: np.ndarray
    decay_rate_per_period: np.ndarray
    chatter: np.ndarray
    off_harmonic_fraction: np.ndarray
    chatter_hz: np.ndarray
    tooth_passing_hz: float


def _mode_arrays(modes: Sequence[ModalParameters]):
    return (
        np.array([m.natural_frequency_hz for m in modes]),
        np.array([m.stiffness_n_per_m for m in modes]),
        np.array([m.damping_ratio for m in modes]),
    )


def simulate_regenerative_cut(
    modes_x: Sequence[ModalParameters],
    modes_y: Sequence[ModalParameters],
    tool: MillingTool,
    conditions: CuttingConditions,
    coefficients: CuttingCoefficients,
    depth_m=None,
    *,
    n_tooth_periods: int = 300,
    steps_per_tooth: int = 120,
) -> RegenerativeCut:
    """Simulate regenerative milling at one pose for one or several axial depths (batched).

    Parameters
    ----------
    modes_x, modes_y : sequence of ModalParameters
        Tool-tip modes in the feed (x) and normal (y) directions.
    tool, conditions, coefficients
        Tool (flutes, diameter; helix ignored), speed / feed / radial depth / up-down milling,
        cutting and edge coefficients.
    depth_m : array_like (b,), optional
        Axial depths [m] to simulate side by side (default: the conditions' depth).
    n_tooth_periods : int
        Length of the cut in tooth periods.
    steps_per_tooth : int
        Time steps per tooth period (the delay is exactly this many steps).

    Returns
    -------
    RegenerativeCut
    """
    modes = list(modes_x) + list(modes_y)
    if not modes:
        raise ValueError("at least one mode (x or y) is needed")
    depth = np.atleast_1d(
        np.asarray(conditions.axial_depth_m if depth_m is None else depth_m, float)
    )
    if depth.ndim != 1 or not (np.all(np.isfinite(depth)) and np.all(depth > 0)):
        raise ValueError("depth_m must be positive axial depths [m]")
    m_steps, n_per = int(steps_per_tooth), int(n_tooth_periods)
    if m_steps < 8 or n_per < 20:
        raise ValueError("need steps_per_tooth >= 8 and n_tooth_periods >= 20")
    n_fl = int(tool.n_flutes)
    tau = 60.0 / (n_fl * conditions.spindle_rpm)
    dt = tau / m_steps
    fn, k, z = _mode_arrays(modes)
    if np.any(fn * dt > 0.1):
        raise ValueError(
            f"steps_per_tooth={m_steps} gives {1 / (fn.max() * dt):.1f} steps per period of the "
            f"{fn.max():.4g} Hz mode; use more (>= 10 per period)"
        )
    p00, p01, p10, p11, g0, g1 = zoh_transition(fn, k, z, dt)
    nx = len(modes_x)
    selx = np.zeros(len(modes))
    selx[:nx] = 1.0
    sely = 1.0 - selx
    phi_st, phi_ex = engagement_angles(tool, conditions)
    pitch = 2 * math.pi / n_fl
    # Flute angles repeat every tooth period (shifted by one flute): tabulate one period.
    ang = (np.arange(m_steps)[:, None] / m_steps * pitch + pitch * np.arange(n_fl)[None, :]) % (
        2 * math.pi
    )
    s_tab, c_tab = np.sin(ang), np.cos(ang)
    g_tab = (ang >= phi_st) & (ang <= phi_ex)
    c = coefficients
    fz = conditions.feed_per_tooth_m
    b = depth.size
    xi = np.zeros((b, len(modes)))
    vi = np.zeros((b, len(modes)))
    hist_x = np.zeros((m_steps, b))
    hist_y = np.zeros((m_steps, b))
    n_steps = m_steps * n_per
    disp = np.empty((b, n_steps, 2))
    force = np.empty((b, n_steps, 2))
    x = np.zeros(b)
    y = np.zeros(b)
    a_col = depth[:, None]
    for i in range(n_steps):
        kk = i % m_steps
        s, co, g = s_tab[kk], c_tab[kk], g_tab[kk]
        dx = x - hist_x[kk]
        dy = y - hist_y[kk]
        hist_x[kk] = x
        hist_y[kk] = y
        h = fz * s + dx[:, None] * s + dy[:, None] * co
        on = g & (h > 0)
        h = np.where(on, h, 0.0)
        ft = a_col * (c.ktc * h + c.kte * on)
        fr = a_col * (c.krc * h + c.kre * on)
        fx = np.sum(-ft * co - fr * s, axis=1)
        fy = np.sum(ft * s - fr * co, axis=1)
        f = fx[:, None] * selx + fy[:, None] * sely
        xi, vi = p00 * xi + p01 * vi + g0 * f, p10 * xi + p11 * vi + g1 * f
        x = xi @ selx
        y = xi @ sely
        disp[:, i, 0], disp[:, i, 1] = x, y
        force[:, i, 0], force[:, i, 1] = fx, fy
    t = (np.arange(n_steps) + 1) * dt
    growth, rate, frac, fch = _indicators(disp, m_steps, dt, 1.0 / tau)
    return RegenerativeCut(t, depth, disp, force, growth, rate, growth > 0.5, frac, fch, 1.0 / tau)


def _indicators(disp: np.ndarray, m_steps: int, dt: float, tpf: float):
    n_per = disp.shape[1] // m_steps
    poincare = disp[:, m_steps - 1 :: m_steps, :][:, :n_per]
    diff = np.linalg.norm(np.diff(poincare, axis=1), axis=-1)  # (b, n_per - 1)
    n = diff.shape[1]
    early = np.sqrt(
        np.mean(diff[:, int(0.05 * n) : max(int(0.2 * n), int(0.05 * n) + 1)] ** 2, axis=1)
    )
    late = np.sqrt(np.mean(diff[:, int(0.85 * n) :] ** 2, axis=1))
    growth = late / np.maximum(early, 1e-300)
    k = np.arange(n // 2, n)
    logd = np.log(np.maximum(diff[:, n // 2 :], 1e-300))
    rate = np.polyfit(k, logd.T, 1)[0]
    half = disp[:, disp.shape[1] // 2 :, :]
    half = half - half.mean(axis=1, keepdims=True)
    spec = np.sum(
        np.abs(np.fft.rfft(half * np.hanning(half.shape[1])[None, :, None], axis=1)) ** 2, axis=2
    )
    f = np.fft.rfftfreq(half.shape[1], dt)
    df = f[1]
    harmonic = np.abs(f / tpf - np.round(f / tpf)) * tpf <= 3 * df
    off = np.where(harmonic[None, :], 0.0, spec)
    frac = off.sum(axis=1) / np.maximum(spec.sum(axis=1), 1e-300)
    fch = f[np.argmax(off, axis=1)]
    return growth, rate, frac, fch


def simulated_stability_limit(
    modes_x: Sequence[ModalParameters],
    modes_y: Sequence[ModalParameters],
    tool: MillingTool,
    conditions: CuttingConditions,
    coefficients: CuttingCoefficients,
    depth_bracket_m: tuple[float, float],
    *,
    n_bisections: int = 6,
    n_parallel: int = 3,
    **simulation,
) -> tuple[float, float]:
    """Bracket [m] of the simulated stability limit by batched bisection on the axial depth.

    Each round simulates ``n_parallel`` depths spread inside the current bracket at once and
    keeps the interval between the deepest stable and the shallowest chattering one.

    Parameters
    ----------
    modes_x, modes_y : sequence of ModalParameters
        Tool-tip modes along feed and normal.
    tool : MillingTool
        The cutter.
    conditions : CuttingConditions
        Spindle speed, feed and radial depth.
    coefficients : CuttingCoefficients
        Cutting-force coefficients.
    depth_bracket_m : (low, high)
        Depths [m] expected stable and chattering (checked: raises if not).
    n_bisections : int
        Rounds of refinement.
    n_parallel : int
        Depths per round.
    **simulation
        Passed to :func:`simulate_regenerative_cut`.

    Returns
    -------
    (low, high) : depths [m], the limit lies between them.
    """
    lo, hi = (float(v) for v in depth_bracket_m)
    if not 0 < lo < hi:
        raise ValueError(f"depth_bracket_m must be 0 < low < high [m], got {depth_bracket_m}")
    ends = simulate_regenerative_cut(
        modes_x, modes_y, tool, conditions, coefficients, [lo, hi], **simulation
    ).chatter
    if ends[0] or not ends[1]:
        raise ValueError(
            f"the bracket must be stable at {lo:g} m and chatter at {hi:g} m "
            f"(simulated: {'chatter' if ends[0] else 'stable'}, "
            f"{'chatter' if ends[1] else 'stable'})"
        )
    for _ in range(int(n_bisections)):
        trial = np.linspace(lo, hi, int(n_parallel) + 2)[1:-1]
        chat = simulate_regenerative_cut(
            modes_x, modes_y, tool, conditions, coefficients, trial, **simulation
        ).chatter
        stable = trial[~chat]
        unstable = trial[chat]
        if stable.size:
            lo = max(lo, float(stable.max()))
        if unstable.size:
            hi = min(hi, float(unstable.min()))
    return lo, hi
