"""Run-time vibration controllers for the command channel (thesis ch. 4 and beyond).

Every controller here follows one small protocol, run once per command period (RSI: 4 ms):

* ``reset(coords, period_s, sample_rate_hz)``: called once before a run with the pose
  coordinates at every command instant (path distance [m], shape (n_cmd,), or workspace poses
  (n_cmd, 3)). Scheduled gains are looked up here for the whole run (a table per instant), so
  the cycle itself does no interpolation.
* ``command(k, tracker_m, force_n) -> (3,)``: called at command instant ``k`` with the tracker
  samples (m, 3) [m] and force-sensor samples (m, 3) [N] of the period that ends at the current
  sample (last row = now, 1 kHz), returning the path correction [m] per direction.

Controllers (directions are the keys ``0, 1, 2`` = X, Y, Z of the dicts they take):

* :class:`StateFeedback` — the thesis' ``u = -(w1 x + w2 v)`` (Eq. 23-25) with the velocity by
  backward difference over the command period; gains constant or scheduled along the path
  (Eq. 28-29).
* :class:`DelayAwareFeedback` — ``u = -K [x, v, u_{k-1}, ..., u_{k-d}]`` (LQR on the
  delay-augmented model, :func:`~robovib.control.lqr.design_delay_aware_lqr`) with either the
  backward-difference state or a steady-state Kalman filter run on every 1 kHz tracker sample
  (LQG, :func:`design_lqg`).
* :class:`ForceFeedforward` — beyond the thesis: the deflection the measured cutting force will
  cause once the correction arrives (``delay`` later) is predicted from the force one (or more)
  excitation periods earlier (the cutting force repeats every tooth period) and cancelled.
* :class:`Combined` — the sum of controllers (feedforward + feedback).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from ..modal.parameters import ModalParameters

# Loop analysis, the Kalman design and the scheduled tables live in their own modules; their
# names stay importable from here (the public API promised them).
from .loop_analysis import (
    delay_aware_gains,
    design_tuned_state_feedback,
    implemented_loop_matrix,
    lqg_loop_matrix,
    modal_correction_frf,
    repetitive_loop_radius,
    state_feedback_sensitivity,
)
from .lqr import KalmanDesign, design_kalman, spectral_radius
from .scheduled import LiveMap, LiveRows, PathCursor, ScheduledTable, map_rows, n_commands

__all__ = [
    "Combined",
    "DelayAwareFeedback",
    "ForceFeedforward",
    "KalmanDesign",
    "LiveMap",
    "LiveRows",
    "PathCursor",
    "RepetitiveFeedback",
    "ScheduledTable",
    "StateFeedback",
    "delay_aware_gains",
    "design_kalman",
    "design_tuned_state_feedback",
    "implemented_loop_matrix",
    "lqg_loop_matrix",
    "map_rows",
    "modal_correction_frf",
    "n_commands",
    "repetitive_loop_radius",
    "spectral_radius",
    "state_feedback_sensitivity",
]


def _table(spec) -> ScheduledTable:
    if isinstance(spec, ScheduledTable):
        return spec
    return ScheduledTable.constant(spec)


class StateFeedback:
    """Thesis controller ``u = -(w1 x + w2 v)`` per direction (Eq. 23-25, 28-29).

    Parameters
    ----------
    gains
        Direction index -> ``(w1, w2)`` constants or a :class:`ScheduledTable` with 2 columns
        (w1 [m/m], w2 [s]).
    """

    def __init__(self, gains: dict[int, ScheduledTable | Sequence[float]]):
        self.gains = {int(a): _table(g) for a, g in gains.items()}
        for a, g in self.gains.items():
            if a not in (0, 1, 2) or g.values.shape[1] != 2:
                raise ValueError("StateFeedback gains: direction 0-2 -> (w1, w2)")

    def reset(self, coords, period_s: float, sample_rate_hz: float) -> None:
        self._tab = {a: g.at(coords) for a, g in self.gains.items()}
        self._period = float(period_s)
        self._prev = np.zeros(3)

    def command(self, k: int, tracker_m: np.ndarray, force_n: np.ndarray) -> np.ndarray:
        x = tracker_m[-1]
        vel = (x - self._prev) / self._period if k > 0 else np.zeros(3)
        self._prev = x
        u = np.zeros(3)
        for a, tab in self._tab.items():
            u[a] = -(tab[k, 0] * x[a] + tab[k, 1] * vel[a])
        return u


class DelayAwareFeedback:
    """``u = -K [x, v, u_{k-1}, ..., u_{k-d}]`` per direction, scheduled along the path.

    Parameters
    ----------
    gains
        Direction -> :class:`ScheduledTable` of the delay-aware gains (2 + d columns), e.g.
        from :func:`~robovib.control.lqr.design_delay_aware_lqr` at grid points.
    kalman
        ``None``: ``[x, v]`` from the latest tracker sample and the backward difference over
        the command period. Otherwise direction -> ``(s_grid_m, [KalmanDesign, ...])``: a
        steady-state Kalman filter run on every tracker sample (LQG), fed with the corrections
        this controller sent, ``delay_samples`` late.
    delay_samples
        The nominal transport delay in tracker samples (used by the Kalman filter).
    """

    def __init__(
        self,
        gains: dict[int, ScheduledTable],
        kalman: dict[int, tuple[np.ndarray, list[KalmanDesign]]] | None = None,
        delay_samples: int = 32,
    ):
        self.gains = {int(a): _table(g) for a, g in gains.items()}
        self.kalman = kalman
        self.delay_samples = int(delay_samples)

    def reset(self, coords, period_s: float, sample_rate_hz: float) -> None:
        self._tab = {a: g.at(coords) for a, g in self.gains.items()}
        self._hist = {a: np.zeros(t.shape[1] - 2) for a, t in self._tab.items()}
        self._period = float(period_s)
        self._every = round(period_s * sample_rate_hz)
        self._prev = np.zeros(3)
        self._kf = None
        if self.kalman is not None:
            self._kf = {}
            for a, (s_grid, designs) in self.kalman.items():
                rows = np.array(
                    [np.concatenate([d.phi.ravel(), d.gamma_u, d.gain]) for d in designs]
                )
                self._kf[a] = ScheduledTable(np.asarray(s_grid, float), rows).at(coords)
            self._xhat = {a: np.zeros(2) for a in self._kf}
            n = n_commands(coords)
            self._sent = np.zeros(((n + 2) * self._every + self.delay_samples, 3))
            self._sample = -1

    def _kalman_step(self, k, tracker_m):
        for row in tracker_m:
            self._sample += 1
            i = self._sample
            applied = self._sent[i - self.delay_samples] if i >= self.delay_samples else None
            for a, tab in self._kf.items():
                r = tab[k]
                x = self._xhat[a]
                x = x + r[6:8] * (row[a] - x[0])  # update with this sample
                u = 0.0 if applied is None else applied[a]
                self._xhat[a] = np.array(
                    [r[0] * x[0] + r[1] * x[1] + r[4] * u, r[2] * x[0] + r[3] * x[1] + r[5] * u]
                )
                self._post = getattr(self, "_post", {})
                self._post[a] = x

    def command(self, k: int, tracker_m: np.ndarray, force_n: np.ndarray) -> np.ndarray:
        u = np.zeros(3)
        if self._kf is not None:
            self._kalman_step(k, tracker_m)
        else:
            x = tracker_m[-1]
            vel = (x - self._prev) / self._period if k > 0 else np.zeros(3)
            self._prev = x
        for a, tab in self._tab.items():
            g = tab[k]
            state = self._post[a] if self._kf is not None else (x[a], vel[a])
            hist = self._hist[a]
            ua = -(g[0] * state[0] + g[1] * state[1] + g[2:] @ hist)
            if hist.size:
                hist[1:] = hist[:-1]
                hist[0] = ua
            u[a] = ua
        if self._kf is not None:
            i = self._sample
            self._sent[i : i + self._every] = u
        return u


class ForceFeedforward:
    """Cancel the deflection the measured periodic force will cause when the correction lands.

    A correction ``u`` enters the structure like a force ``k_s u`` at the tool (``k_s`` the
    static stiffness of the direction, ``1 / H(0)`` of the pose's FRF), so the correction that
    cancels the deflection ``H F`` of a force ``F`` is ``u = -F / k_s`` at every frequency
    (``P_u^-1 H = 1 / k_s``). The force acting when the correction arrives, ``delay`` to
    ``delay + period`` later, is predicted from the measured force ``p`` excitation periods
    earlier (averaged over ``n_periods`` periods to shed the non-repeating part), which is
    causal as long as the excitation period is longer than delay + command period.

    Parameters
    ----------
    stiffness
        Direction -> static stiffness [N/m] (constant or a 1-column :class:`ScheduledTable`
        along the path), from the pose model.
    excitation_period_s
        Period of the force [s] (tooth period ``60 / (rpm * teeth)``, rotation period for an
        offset mass).
    delay_s
        Nominal transport delay [s] of the command channel.
    n_periods
        Past periods averaged in the prediction.
    include_mean
        Also cancel the mean (static) deflection; ``False`` cancels only the vibration.
    """

    def __init__(
        self,
        stiffness: dict[int, ScheduledTable | float],
        excitation_period_s: float,
        delay_s: float = 0.032,
        *,
        n_periods: int = 3,
        include_mean: bool = False,
    ):
        if not (math.isfinite(excitation_period_s) and excitation_period_s > 0):
            raise ValueError(f"excitation_period_s must be > 0 [s], got {excitation_period_s!r}")
        if not delay_s >= 0:
            raise ValueError(f"delay_s must be >= 0 [s], got {delay_s!r}")
        if int(n_periods) < 1:
            raise ValueError("n_periods must be >= 1")
        self.stiffness = {int(a): _table(k) for a, k in stiffness.items()}
        self.excitation_period_s = float(excitation_period_s)
        self.delay_s = float(delay_s)
        self.n_periods = int(n_periods)
        self.include_mean = bool(include_mean)

    def reset(self, coords, period_s: float, sample_rate_hz: float) -> None:
        fs = float(sample_rate_hz)
        self._every = round(period_s * fs)
        self._delay = round(self.delay_s * fs)
        self._n = self.excitation_period_s * fs  # samples per period (may be fractional)
        need = self._delay + self._every
        if self._n < need:
            raise ValueError(
                f"the excitation period {self.excitation_period_s * 1e3:.1f} ms is shorter than "
                f"delay + command period {need / fs * 1e3:.1f} ms: the force cannot be predicted"
            )
        self._p0 = max(1, math.ceil(need / self._n))
        self._k = {a: t.at(coords)[:, 0] for a, t in self.stiffness.items()}
        n_cmd = n_commands(coords) if self._k else 0
        self._buf = np.zeros(((n_cmd + 2) * self._every, 3))
        self._len = 0
        self._sum = np.zeros(3)

    def command(self, k: int, tracker_m: np.ndarray, force_n: np.ndarray) -> np.ndarray:
        m = force_n.shape[0]
        self._buf[self._len : self._len + m] = force_n
        self._sum += force_n.sum(axis=0)
        self._len += m
        i = self._len - 1
        offsets = i + self._delay + np.arange(self._every)  # samples the correction will act on
        preds, used = np.zeros(3), 0
        for p in range(self._p0, self._p0 + self.n_periods):
            src = offsets - p * self._n
            if src[0] < 0:
                break
            lo = np.floor(src).astype(int)
            w = src - lo
            f = self._buf[lo] * (1 - w)[:, None] + self._buf[np.minimum(lo + 1, i)] * w[:, None]
            preds += f.mean(axis=0)
            used += 1
        u = np.zeros(3)
        if used == 0:
            return u
        pred = preds / used
        if not self.include_mean:
            pred = pred - self._sum / self._len
        for a, kk in self._k.items():
            u[a] = -pred[a] / kk[k]
        return u


class RepetitiveFeedback:
    """Feedback with an internal model of the periodic disturbance (harmonic repetitive control).

    Uses the tracker only (no force sensor). The correction is a sum of harmonics of the
    excitation frequency, ``u(t) = Re sum_h U_h e^{j h w0 t}`` (evaluated at the time the
    correction lands, ``delay_s`` after it is sent), whose phasors are learnt: every
    command period the residual tip vibration's harmonics ``R_h`` are estimated over the last
    excitation period (a DFT: broadband noise is rejected) and ``U_h <- U_h - gain R_h /
    P(j h w0)``, with ``P(j w) = wn^2 / (wn^2 - w^2 + 2 j zeta wn w)`` the pose model's
    correction-to-tip FRF and ``gain = period / learning_time``. The 32 ms delay does not matter
    for a phasor fixed in absolute time; the learning loop converges when ``Re(P / P_model) > 0``
    at each harmonic and the learning is slow against delay + window. Only harmonics below
    ``max_harmonic_ratio`` x the mode's frequency are used (above, unmodelled modes make the
    model's phase unreliable).

    Parameters
    ----------
    modes
        Direction -> :class:`ScheduledTable` with columns (fn [Hz], zeta) along the path.
    excitation_period_s
        Period of the disturbance [s] (tooth period).
    delay_s
        Nominal transport delay [s] of the command channel.
    n_harmonics
        Most harmonics cancelled.
    learning_time_s
        Time constant of the learning [s].
    max_harmonic_ratio
        Harmonics above this multiple of the mode's natural frequency are left alone.
    """

    def __init__(
        self,
        modes: dict[int, ScheduledTable],
        excitation_period_s: float,
        delay_s: float = 0.032,
        *,
        n_harmonics: int = 4,
        learning_time_s: float = 0.4,
        max_harmonic_ratio: float = 1.6,
    ):
        if not (math.isfinite(excitation_period_s) and excitation_period_s > 0):
            raise ValueError(f"excitation_period_s must be > 0 [s], got {excitation_period_s!r}")
        if int(n_harmonics) < 1 or not learning_time_s > 0 or not max_harmonic_ratio > 0:
            raise ValueError("n_harmonics >= 1, learning_time_s > 0 [s], max_harmonic_ratio > 0")
        self.modes = {int(a): _table(m) for a, m in modes.items()}
        self.excitation_period_s = float(excitation_period_s)
        self.delay_s = float(delay_s)
        self.n_harmonics = int(n_harmonics)
        self.learning_time_s = float(learning_time_s)
        self.max_harmonic_ratio = float(max_harmonic_ratio)

    def harmonics_used(self, mode: ModalParameters) -> np.ndarray:
        """Frequencies [Hz] of the harmonics this controller cancels for a model ``mode``.

        Parameters
        ----------
        mode : ModalParameters
            The (model) mode.

        Returns
        -------
        numpy.ndarray
            Harmonic frequencies [Hz].
        """
        f = np.arange(1, self.n_harmonics + 1) / self.excitation_period_s
        return f[f <= self.max_harmonic_ratio * mode.natural_frequency_hz]

    def loop_radius(self, plant: Sequence[ModalParameters], model: ModalParameters,
                    period_s: float = 0.004) -> float:  # fmt: skip
        """Worst :func:`repetitive_loop_radius` over the used harmonics for a true ``plant``.

        Parameters
        ----------
        plant : sequence of ModalParameters
            The true modes.
        model : ModalParameters
            The controller's model mode.
        period_s : float
            Command period [s].

        Returns
        -------
        float
            Largest spectral radius (< 1: the learning loop converges).
        """
        f = self.harmonics_used(model)
        if f.size == 0:
            return 0.0
        ratio = modal_correction_frf(plant, f) / modal_correction_frf([model], f)
        return max(
            repetitive_loop_radius(r, period_s / self.learning_time_s,
                                   round(self.delay_s / period_s),
                                   round(self.excitation_period_s / period_s))
            for r in ratio
        )  # fmt: skip

    def reset(self, coords, period_s: float, sample_rate_hz: float) -> None:
        fs = float(sample_rate_hz)
        self._dt = 1.0 / fs
        self._every = round(period_s * fs)
        self._delay = round(self.delay_s * fs)
        self._w0 = 2 * math.pi / self.excitation_period_s
        self._window = max(2, round(self.excitation_period_s * fs))
        self._gain = period_s / self.learning_time_s
        hw = np.arange(1, self.n_harmonics + 1) * self._w0
        self._hw = hw
        self._pinv = {}

        def pinv(rows):  # (n_cmd, 2): fn, zeta -> (n_cmd, H) inverse model FRF
            wn = 2 * np.pi * rows[:, :1]
            z = rows[:, 1:2]
            p = wn**2 / (wn**2 - hw**2 + 2j * z * wn * hw)
            return np.where(hw <= self.max_harmonic_ratio * wn, 1.0 / p, 0.0)

        for a, tab in self.modes.items():
            self._pinv[a] = map_rows(tab.at(coords), pinv)
        n_cmd = n_commands(coords) if self._pinv else 0
        self._y = np.zeros(((n_cmd + 2) * self._every, 3))
        self._len = 0
        self._u = np.zeros((self.n_harmonics, 3), complex)

    def command(self, k: int, tracker_m: np.ndarray, force_n: np.ndarray) -> np.ndarray:
        m = tracker_m.shape[0]
        self._y[self._len : self._len + m] = tracker_m
        self._len += m
        i = self._len - 1
        if self._len >= self._window:
            lo = self._len - self._window
            seg = self._y[lo : self._len]
            seg = seg - seg.mean(axis=0)
            tj = np.arange(lo, self._len) * self._dt
            resid = 2.0 / self._window * (np.exp(-1j * np.outer(self._hw, tj)) @ seg)  # (H, 3)
            for a, pinv in self._pinv.items():
                self._u[:, a] -= self._gain * resid[:, a] * pinv[k]
        # The phasors are fixed in absolute time: evaluate them when the correction lands.
        target = (i + self._delay + np.arange(self._every)) * self._dt
        phase = np.exp(1j * np.outer(self._hw, target)).mean(axis=1)  # (H,)
        return np.real(phase @ self._u)


class Combined:
    """Sum of the commands of several controllers (e.g. feedforward + feedback).

    Parameters
    ----------
    *parts
        The controllers (each with ``reset`` and ``command``).
    """

    def __init__(self, *parts):
        if not parts:
            raise ValueError("Combined needs at least one controller")
        self.parts = parts

    def reset(self, coords, period_s: float, sample_rate_hz: float) -> None:
        for p in self.parts:
            p.reset(coords, period_s, sample_rate_hz)

    def command(self, k: int, tracker_m: np.ndarray, force_n: np.ndarray) -> np.ndarray:
        return sum(p.command(k, tracker_m, force_n) for p in self.parts)
