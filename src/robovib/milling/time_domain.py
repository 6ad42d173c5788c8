"""Regenerative milling in the time domain: the chip thickness remembers the previous tooth.

At a fixed pose (a short cut, so the modes do not change), each flute ``j`` at the immersion
angle ``phi_j`` (the convention of :mod:`robovib.milling.forces`) removes the chip::

    h_j(t) = f_z sin(phi_j) + (x(t) - x(t - tau)) sin(phi_j) + (y(t) - y(t - tau)) cos(phi_j)

``tau = 60 / (N n)`` (tooth period), ``x`` feed and ``y`` normal tool-tip displacement. The
edge forces are ``F_t = a (K_tc h + K_te)``, ``F_r = a (K_rc h + K_re)`` where the flute is in
the engagement and ``h > 0`` (it leaves the cut otherwise: the nonlinearity that bounds chatter),
projected as in :func:`robovib.milling.forces.milling_forces`. The helix is ignored (as in
:mod:`robovib.milling.sdm`). The modes of each direction advance exactly over each step
(:func:`robovib.modal.stepping.zoh_transition`) with the force held; the step is ``tau /
steps_per_tooth`` so the delayed displacement is a stored sample.

Chatter indicator: the motion is sampled once per tooth period (a Poincaré section). A stable
cut settles on the tooth-periodic forced vibration, so successive samples stop changing and their
differences decay like ``|mu|^k`` (``mu`` the critical Floquet multiplier); chatter makes them grow
until the tool leaves the cut, where they stay. ``growth`` is the RMS of those differences over the
last 15 % of the periods divided by that over 5-20 %; ``decay_rate_per_period`` is the slope of
``log`` of the differences over the second half: in the linear regime it is ``log |mu|`` of the
critical multiplier (compared with the semi-discretization in the tests).
``chatter_amplitude_m`` is the RMS of the differences over the last 15 %: the vibration that is not
tooth-periodic, i.e. the modulation of the chip thickness. A cut chatters when that modulation is
still growing (``decay_rate_per_period > 1e-3``, the linear regime above the limit) or when it has
settled at a size that marks the surface: ``growth > 0.5`` *and* ``chatter_amplitude_m`` more than
``chatter_fraction_of_feed`` (10 %) of the feed per tooth. The second condition keeps a stable cut
with a small self-sustained sub-harmonic (a flute grazing in and out of the cut at the entry angle
with the edge force switching on and off: ~1 µm, 2 % of the feed, seen at 0.5x the linear limit)
from being called chatter; saturated chatter is 50-150 % of the feed.

Entry: a cut that starts at full depth at ``t = 0`` is hit by a step force whose transient can
throw the tool out of the cut and into the large-amplitude chatter that coexists with the stable
cut slightly below the linear limit (the fly-over "unsafe zone"). A tool entering a part along the
feed engages gradually: ``entry_tooth_periods`` ramps the engagement (the force scale) from 0 to
full over that many tooth periods (``sqrt(a_e (D - a_e)) / f_z`` for a straight entry across the
part's edge, e.g. 186 for a 6 mm step of a 25.4 mm tool at 0.058 mm/tooth); the indicators are
computed over the ``n_tooth_periods`` that follow. The spectral fraction of vibration energy away
from the tooth-passing harmonics (last half of the record) and the strongest off-harmonic
frequency are reported too.

The comparison with linear stability theory holds while the tool stays in the cut in a stable
cut: with large edge forces (``K_te``) or a compliant robot the forced vibration alone can exceed
the feed per tooth, the flute then loses contact and the cut is nonlinear even below the limit.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..modal.parameters import ModalParameters
from ..modal.stepping import zoh_transition
from .forces import CuttingCoefficients, CuttingConditions, MillingTool, engagement_angles

__all__ = [
    "RegenerativeCut",
    "simulate_regenerative_cut",
    "simulated_stability_limit",
    "time_domain_limit_ratio",
    "time_domain_limit_ratios",
]


@dataclass(frozen=True)
class RegenerativeCut:
    """A simulated cut at one pose for a batch of axial depths.

        ``displacement_m`` (b, n, 2) feed/normal tool-tip displacement, ``force_n`` (b, n, 2),
        ``growth`` (b,) Poincaré-difference growth ratio, ``decay_rate_per_period`` (b,) their
    log-slope, ``chatter_amplitude_m`` (b,) their late RMS [m], ``chatter`` (b,) bool,
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
    chatter_amplitude_m
        (b,) RMS of the Poincaré differences over the last 15 % [m].
    entry_tooth_periods
        Tooth periods of the entry ramp before the record.
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
    chatter_amplitude_m: np.ndarray | None = None
    entry_tooth_periods: int = 0


def _mode_arrays(modes: Sequence[ModalParameters]):
    return (
        np.array([m.natural_frequency_hz for m in modes]),
        np.array([m.stiffness_n_per_m for m in modes]),
        np.array([m.damping_ratio for m in modes]),
    )


def _checked_simulation(
    steps_per_tooth, n_tooth_periods, entry_tooth_periods, chatter_fraction_of_feed
) -> tuple[int, int, int]:
    m_steps, n_per, n_entry = int(steps_per_tooth), int(n_tooth_periods), int(entry_tooth_periods)
    if m_steps < 8 or n_per < 20:
        raise ValueError("need steps_per_tooth >= 8 and n_tooth_periods >= 20")
    if n_entry < 0:
        raise ValueError(f"entry_tooth_periods must be >= 0, got {entry_tooth_periods}")
    if not (np.isfinite(chatter_fraction_of_feed) and chatter_fraction_of_feed > 0):
        raise ValueError(f"chatter_fraction_of_feed must be > 0, got {chatter_fraction_of_feed!r}")
    return m_steps, n_per, n_entry


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
    entry_tooth_periods: int = 0,
    chatter_fraction_of_feed: float = 0.1,
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
        Length of the cut in tooth periods after the entry (the indicators' record).
    steps_per_tooth : int
        Time steps per tooth period (the delay is exactly this many steps).
    entry_tooth_periods : int
        Tooth periods over which the engagement ramps from 0 to full before the record (module
        docs; 0: full depth from the first step).
    chatter_fraction_of_feed : float
        Settled non-tooth-periodic vibration (RMS of the Poincaré differences) above which a
        non-decaying cut is called chatter, as a fraction of the feed per tooth.

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
    m_steps, n_per, n_entry = _checked_simulation(
        steps_per_tooth, n_tooth_periods, entry_tooth_periods, chatter_fraction_of_feed
    )
    tau = 60.0 / (int(tool.n_flutes) * conditions.spindle_rpm)
    dt = tau / m_steps
    fn, k, z = _mode_arrays(modes)
    b = depth.size
    in_feed = np.arange(len(modes)) < len(modes_x)
    disp, force = _step_rows(
        np.broadcast_to(fn, (b, fn.size)), np.broadcast_to(k, (b, fn.size)),
        np.broadcast_to(z, (b, fn.size)), np.broadcast_to(in_feed, (b, fn.size)),
        np.full(b, float(conditions.spindle_rpm)), depth, tool, conditions, coefficients,
        steps_per_tooth=m_steps, n_tooth_periods=n_per, entry_tooth_periods=n_entry,
        record="all",
    )  # fmt: skip
    n_ramp = m_steps * n_entry
    n_steps = disp.shape[1]
    fz = conditions.feed_per_tooth_m
    t = (np.arange(n_steps) + 1) * dt
    growth, rate, frac, fch, amp = _indicators(disp[:, n_ramp:], m_steps, dt, 1.0 / tau)
    chatter = _is_chatter(growth, rate, amp, chatter_fraction_of_feed, fz)
    return RegenerativeCut(
        t, depth, disp, force, growth, rate, chatter, frac, fch, 1.0 / tau, amp, n_entry
    )


def _poincare_indicators(poincare: np.ndarray):
    """Growth, decay rate and late amplitude from (b, n_periods, 2) once-per-period samples."""
    step = np.diff(poincare, axis=1)
    # |step| as numpy.linalg.norm computes it (same bits), without its generic overhead.
    diff = np.sqrt(step[..., 0] * step[..., 0] + step[..., 1] * step[..., 1])  # (b, n_per - 1)
    n = diff.shape[1]
    early = np.sqrt(
        np.mean(diff[:, int(0.05 * n) : max(int(0.2 * n), int(0.05 * n) + 1)] ** 2, axis=1)
    )
    late = np.sqrt(np.mean(diff[:, int(0.85 * n) :] ** 2, axis=1))
    growth = late / np.maximum(early, 1e-300)
    k = np.arange(n // 2, n)
    logd = np.log(np.maximum(diff[:, n // 2 :], 1e-300))
    rate = np.polyfit(k, logd.T, 1)[0]
    return growth, rate, late


def _indicators(disp: np.ndarray, m_steps: int, dt: float, tpf: float):
    n_per = disp.shape[1] // m_steps
    poincare = disp[:, m_steps - 1 :: m_steps, :][:, :n_per]
    growth, rate, amplitude = _poincare_indicators(poincare)
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
    return growth, rate, frac, fch, amplitude


def _is_chatter(growth, rate, amplitude, chatter_fraction_of_feed: float, feed_per_tooth_m: float):
    return (rate > 1e-3) | (
        (growth > 0.5) & (amplitude > chatter_fraction_of_feed * feed_per_tooth_m)
    )


def _row_setup(
    fn_hz, stiffness_n_per_m, damping_ratio, in_feed, spindle_rpm, tool, conditions, m_steps: int
):
    """Per-row step coefficients (ZOH transition of every mode over the row's own step), the
    feed/normal selectors and the flute tables of one tooth period, for :func:`_step_rows`."""
    fn = np.asarray(fn_hz, float)
    present = fn > 0
    fn = np.where(present, fn, 1.0)
    k = np.where(present, np.asarray(stiffness_n_per_m, float), 1.0)
    z = np.where(present, np.asarray(damping_ratio, float), 0.5)
    n_fl = int(tool.n_flutes)
    dt = (60.0 / (n_fl * np.asarray(spindle_rpm, float)) / m_steps)[:, None]
    if np.any(fn * dt > 0.1):
        raise ValueError(
            f"steps_per_tooth={m_steps} gives {1 / np.max(fn * dt):.1f} steps per period of the "
            f"{fn[np.unravel_index(np.argmax(fn * dt), fn.shape)]:.4g} Hz mode; "
            "use more (>= 10 per period)"
        )
    p00, p01, p10, p11, g0, g1 = zoh_transition(fn, k, z, dt)
    g0, g1 = g0 * present, g1 * present
    selx = (np.asarray(in_feed, bool) & present).astype(float)
    sely = (~np.asarray(in_feed, bool) & present).astype(float)
    phi_st, phi_ex = engagement_angles(tool, conditions)
    pitch = 2 * math.pi / n_fl
    # Flute angles repeat every tooth period (shifted by one flute): tabulate one period.
    ang = (np.arange(m_steps)[:, None] / m_steps * pitch + pitch * np.arange(n_fl)[None, :]) % (
        2 * math.pi
    )
    s_tab, c_tab = np.sin(ang), np.cos(ang)
    g_tab = (ang >= phi_st) & (ang <= phi_ex)
    return (p00, p01, p10, p11, g0, g1), selx, sely, (s_tab, c_tab, g_tab)


def _step_rows(
    fn_hz: np.ndarray,
    stiffness_n_per_m: np.ndarray,
    damping_ratio: np.ndarray,
    in_feed: np.ndarray,
    spindle_rpm: np.ndarray,
    depth_m: np.ndarray,
    tool: MillingTool,
    conditions: CuttingConditions,
    coefficients: CuttingCoefficients,
    *,
    steps_per_tooth: int,
    n_tooth_periods: int,
    entry_tooth_periods: int,
    record: str,
):
    """Step b independent cuts, each with its own modes, speed and depth (module docs).

    The (b, n_modes) mode arrays (``fn_hz <= 0`` marks a missing mode: rows may hold different
    numbers of modes), ``in_feed`` (b, n_modes) True for the feed-direction modes, a speed per
    row (the tooth period, hence the step, differs by row; the number of steps per tooth is the
    same, so one delay buffer serves all). ``record="all"``: the (b, n, 2) displacement and
    force of every step; ``"poincare"``: only the (b, n_tooth_periods, 2) displacement once per
    tooth period after the entry, so a batch of thousands of cuts fits in memory.
    """
    m_steps, n_per, n_entry = int(steps_per_tooth), int(n_tooth_periods), int(entry_tooth_periods)
    (p00, p01, p10, p11, g0, g1), selx, sely, (s_tab, c_tab, g_tab) = _row_setup(
        fn_hz, stiffness_n_per_m, damping_ratio, in_feed, spindle_rpm, tool, conditions, m_steps
    )
    depth = np.asarray(depth_m, float)
    c = coefficients
    fz = conditions.feed_per_tooth_m
    b, nm = p00.shape
    xi = np.zeros((b, nm))
    vi = np.zeros((b, nm))
    hist_x = np.zeros((m_steps, b))
    hist_y = np.zeros((m_steps, b))
    n_ramp = m_steps * n_entry
    n_steps = m_steps * (n_per + n_entry)
    full = record == "all"
    if full:
        disp = np.empty((b, n_steps, 2))
        force = np.empty((b, n_steps, 2))
    else:
        poincare = np.empty((b, n_per, 2))
    x = np.zeros(b)
    y = np.zeros(b)
    a_col = depth[:, None]
    for i in range(n_steps):
        kk = i % m_steps
        if i < n_ramp:
            a_col = depth[:, None] * ((i + 1) / n_ramp)
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
        x = np.sum(xi * selx, axis=1)
        y = np.sum(xi * sely, axis=1)
        if full:
            disp[:, i, 0], disp[:, i, 1] = x, y
            force[:, i, 0], force[:, i, 1] = fx, fy
        elif i >= n_ramp and kk == m_steps - 1:
            j = (i - n_ramp) // m_steps
            poincare[:, j, 0], poincare[:, j, 1] = x, y
    return (disp, force) if full else poincare


def _poincare_loop(
    coef, n_feed, depth, s_tab, c_tab, engaged, n_engaged, ktc, kte, krc, kre, fz, n_per,
    n_entry, chunk, poincare,
):  # fmt: skip
    """The stepping loop of :func:`_step_rows` (``record="poincare"``), compiled by numba.

    ``coef`` (n_slots, 6, b) holds per mode slot and row the step transition ``p00, p01, p10,
    p11, g0, g1``; the first ``n_feed`` slots are feed modes, the others normal ones (a row with
    fewer modes has zero slots). The loops over the rows are innermost and touch few arrays,
    so that they vectorise. The operations are those of :func:`_step_rows` in the same order
    (the displacement sums the feed modes in their order; a zero slot adds a zero), so the
    once-per-period samples are bit for bit the same (tested), less the work whose result is
    never used or is an exact zero: at a step where no flute is in the engagement the force is
    zero (its term is left out) and the delay buffer is not read, the displacement is summed
    only where the next step's chip or the record needs it, and runs of such steps advance
    eight or four at a time with each row's state held in registers (the same operations). Rows are
    stepped ``chunk`` at a time (cache). Which arrays a loop reads and writes was chosen by
    measurement: arrays written in a loop are not read at other rows of the same array in it,
    or the loop does not vectorise. ``engaged[kk, :n_engaged[kk]]``: the flutes inside the
    engagement at step ``kk`` of the tooth period; ``poincare`` (b, n_per, 2) is filled.
    """
    nm = coef.shape[0]
    b = coef.shape[2]
    m_steps = s_tab.shape[0]
    n_ramp = m_steps * n_entry
    n_steps = m_steps * (n_per + n_entry)
    # Steps from kk on with no flute in the cut whose displacement nothing reads (the next
    # step cuts no chip and the record is at the last step of the period).
    free_run = np.zeros(m_steps + 1, np.int64)
    for kk in range(m_steps - 2, -1, -1):
        if n_engaged[kk] == 0 and n_engaged[kk + 1] == 0:
            free_run[kk] = free_run[kk + 1] + 1
    for r0 in range(0, b, chunk):
        r1 = min(b, r0 + chunk)
        n = r1 - r0
        cc = np.ascontiguousarray(coef[:, :, r0:r1])
        xs = np.zeros((nm, n))  # displacement and velocity of every mode slot
        vs = np.zeros((nm, n))
        hist = np.zeros((m_steps, 2, n))
        xy = np.zeros((2, n))
        dxy = np.empty((2, n))
        fxy = np.empty((2, n))
        a = np.empty(n)
        for r in range(n):
            a[r] = depth[r0 + r]
        i = 0
        while i < n_steps:
            kk = i % m_steps
            if free_run[kk] >= 8:
                # Eight steps of free vibration at once, each row's state kept in registers.
                for m in range(nm):
                    for r in range(n):
                        c0 = cc[m, 0, r]
                        c1 = cc[m, 1, r]
                        c2 = cc[m, 2, r]
                        c3 = cc[m, 3, r]
                        xo = xs[m, r]
                        vo = vs[m, r]
                        for _ in range(8):
                            xn = c0 * xo + c1 * vo
                            vo = c2 * xo + c3 * vo
                            xo = xn
                        xs[m, r] = xo
                        vs[m, r] = vo
                i += 8
                continue
            if free_run[kk] >= 4:
                # Four steps of free vibration at once, each row's state kept in registers.
                for m in range(nm):
                    for r in range(n):
                        c0 = cc[m, 0, r]
                        c1 = cc[m, 1, r]
                        c2 = cc[m, 2, r]
                        c3 = cc[m, 3, r]
                        xo = xs[m, r]
                        vo = vs[m, r]
                        x1 = c0 * xo + c1 * vo
                        v1 = c2 * xo + c3 * vo
                        x2 = c0 * x1 + c1 * v1
                        v2 = c2 * x1 + c3 * v1
                        x3 = c0 * x2 + c1 * v2
                        v3 = c2 * x2 + c3 * v2
                        xs[m, r] = c0 * x3 + c1 * v3
                        vs[m, r] = c2 * x3 + c3 * v3
                i += 4
                continue
            cutting = n_engaged[kk] > 0
            # x, y at the end of this step are needed by the next step's chip or the record.
            need = n_engaged[(kk + 1) % m_steps] > 0 or kk == m_steps - 1
            if cutting and i < n_ramp + m_steps:  # the entry ramp, and full depth after it
                scale = (i + 1) / n_ramp if i < n_ramp else 1.0
                for r in range(n):
                    a[r] = depth[r0 + r] * scale
            if cutting:
                for r in range(n):
                    x = xy[0, r]
                    y = xy[1, r]
                    dxy[0, r] = x - hist[kk, 0, r]
                    dxy[1, r] = y - hist[kk, 1, r]
                    hist[kk, 0, r] = x
                    hist[kk, 1, r] = y
                    fxy[0, r] = 0.0
                    fxy[1, r] = 0.0
                for jj in range(n_engaged[kk]):
                    j = engaged[kk, jj]
                    s = s_tab[kk, j]
                    co = c_tab[kk, j]
                    base = fz * s
                    for r in range(n):
                        h = base + dxy[0, r] * s + dxy[1, r] * co
                        cut = h > 0.0
                        hc = h if cut else 0.0
                        on = 1.0 if cut else 0.0
                        ft = a[r] * (ktc * hc + kte * on)
                        fr = a[r] * (krc * hc + kre * on)
                        fxy[0, r] += -ft * co - fr * s
                        fxy[1, r] += ft * s - fr * co
            if need:
                for r in range(n):
                    xy[0, r] = 0.0
                    xy[1, r] = 0.0
            for m in range(nm):
                if cutting and need and m < n_feed:
                    for r in range(n):
                        f = fxy[0, r]
                        xo = xs[m, r]
                        vo = vs[m, r]
                        xn = cc[m, 0, r] * xo + cc[m, 1, r] * vo + cc[m, 4, r] * f
                        xs[m, r] = xn
                        vs[m, r] = cc[m, 2, r] * xo + cc[m, 3, r] * vo + cc[m, 5, r] * f
                        xy[0, r] += xn
                elif cutting and need:
                    for r in range(n):
                        f = fxy[1, r]
                        xo = xs[m, r]
                        vo = vs[m, r]
                        xn = cc[m, 0, r] * xo + cc[m, 1, r] * vo + cc[m, 4, r] * f
                        xs[m, r] = xn
                        vs[m, r] = cc[m, 2, r] * xo + cc[m, 3, r] * vo + cc[m, 5, r] * f
                        xy[1, r] += xn
                elif cutting:
                    d = 0 if m < n_feed else 1
                    for r in range(n):
                        f = fxy[d, r]
                        xo = xs[m, r]
                        vo = vs[m, r]
                        xs[m, r] = cc[m, 0, r] * xo + cc[m, 1, r] * vo + cc[m, 4, r] * f
                        vs[m, r] = cc[m, 2, r] * xo + cc[m, 3, r] * vo + cc[m, 5, r] * f
                elif need and m < n_feed:
                    for r in range(n):
                        xo = xs[m, r]
                        vo = vs[m, r]
                        xn = cc[m, 0, r] * xo + cc[m, 1, r] * vo
                        xs[m, r] = xn
                        vs[m, r] = cc[m, 2, r] * xo + cc[m, 3, r] * vo
                        xy[0, r] += xn
                elif need:
                    for r in range(n):
                        xo = xs[m, r]
                        vo = vs[m, r]
                        xn = cc[m, 0, r] * xo + cc[m, 1, r] * vo
                        xs[m, r] = xn
                        vs[m, r] = cc[m, 2, r] * xo + cc[m, 3, r] * vo
                        xy[1, r] += xn
                else:
                    for r in range(n):
                        xo = xs[m, r]
                        vo = vs[m, r]
                        xs[m, r] = cc[m, 0, r] * xo + cc[m, 1, r] * vo
                        vs[m, r] = cc[m, 2, r] * xo + cc[m, 3, r] * vo
            if i >= n_ramp and kk == m_steps - 1:
                j = (i - n_ramp) // m_steps
                for r in range(n):
                    poincare[r0 + r, j, 0] = xy[0, r]
                    poincare[r0 + r, j, 1] = xy[1, r]
            i += 1


def _slots(coef, selx: np.ndarray, sely: np.ndarray) -> tuple[np.ndarray, int]:
    """Step coefficients (n_slots, 6, b) for :func:`_poincare_loop`: each row's feed modes in
    their order in the first slots, then its normal modes; missing modes are zero slots."""
    b = selx.shape[0]
    feed, normal = selx > 0, sely > 0
    n_feed, n_normal = int(feed.sum(axis=1).max()), int(normal.sum(axis=1).max())
    packed = np.zeros((n_feed + n_normal, 6, b))
    coef = np.stack([np.asarray(c, float) for c in coef], axis=1)  # (b, 6, n_modes)
    for mask, first in ((feed, 0), (normal, n_feed)):
        rank = np.cumsum(mask, axis=1) - 1  # the mode's place among its direction's modes
        rows, modes = np.nonzero(mask)
        packed[first + rank[rows, modes], :, rows] = coef[rows, :, modes]
    return packed, n_feed


_COMPILED: dict = {}


def _compiled_loop():
    """:func:`_poincare_loop` compiled by numba, or ``None``: the numpy stepping then.

    ``None`` without numba and under ``NUMBA_DISABLE_JIT=1`` (the loop interpreted by Python
    takes about 0.5 s per cut: a chart would take hours). The machine code is cached on disk
    (next to this file, else in the user's cache folder); where neither is writable (a
    read-only install, no home folder) numba refuses ``cache=True`` and the loop is compiled
    in every process instead (about 8 s at first use).
    """
    if "loop" not in _COMPILED:
        try:
            import numba
        except ImportError:
            _COMPILED["loop"] = None
        else:
            if numba.config.DISABLE_JIT:
                _COMPILED["loop"] = None
            else:
                try:
                    _COMPILED["loop"] = numba.njit(cache=True, nogil=True)(_poincare_loop)
                except RuntimeError:  # "cannot cache function ...: no locator available"
                    _COMPILED["loop"] = numba.njit(nogil=True)(_poincare_loop)
    return _COMPILED["loop"]


def _poincare_rows(
    fn_hz, stiffness_n_per_m, damping_ratio, in_feed, spindle_rpm, depth_m, tool, conditions,
    coefficients, *, steps_per_tooth: int, n_tooth_periods: int, entry_tooth_periods: int,
    backend: str = "numba", chunk: int | None = None,
) -> np.ndarray:  # fmt: skip
    """The (b, n_tooth_periods, 2) once-per-period samples of :func:`_step_rows`, compiled.

    ``backend="numba"`` runs :func:`_poincare_loop` (bit for bit the samples of ``"numpy"``,
    :func:`_step_rows`, at about a hundredth of the time for a few rows); without numba it
    falls back to ``"numpy"``.
    """
    if backend not in ("numba", "numpy"):
        raise ValueError(f"backend must be 'numba' or 'numpy', got {backend!r}")
    loop = _compiled_loop() if backend == "numba" else None
    if loop is None:
        return _step_rows(
            fn_hz, stiffness_n_per_m, damping_ratio, in_feed, spindle_rpm, depth_m, tool,
            conditions, coefficients, steps_per_tooth=steps_per_tooth,
            n_tooth_periods=n_tooth_periods, entry_tooth_periods=entry_tooth_periods,
            record="poincare",
        )  # fmt: skip
    m_steps, n_per, n_entry = int(steps_per_tooth), int(n_tooth_periods), int(entry_tooth_periods)
    coef, selx, sely, (s_tab, c_tab, g_tab) = _row_setup(
        fn_hz, stiffness_n_per_m, damping_ratio, in_feed, spindle_rpm, tool, conditions, m_steps
    )
    depth = np.ascontiguousarray(np.asarray(depth_m, float))
    n_engaged = g_tab.sum(axis=1).astype(np.int64)
    # Each step's engaged flutes first, in their order (a stable sort of "not engaged"); the
    # loop reads only the first n_engaged of a row.
    engaged = np.argsort(~g_tab, axis=1, kind="stable").astype(np.int64)
    packed, n_feed = _slots(coef, selx, sely)
    if chunk is None:  # rows stepped together: their coefficients stay in the first cache level
        chunk = 128 if packed.shape[0] <= 2 else 64
    c = coefficients
    out = np.empty((depth.size, n_per, 2))
    if depth.size:
        loop(
            packed, n_feed, depth, np.ascontiguousarray(s_tab), np.ascontiguousarray(c_tab),
            engaged, n_engaged, float(c.ktc), float(c.kte), float(c.krc), float(c.kre),
            float(conditions.feed_per_tooth_m), n_per, n_entry, int(chunk), out,
        )  # fmt: skip
    return out


def _chatter_of_rows(
    fn_hz: np.ndarray,
    stiffness_n_per_m: np.ndarray,
    damping_ratio: np.ndarray,
    in_feed: np.ndarray,
    spindle_rpm: np.ndarray,
    depth_m: np.ndarray,
    tool: MillingTool,
    conditions: CuttingConditions,
    coefficients: CuttingCoefficients,
    *,
    n_tooth_periods: int = 300,
    steps_per_tooth: int = 120,
    entry_tooth_periods: int = 0,
    chatter_fraction_of_feed: float = 0.1,
    backend: str = "numba",
) -> np.ndarray:
    """Chatter (b,) of b independent cuts (:func:`_poincare_rows`), decided from the
    once-per-period samples as in :func:`simulate_regenerative_cut`."""
    _checked_simulation(
        steps_per_tooth, n_tooth_periods, entry_tooth_periods, chatter_fraction_of_feed
    )
    poincare = _poincare_rows(
        fn_hz, stiffness_n_per_m, damping_ratio, in_feed, spindle_rpm, depth_m, tool,
        conditions, coefficients, steps_per_tooth=steps_per_tooth,
        n_tooth_periods=n_tooth_periods, entry_tooth_periods=entry_tooth_periods,
        backend=backend,
    )  # fmt: skip
    growth, rate, amp = _poincare_indicators(poincare)
    return _is_chatter(growth, rate, amp, chatter_fraction_of_feed, conditions.feed_per_tooth_m)


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
        ``n_tooth_periods``, ``steps_per_tooth``, ``entry_tooth_periods``,
        ``chatter_fraction_of_feed`` of :func:`simulate_regenerative_cut` (whose verdicts the
        compiled batch reproduces).

    Returns
    -------
    (low, high) : depths [m], the limit lies between them.
    """
    lo, hi = (float(v) for v in depth_bracket_m)
    if not 0 < lo < hi:
        raise ValueError(f"depth_bracket_m must be 0 < low < high [m], got {depth_bracket_m}")
    modes = list(modes_x) + list(modes_y)
    if not modes:
        raise ValueError("at least one mode (x or y) is needed")
    fn, k, z = (a[None, :] for a in _mode_arrays(modes))
    feed = (np.arange(len(modes)) < len(modes_x))[None, :]

    def chatter(depth):
        # The verdicts of simulate_regenerative_cut (same samples, bit for bit), compiled.
        depth = np.asarray(depth, float)
        rows = np.zeros(depth.size, int)
        return _chatter_of_rows(
            fn[rows], k[rows], z[rows], feed[rows], np.full(depth.size, conditions.spindle_rpm),
            depth, tool, conditions, coefficients, **simulation,
        )  # fmt: skip

    ends = chatter([lo, hi])
    if ends[0] or not ends[1]:
        raise ValueError(
            f"the bracket must be stable at {lo:g} m and chatter at {hi:g} m "
            f"(simulated: {'chatter' if ends[0] else 'stable'}, "
            f"{'chatter' if ends[1] else 'stable'})"
        )
    for _ in range(int(n_bisections)):
        trial = np.linspace(lo, hi, int(n_parallel) + 2)[1:-1]
        chat = chatter(trial)
        stable = trial[~chat]
        unstable = trial[chat]
        if stable.size:
            lo = max(lo, float(stable.max()))
        if unstable.size:
            hi = min(hi, float(unstable.min()))
    return lo, hi


def time_domain_limit_ratio(
    modes_x: Sequence[ModalParameters],
    modes_y: Sequence[ModalParameters],
    tool: MillingTool,
    conditions: CuttingConditions,
    coefficients: CuttingCoefficients,
    spindle_rpm,
    linear_limit_m,
    *,
    factors: Sequence[float] = (0.6, 0.7, 0.8, 0.825, 0.85, 0.875, 0.9, 0.925, 0.95, 0.975, 1.0),
    return_bracket: bool = False,
    onset: str = "persistent",
    **simulation,
) -> np.ndarray | tuple[np.ndarray, np.ndarray]:
    """Ratio of the time-domain stability limit to a linear one, per speed.

    Linear theory (semi-discretization, zero-order method) assumes the flutes never leave the
    cut. The time-domain cut (:func:`simulate_regenerative_cut`, with its edge forces and its
    entry) can chatter below that limit: the large-amplitude chatter that coexists with the
    stable cut just below the linear limit is reached from the entry transient (the fly-over
    "unsafe zone"). At each speed the cut is simulated at ``factors`` × the linear limit (one
    batch); the ratio is the midpoint between the onset of chatter (``onset``, see
    :func:`time_domain_limit_ratios`) and the stable factor below it. It is never above 1 (a simulated limit above the linear
    one is taken as the linear one: the simulation's finite record can miss slow growth) and is
    ``0.75 * factors[0]`` where even the first factor chatters (bracket ``[0.5, 1] * factors[0]``).

    Parameters
    ----------
    modes_x, modes_y : sequence of ModalParameters
        Tool-tip modes in the feed and normal directions.
    tool, conditions, coefficients
        As for :func:`simulate_regenerative_cut` (the conditions' speed is replaced by each
        ``spindle_rpm``).
    spindle_rpm : array_like (n,)
        Speeds [rpm].
    linear_limit_m : array_like (n,)
        The linear limit [m] at each speed (e.g. ``sdm_lobes(...).a_lim_m``).
    factors : sequence of float
        Fractions of the linear limit simulated, increasing, in (0, 1].
    return_bracket : bool
        Also return where the ratio lies: ``(low, high)`` arrays (the stable and the chattering
        factor; both 1 where nothing chatters).
    onset : {"persistent", "first"}
        Where chatter starts: below the run of chattering factors that reaches the linear limit
        (default), or at the first chattering factor, isolated or not (the conservative form,
        robovib's earlier default); see :func:`time_domain_limit_ratios`.
    **simulation
        Passed to :func:`simulate_regenerative_cut` (``n_tooth_periods``, ``steps_per_tooth``,
        ``entry_tooth_periods``, ...).

    Returns
    -------
    numpy.ndarray (n,)
        Time-domain limit / linear limit at each speed, in (0, 1]; with ``return_bracket`` the
        tuple ``(low, high)`` instead (the ratio is their midpoint).

    Examples
    --------
    >>> from robovib.milling import ALUMINIUM_7075, CuttingConditions, MillingTool
    >>> from robovib.milling.sdm import sdm_lobes
    >>> from robovib.modal import ModalParameters
    >>> mx, my = [ModalParameters(16.5, 4.2e6, 0.1)], [ModalParameters(8.4, 9e5, 0.15)]
    >>> cond = CuttingConditions(1750.0, 0.058e-3, 3e-3, 6e-3)
    >>> lim = sdm_lobes(mx, my, MillingTool(), cond, ALUMINIUM_7075, [1750.0]).a_lim_m
    >>> r = time_domain_limit_ratio(mx, my, MillingTool(), cond, ALUMINIUM_7075, [1750.0], lim)
    >>> bool(0 < r[0] <= 1)
    True
    """
    rpm = np.atleast_1d(np.asarray(spindle_rpm, float))
    lim = np.atleast_1d(np.asarray(linear_limit_m, float))
    if rpm.shape != lim.shape:
        raise ValueError(f"spindle_rpm {rpm.shape} and linear_limit_m {lim.shape} differ in shape")
    low, high = time_domain_limit_ratios(
        [(modes_x, modes_y)], tool, conditions, coefficients, rpm, lim[None, :],
        factors=factors, onset=onset, **simulation,
    )  # fmt: skip
    low, high = low[0], high[0]
    return (low, high) if return_bracket else 0.5 * (low + high)


def time_domain_limit_ratios(
    mode_sets: Sequence[tuple[Sequence[ModalParameters], Sequence[ModalParameters]]],
    tool: MillingTool,
    conditions: CuttingConditions,
    coefficients: CuttingCoefficients,
    spindle_rpm,
    linear_limits_m,
    *,
    factors: Sequence[float] = (0.6, 0.7, 0.8, 0.825, 0.85, 0.875, 0.9, 0.925, 0.95, 0.975, 1.0),
    max_batch: int = 2048,
    onset: str = "persistent",
    above: Sequence[float] = (),
    search: str = "top-down",
    **simulation,
) -> tuple[np.ndarray, np.ndarray]:
    """Brackets of the time-domain / linear limit ratio for many mode sets at once.

    :func:`time_domain_limit_ratio` for each of ``S`` structures (e.g. the samples of a pose
    model's predictive distribution), every structure at every speed at every factor of its
    own linear limit simulated side by side in one batch (each cut its own modes, speed and
    depth; only the once-per-period samples are kept). The sampled structures sit at
    different places of their lobes, where the margin differs: this gives each its own.

    Parameters
    ----------
    mode_sets : sequence of (modes_x, modes_y)
        ``S`` structures: tool-tip modes in the feed and normal directions.
    tool, conditions, coefficients
        As for :func:`simulate_regenerative_cut` (the speed is replaced by each of
        ``spindle_rpm``).
    spindle_rpm : array_like (n,)
        Speeds [rpm].
    linear_limits_m : array_like (S, n)
        Each structure's linear limit [m] at each speed.
    factors : sequence of float
        Fractions of the linear limit simulated, increasing, in (0, 1].
    max_batch : int
        Cuts simulated at once (memory and cache).
    onset : {"persistent", "first"}
        Which chattering factor starts the chatter. ``"persistent"`` (default): the first of
        the run of chattering factors that goes on up to the linear limit. Below it, a full-depth
        entry at one isolated depth can reach the coexisting chatter while the depths on both
        sides stay stable (``...X.....XXXX``: about one pose and speed in six of the virtual
        robot, one 2.5 % step wide); that island is not where the cut becomes unstable, and
        taking it as the limit put too many low limits in the samples of
        :func:`robovib.milling.uncertainty.stability_probability` (cuts just below the predicted
        limit were stable 6-10 points more often than predicted, issue 24). ``"first"``: the
        first chattering factor, island or not (conservative; robovib's earlier default).
    above : sequence of float
        Factors above ``factors[-1]`` (increasing), simulated only for the structures and
        speeds whose cut at ``factors[-1]`` is stable: there the time-domain limit lies above
        the linear one. With several modes per direction this is common (issue 36: on the
        virtual robot with every mode, the cut at the zero-order limit was stable at 12 of 30
        poses and speeds, up to 1.3 times it, against 1 in 18 with the dominant modes alone):
        a bracket capped at 1 puts those limits too low. Empty (default): the ratio is never
        above 1. Where the cut at
        ``factors[-1]`` chatters, the factors above are taken to chatter as well.
    search : {"top-down", "grid"}
        How the factors are visited under ``onset="persistent"`` (``"first"`` always simulates
        every factor). ``"top-down"`` (default, issue 37): every case at the top factor first,
        then only the cases that chattered at the next factor down, round after round, until
        each meets a stable cut; the brackets are the same as ``"grid"`` (every factor of
        every case simulated) at the cost of the chattering run plus one cut per case instead
        of every factor. The cuts run in a compiled loop (numba) that gives the same samples,
        bit for bit, as :func:`simulate_regenerative_cut`'s.
    **simulation
        ``n_tooth_periods``, ``steps_per_tooth``, ``entry_tooth_periods``,
        ``chatter_fraction_of_feed`` of :func:`simulate_regenerative_cut`. ``steps_per_tooth``
        (default 120) is a minimum here: at a speed where a structure's highest mode would get
        fewer than 10 steps per period of its own, its cuts take enough more (a slow speed
        with a stiff mode, e.g. 100 rpm and 63 Hz; :func:`simulate_regenerative_cut` raises
        there instead).

    Returns
    -------
    low, high : numpy.ndarray (S, n)
        The stable factor below the onset of chatter, and the onset (both ``max(1, top)``
        where the top factor, ``factors[-1]`` or ``above[-1]``, is stable under
        ``"persistent"`` or nothing chatters; ``0.5, 1 × factors[0]`` where chatter starts at
        the first factor). The ratio of :func:`time_domain_limit_ratio` is their midpoint.

    Examples
    --------
    >>> from robovib.milling import ALUMINIUM_7075, CuttingConditions, MillingTool
    >>> from robovib.milling.sdm import sdm_lobes
    >>> from robovib.modal import ModalParameters
    >>> sets = [([ModalParameters(f, 4.2e6, 0.1)], [ModalParameters(8.4, 9e5, 0.15)])
    ...         for f in (16.0, 17.0)]
    >>> cond = CuttingConditions(1750.0, 0.058e-3, 3e-3, 6e-3)
    >>> lim = [sdm_lobes(mx, my, MillingTool(), cond, ALUMINIUM_7075, [1750.0]).a_lim_m
    ...        for mx, my in sets]
    >>> low, high = time_domain_limit_ratios(sets, MillingTool(), cond, ALUMINIUM_7075,
    ...                                      [1750.0], lim, n_tooth_periods=100)
    >>> low.shape, bool(np.all((0 < low) & (low <= high) & (high <= 1)))
    ((2, 1), True)
    """
    rpm = np.atleast_1d(np.asarray(spindle_rpm, float))
    lim = np.asarray(linear_limits_m, float)
    f = np.asarray(factors, float)
    n_sets = len(mode_sets)
    if n_sets == 0:
        raise ValueError("mode_sets is empty: give at least one (modes_x, modes_y)")
    if rpm.ndim != 1 or lim.shape != (n_sets, rpm.size):
        raise ValueError(
            f"linear_limits_m must have shape (n_sets, n_speeds) = ({n_sets}, {rpm.size}), "
            f"got {lim.shape}"
        )
    if f.ndim != 1 or f.size < 2 or np.any(np.diff(f) <= 0) or f[0] <= 0 or f[-1] > 1:
        raise ValueError("factors must increase within (0, 1] (at least two)")
    if onset not in ("persistent", "first"):
        raise ValueError(f"onset must be 'persistent' or 'first', got {onset!r}")
    if search not in ("top-down", "grid"):
        raise ValueError(f"search must be 'top-down' or 'grid', got {search!r}")
    up = np.asarray(above, float).ravel()
    if up.size and (not np.all(np.isfinite(up)) or np.any(np.diff(up) <= 0) or up[0] <= f[-1]):
        raise ValueError(
            f"above must increase from beyond the last factor {f[-1]:g}, got {list(above)!r}"
        )
    bad = ~(np.isfinite(lim) & (lim > 0))
    if bad.any():
        s_bad, r_bad = np.argwhere(bad)[0]
        raise ValueError(
            f"linear_limits_m of set {s_bad} at {rpm[r_bad]:g} rpm must be a positive depth [m]"
        )
    unknown = set(simulation) - {
        "n_tooth_periods", "steps_per_tooth", "entry_tooth_periods", "chatter_fraction_of_feed"
    }  # fmt: skip
    if unknown:
        raise TypeError(f"unknown simulation options: {sorted(unknown)}")
    n_modes = max(len(mx) + len(my) for mx, my in mode_sets)
    if n_modes == 0:
        raise ValueError("at least one mode (x or y) is needed")
    fn = np.zeros((n_sets, n_modes))
    k = np.ones((n_sets, n_modes))
    z = np.full((n_sets, n_modes), 0.5)
    feed = np.zeros((n_sets, n_modes), bool)
    for i, (mx, my) in enumerate(mode_sets):
        modes = list(mx) + list(my)
        fn[i, : len(modes)], k[i, : len(modes)], z[i, : len(modes)] = _mode_arrays(modes)
        feed[i, : len(mx)] = True
    step = max(int(max_batch), 1)
    m_min, _, _ = _checked_simulation(
        simulation.get("steps_per_tooth", 120), simulation.get("n_tooth_periods", 300),
        simulation.get("entry_tooth_periods", 0), simulation.get("chatter_fraction_of_feed", 0.1),
    )  # fmt: skip
    # Steps per tooth period of each structure and speed: at least ``steps_per_tooth``, more
    # where its highest mode would get fewer than 10 steps per period (slow speeds).
    tooth_period = 60.0 / (int(tool.n_flutes) * rpm)
    steps = np.maximum(m_min, np.floor(10 * fn.max(axis=1)[:, None] * tooth_period).astype(int) + 1)

    def chatter_at(sets_i, speeds_i, depth):
        """Chatter of the cuts of structures ``sets_i`` at speeds ``speeds_i`` and ``depth``."""
        flags = np.empty(depth.size, bool)
        m_rows = steps[sets_i, speeds_i]
        for m in np.unique(m_rows):
            rows = np.flatnonzero(m_rows == m)
            for a in range(0, rows.size, step):
                sub = rows[a : a + step]
                si = sets_i[sub]
                flags[sub] = _chatter_of_rows(
                    fn[si], k[si], z[si], feed[si], rpm[speeds_i[sub]], depth[sub], tool,
                    conditions, coefficients, **{**simulation, "steps_per_tooth": int(m)},
                )  # fmt: skip
        return flags

    if search == "top-down" and onset == "persistent":
        return _top_down(chatter_at, lim, f, up)
    # Every factor of every structure and speed (the reference of "top-down"; and "first").
    shape = (n_sets, rpm.size, f.size)
    idx_set = np.broadcast_to(np.arange(n_sets)[:, None, None], shape).ravel()
    idx_speed = np.broadcast_to(np.arange(rpm.size)[None, :, None], shape).ravel()
    row_depth = (lim[:, :, None] * f[None, None, :]).ravel()
    chat = chatter_at(idx_set, idx_speed, row_depth).reshape(shape)
    if up.size:  # only the structures and speeds still stable at the last factor
        chat_up = np.ones((*shape[:2], up.size), bool)
        s_open, r_open = np.nonzero(~chat[:, :, -1])
        if s_open.size:
            depth_up = (lim[s_open, r_open][:, None] * up[None, :]).ravel()
            flags = chatter_at(np.repeat(s_open, up.size), np.repeat(r_open, up.size), depth_up)
            chat_up[s_open, r_open] = flags.reshape(s_open.size, up.size)
        chat = np.concatenate([chat, chat_up], axis=2)
        f = np.concatenate([f, up])
        shape = chat.shape
    if onset == "persistent":
        # Chattering from here up to the last factor: isolated chattering depths drop out.
        chat = np.flip(np.logical_and.accumulate(np.flip(chat, axis=2), axis=2), axis=2)
    top = max(1.0, float(f[-1]))
    low, high = np.full(shape[:2], top), np.full(shape[:2], top)
    any_chat = chat.any(axis=2)
    first = np.argmax(chat, axis=2)
    at_first = any_chat & (first == 0)
    later = any_chat & (first > 0)
    low[at_first], high[at_first] = 0.5 * f[0], f[0]
    low[later], high[later] = f[first[later] - 1], f[first[later]]
    return low, high


def _top_down(chatter_at, lim: np.ndarray, factors: np.ndarray, above: np.ndarray):
    """The persistent-onset brackets of :func:`time_domain_limit_ratios`, walking down.

    The persistent onset is the lowest factor of the run of chattering factors that reaches the
    top, so it is found by simulating the top factor of every case (structure x speed), then,
    for the cases that chattered there, the next factor down, and so on until a case's cut is
    stable: below that stable factor nothing changes its bracket. Every round is one batch of
    the cases still walking (``chatter_at(set_index, speed_index, depth)``). The factors above
    the linear limit are walked the same way from ``above[-1]`` for the cases stable at
    ``factors[-1]``. The brackets are those of simulating every factor (same cuts, same
    verdicts; tested), at the cost of the run of chattering factors plus one per case instead
    of every factor.
    """
    top = max(1.0, float(above[-1] if above.size else factors[-1]))
    low, high = np.full(lim.size, top), np.full(lim.size, top)

    def walk(set_i, speed_i, levels):
        # Index in levels of the persistent onset per case; levels.size where the top is stable.
        onset = np.full(set_i.size, levels.size)
        pos = np.full(set_i.size, levels.size - 1)
        active = np.arange(set_i.size)
        while active.size:
            si, ri = set_i[active], speed_i[active]
            chat = chatter_at(si, ri, lim[si, ri] * levels[pos[active]])
            onset[active[chat]] = pos[active[chat]]
            active = active[chat & (pos[active] > 0)]
            pos[active] -= 1
        return onset

    set_i, speed_i = (a.ravel() for a in np.indices(lim.shape))
    onset = walk(set_i, speed_i, factors)
    at_first, later = onset == 0, (onset > 0) & (onset < factors.size)
    low[at_first], high[at_first] = 0.5 * factors[0], factors[0]
    low[later], high[later] = factors[onset[later] - 1], factors[onset[later]]
    still = np.flatnonzero(onset == factors.size)  # stable at the last factor
    if above.size and still.size:
        onset_up = walk(set_i[still], speed_i[still], above)
        below = np.concatenate([factors[-1:], above])  # the stable factor under each onset
        closed = onset_up < above.size
        low[still[closed]] = below[onset_up[closed]]
        high[still[closed]] = above[onset_up[closed]]
    return low.reshape(lim.shape), high.reshape(lim.shape)
