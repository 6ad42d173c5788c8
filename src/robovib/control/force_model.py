"""Feedforward of the measured force through the pose model: the non-periodic force too.

A repetitive or harmonic controller cancels only the tooth-periodic part of the cutting force.
The rest — material inhomogeneity, chip breakage, engagement changes, runout lines it does not
learn — excites the structural mode too, and the force sensor measures it. Here the pose
model's mode (per direction: fn, zeta, static stiffness k) is run on the measured force
(high-passed: the sensor bias and the mean force do not vibrate) and on this controller's own
corrections, ``delay_s`` late:

    x'' + 2 zeta wn x' + wn^2 x = wn^2 (F / k + u(t - delay))

and the delay-aware LQR of :func:`~robovib.control.lqr.design_delay_aware_lqr` (weights
``Q = diag(1, 0)`` on the displacement, ``R = r``) acts on that model state and the commands
in flight. Against the true robot it is a *feedforward*: the correction is a causal, stable
filter of the measured force (the loop closes through the model only), so it cannot
destabilise the robot whatever the delay or gain error, and it leaves the plant that a
tracker-based controller added to it (e.g. :class:`~robovib.control.adaptive.TrackingRepetitive`)
sees unchanged.

What it can remove is bounded by the delay: the response of the mode to the force of the last
``delay`` seconds cannot be predicted (:func:`unpredictable_fraction`).
"""

from __future__ import annotations

import math

import numpy as np

from ..modal.parameters import ModalParameters
from .controllers import ScheduledTable
from .lqr import continuous_model, design_delay_aware_lqr, discretize, spectral_radius

__all__ = [
    "ForceModelFeedforward",
    "force_model_r",
    "force_model_variance_ratio",
    "unpredictable_fraction",
]


def unpredictable_fraction(
    mode: ModalParameters, delay_s: float, sample_rate_hz: float = 1000.0, band_hz=None
) -> float:
    """RMS fraction of a mode's response to white (or low-passed) force left by any causal
    controller whose input arrives ``delay_s`` late: ``sqrt(int_0^delay h^2 / int_0^inf h^2)``.

    ``h`` is the impulse response from force to displacement (with a 2nd-order Butterworth
    low-pass at ``band_hz`` in front when given). The minimum-variance bound: the part of the
    response to the force of the last ``delay_s`` is unknown when the correction is sent.

    Parameters
    ----------
    mode
        The mode.
    delay_s
        Input delay [s] (>= 0).
    sample_rate_hz
        Rate of the discretisation [Hz].
    band_hz
        Cut-off of the force's low-pass [Hz] or None (white).

    Returns
    -------
    float
        In [0, 1].
    """
    from scipy import signal

    if not (delay_s >= 0 and sample_rate_hz > 0):
        raise ValueError("delay_s >= 0 and sample_rate_hz > 0")
    fs = float(sample_rate_hz)
    a, b = continuous_model(mode)
    ad, bd = discretize(a, b, 1.0 / fs)
    n = max(int(20 / (mode.damping_ratio * mode.omega_n) * fs), round(delay_s * fs) + 10)
    x = bd[:, 0].copy()
    h = np.empty(n)
    for i in range(n):
        h[i] = x[0]
        x = ad @ x
    h = np.concatenate([[0.0], h[:-1]])  # the force of sample 0 moves the tip from sample 1
    if band_hz is not None:
        bb, aa = signal.butter(2, min(band_hz / (fs / 2), 0.99))
        h = signal.lfilter(bb, aa, h)
    d = round(delay_s * fs)
    return float(math.sqrt(np.sum(h[: d + 1] ** 2) / np.sum(h**2)))


def _plant(plant) -> list[ModalParameters]:
    return [plant] if isinstance(plant, ModalParameters) else list(plant)


def _gains(model: ModalParameters, period_s: float, d_model: int, r: float) -> np.ndarray:
    return design_delay_aware_lqr(model, period_s, d_model * period_s, q=np.diag([1.0, 0.0]),
                                  r=[[r]]).gains  # fmt: skip


def _loop(plant, model: ModalParameters, period_s, d_model, d_true, g):
    """(A, B, C) at the command rate: true plant, the feedforward's model and its commands.

    ``plant``: one mode or a list (tip = sum of the modes; each driven by ``F / k_i`` and the
    correction through the static stiffness ``k_s = 1 / sum(1 / k_i)``, as the simulator).
    State ``[x_1, v_1, ..., x_m, v_m, u_{k-1}, ..., u_{k-n}]`` then the model's ``[x, v]``;
    input the force [N] held over a command period.
    """
    if d_true < 1 or d_model < 1:
        raise ValueError("the delays must be at least one command period")
    modes = _plant(plant)
    k_s = 1.0 / sum(1.0 / m.stiffness_n_per_m for m in modes)
    am, bm = discretize(*continuous_model(model), period_s)
    nh = max(d_model, d_true)
    npl = 2 * len(modes)
    n = npl + 2 + nh
    a = np.zeros((n, n))
    b = np.zeros((n, 1))
    c = np.zeros((1, n))
    mi = slice(npl, npl + 2)  # the model's state

    def u_col(j):  # column of u_{k-j} (j >= 1) in the state
        return npl + 1 + j

    for i, m in enumerate(modes):
        ap, bp = discretize(*continuous_model(m), period_s)
        sl = slice(2 * i, 2 * i + 2)
        a[sl, sl] = ap
        b[sl, 0] = bp[:, 0] / m.stiffness_n_per_m
        a[sl, u_col(d_true)] += bp[:, 0] * k_s / m.stiffness_n_per_m
        c[0, 2 * i] = 1.0
    a[mi, mi] = am
    b[mi, 0] = bm[:, 0] / model.stiffness_n_per_m
    a[mi, u_col(d_model)] += bm[:, 0]
    # u_k = -K [x_m, v_m, u_{k-1..k-d_model}] enters the history
    a[u_col(1), mi] = -g[:2]
    for j in range(1, d_model + 1):
        a[u_col(1), u_col(j)] -= g[1 + j]
    for j in range(2, nh + 1):
        a[u_col(j), u_col(j - 1)] = 1.0
    return a, b, c


def force_model_variance_ratio(
    plant,
    model: ModalParameters,
    r: float,
    *,
    period_s: float = 0.004,
    delay_s: float = 0.032,
    true_delay_s: float | None = None,
    gains=None,
) -> float:
    """RMS displacement with / without :class:`ForceModelFeedforward` under white force.

    Linear analysis at the command rate (force held over a command period): the feedforward
    designed on ``model`` with ``delay_s`` against the true ``plant`` whose corrections arrive
    ``true_delay_s`` late; steady-state variances from discrete Lyapunov equations.

    Parameters
    ----------
    plant, model
        The true mode (or list of modes: tip = their sum) and the pose model's mode.
    r
        LQR weight of the feedforward.
    period_s
        Command period [s].
    delay_s, true_delay_s
        Nominal and true transport delay [s] (whole command periods; true default: nominal).
    gains
        The feedforward's LQR gains if already designed (else from ``model``, ``r``).

    Returns
    -------
    float
        ``sqrt(var_closed / var_open)``; < 1: the feedforward reduces the vibration; inf when
        the combination is unstable (the model's own loop: never for a stable design).
    """
    from scipy.linalg import solve_discrete_lyapunov

    true_delay_s = delay_s if true_delay_s is None else true_delay_s
    d_m, d_t = round(delay_s / period_s), round(true_delay_s / period_s)
    g = _gains(model, period_s, d_m, r) if gains is None else gains
    a, b, c = _loop(plant, model, period_s, d_m, d_t, g)
    if spectral_radius(a) >= 1:
        return math.inf
    var = (c @ solve_discrete_lyapunov(a, b @ b.T) @ c.T)[0, 0]
    npl = 2 * len(_plant(plant))  # open loop: the plant block alone
    a0, b0, c0 = a[:npl, :npl], b[:npl], c[:, :npl]
    var0 = (c0 @ solve_discrete_lyapunov(a0, b0 @ b0.T) @ c0.T)[0, 0]
    return float(math.sqrt(var / var0))


def force_model_r(
    plants,
    model: ModalParameters,
    *,
    period_s: float = 0.004,
    delay_s: float = 0.032,
    true_delays_s=None,
    r_grid=None,
) -> tuple[float, float]:
    """The LQR weight of :class:`ForceModelFeedforward` with the best worst case.

    The worst :func:`force_model_variance_ratio` over ``plants`` (e.g. the pose model's band)
    and ``true_delays_s`` (default: the nominal delay ± 8 ms, the 24-40 ms range around the
    32 ms measured) is minimised over ``r_grid`` (default 1e-3 ... 1e2).

    Parameters
    ----------
    plants
        Iterable of plant hypotheses (:class:`robovib.modal.ModalParameters` or lists of
        them, e.g. the pose model's band and second-mode cases) the worst case is taken over.
    model
        The pose model's mode the feedforward is designed on (fn [Hz], k [N/m], zeta).
    period_s
        Command period [s].
    delay_s
        Command delay the design assumes [s].
    true_delays_s
        Delays [s] the worst case is taken over (default ``delay_s`` - 8 ms, ``delay_s``,
        ``delay_s`` + 8 ms).
    r_grid
        Candidate control weights (default ``logspace(-3, 2, 11)``).

    Returns
    -------
    r, worst_ratio
        The weight and its worst RMS ratio.
    """
    if true_delays_s is None:
        true_delays_s = (delay_s - 0.008, delay_s, delay_s + 0.008)
    grid = np.logspace(-3, 2, 11) if r_grid is None else np.asarray(r_grid, float)
    best = (math.nan, math.inf)
    for r in grid:
        g = _gains(model, period_s, round(delay_s / period_s), r)
        worst = max(
            force_model_variance_ratio(
                p, model, r, period_s=period_s, delay_s=delay_s, true_delay_s=td, gains=g
            )
            for p in plants
            for td in true_delays_s
        )
        if worst < best[1]:
            best = (float(r), worst)
    return best


class ForceModelFeedforward:
    """Delay-aware LQR on the pose model driven by the measured force (see the module docs).

    Parameters
    ----------
    modes
        Direction -> :class:`ScheduledTable` of (fn [Hz], zeta, k [N/m]) rows along the path
        (or a :class:`~robovib.modal.ModalParameters`), from the pose model.
    delay_s
        Nominal transport delay [s] of the command channel (a whole number of command periods).
    r
        LQR weight of the correction against the displacement (> 0; smaller: closer to the
        minimum-variance bound, larger: gentler against model and delay errors), one for all
        directions or direction -> weight (e.g. from :func:`force_model_r`).
    highpass_hz
        Cut-off of the first-order high-pass on the measured force [Hz] (> 0): removes the
        sensor bias and the mean force.
    """

    def __init__(
        self,
        modes: dict,
        delay_s: float = 0.032,
        *,
        r: float | dict = 1.0,
        highpass_hz: float = 1.0,
    ):
        self.modes = {int(a): m for a, m in modes.items()}
        rr = dict(r) if isinstance(r, dict) else dict.fromkeys(self.modes, r)
        self.r = {int(a): float(rr[a]) for a in self.modes}
        if not (all(v > 0 for v in self.r.values()) and highpass_hz > 0 and delay_s >= 0):
            raise ValueError("r > 0, highpass_hz > 0 [Hz] and delay_s >= 0 [s]")
        self.delay_s = float(delay_s)
        self.highpass_hz = float(highpass_hz)
        self._cache: dict = {}

    def _rows(self, table: ScheduledTable, period_s: float, dt: float, r: float) -> ScheduledTable:
        """Per grid point: [k, Phi (4), Gamma (2), K (2 + d)] of the 1 kHz model and the gains."""
        rows = []
        for fn, z, k in table.values[:, :3]:
            key = (fn, z, k, period_s, dt, r)
            if key not in self._cache:
                mode = ModalParameters(fn, k, z)
                ad, bd = discretize(*continuous_model(mode), dt)
                g = _gains(mode, period_s, round(self.delay_s / period_s), r)
                self._cache[key] = np.concatenate([[k], ad.ravel(), bd[:, 0], g])
            rows.append(self._cache[key])
        return ScheduledTable(table.s_m, np.array(rows))

    def reset(self, coords, period_s: float, sample_rate_hz: float) -> None:
        dt = 1.0 / float(sample_rate_hz)
        self._every = round(period_s * sample_rate_hz)
        d = round(self.delay_s / period_s)
        if abs(d * period_s - self.delay_s) > 1e-9:
            raise ValueError("delay_s must be a whole number of command periods")
        self._tab = {}
        for a, m in self.modes.items():
            if isinstance(m, ModalParameters):
                m = ScheduledTable.constant([m.natural_frequency_hz, m.damping_ratio,
                                             m.stiffness_n_per_m])  # fmt: skip
            self._tab[a] = self._rows(m, float(period_s), dt, self.r[a]).at(coords)
        self._x = {a: np.zeros(2) for a in self._tab}
        self._hist = {a: np.zeros(d) for a in self._tab}  # u_{k-1} ... u_{k-d}
        self._alpha = math.exp(-2 * math.pi * self.highpass_hz * dt)
        self._f_prev = None
        self._f_hp = np.zeros(3)
        self._pending = None  # the newest force sample: it acts over the next sample
        self._applied = {a: 0.0 for a in self._tab}  # the command reaching the model's plant

    def _highpass(self, f: np.ndarray) -> np.ndarray:
        if self._f_prev is None:
            self._f_prev = f[0].copy()  # the first sample (a first cycle may bring several)
        out = np.empty_like(f)
        for i, row in enumerate(f):
            self._f_hp = self._alpha * (self._f_hp + row - self._f_prev)
            self._f_prev = row
            out[i] = self._f_hp
        return out

    def command(self, k: int, tracker_m: np.ndarray, force_n: np.ndarray) -> np.ndarray:
        f = self._highpass(np.asarray(force_n, float))
        steps = f[:-1] if self._pending is None else np.vstack([self._pending, f[:-1]])
        self._pending = f[-1]
        u = np.zeros(3)
        for a, tab in self._tab.items():
            row = tab[k]
            stiff, phi, gam, g = row[0], row[1:5].reshape(2, 2), row[5:7], row[7:]
            x = self._x[a]
            for fi in steps[:, a]:
                x = phi @ x + gam * (fi / stiff + self._applied[a])
            self._x[a] = x
            hist = self._hist[a]
            ua = -(g[0] * x[0] + g[1] * x[1] + g[2:] @ hist)
            if hist.size:
                self._applied[a] = hist[-1]  # u_{k-d}: reaches the plant over this period
                hist[1:] = hist[:-1]
                hist[0] = ua
            else:
                self._applied[a] = ua
            u[a] = ua
        return u
