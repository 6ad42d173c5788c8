"""Controllers that survive a real cut: period tracking and adaptive harmonics.

The controllers of :mod:`robovib.control.controllers` take the excitation period from the
nominal spindle speed; a real spindle turns a few per cent off it and drifts, and a
feedforward that predicts one tooth period ahead then predicts the wrong force. Here:

* :func:`estimate_period` — the period of a signal near a nominal one: the lag of the largest
  normalised autocorrelation within ``±rel_range`` of the nominal lag, refined by a parabola
  through the peak (sub-sample). The peak value is a periodicity measure (1: exactly periodic,
  ~0: white noise).
* :class:`PeriodTracker` — runs :func:`estimate_period` on the measured force about once per
  excitation period and smooths it; shared by the controllers of one loop.
* :class:`TrackingFeedforward` — :class:`~robovib.control.controllers.ForceFeedforward` with
  the period from the tracker.
* :class:`TrackingRepetitive` — :class:`~robovib.control.controllers.RepetitiveFeedback` whose
  harmonics follow the tracked period (a running phase instead of a fixed ``w0 t``): the
  per-harmonic phasors adapt amplitude and phase from the tracker signal, so the gain and
  phase errors of the actuator and of the model are learnt out.

The fade-out guard that wraps them (:class:`~robovib.control.guard.FadeGuard`) is in
:mod:`robovib.control.guard`.

All follow the ``reset`` / ``command`` protocol of :mod:`robovib.control.controllers`.
"""

from __future__ import annotations

import math

import numpy as np

from .controllers import ForceFeedforward, RepetitiveFeedback, map_rows
from .guard import GuardEvent
from .loop_identification import IDENTIFY_EVERY_CYCLES, IDENTIFY_MEMORY_S, LoopIdentifier

__all__ = [
    "IDENTIFY_MEMORY_S",
    "LoopIdentifier",
    "PeriodTracker",
    "TrackingFeedforward",
    "TrackingRepetitive",
    "estimate_period",
    "robust_learning_scale",
]


def estimate_period(
    x,
    sample_rate_hz: float,
    nominal_s: float,
    *,
    rel_range: float = 0.1,
    window_periods: float = 2.0,
) -> tuple[float, float]:
    """Period [s] of ``x`` near ``nominal_s`` and the normalised autocorrelation at it.

    Parameters
    ----------
    x
        (n,) or (n, m) samples (columns are summed in the correlation); the newest are used.
    sample_rate_hz
        Sample rate [Hz].
    nominal_s
        Expected period [s]; lags within ``nominal_s * (1 ± rel_range)`` are searched.
    rel_range
        Relative search range (0.1: ±10 %).
    window_periods
        Length of the correlated window in nominal periods.

    Returns
    -------
    period_s, correlation
        The refined period [s] and the normalised correlation at the best lag (≤ 1).

    Raises
    ------
    ValueError
        Bad arguments or fewer samples than window + largest lag.
    """
    a = np.asarray(x, float)
    if a.ndim == 1:
        a = a[:, None]
    fs = float(sample_rate_hz)
    if not (fs > 0 and nominal_s > 0 and 0 < rel_range < 1 and window_periods > 0):
        raise ValueError("sample_rate_hz, nominal_s, window_periods > 0 and 0 < rel_range < 1")
    n0 = nominal_s * fs
    lo = max(2, math.floor(n0 * (1 - rel_range)))
    hi = math.ceil(n0 * (1 + rel_range))
    w = max(4, round(window_periods * n0))
    if a.shape[0] < w + hi + 1:
        raise ValueError(f"need at least {w + hi + 1} samples, got {a.shape[0]}")
    a = a[-(w + hi + 1) :]
    a = a - a.mean(axis=0)
    seg = a[-w:]
    e0 = float(np.sum(seg * seg))
    lags = np.arange(lo - 1, hi + 2)
    end = a.shape[0]
    # Windows ending ``lag`` samples before the newest, all lags at once (a strided view).
    view = np.lib.stride_tricks.sliding_window_view(a, w, axis=0)  # (end - w + 1, m, w)
    prev = view[end - w - lags]  # (n_lags, m, w)
    num = np.einsum("lmw,wm->l", prev, seg)
    den = np.sqrt(e0 * np.einsum("lmw,lmw->l", prev, prev))
    r = np.divide(num, den, out=np.zeros(lags.size), where=den > 0)
    j = int(np.argmax(r[1:-1])) + 1
    y0, y1, y2 = r[j - 1], r[j], r[j + 1]
    curv = y0 - 2 * y1 + y2
    off = 0.5 * (y0 - y2) / curv if curv < 0 else 0.0
    off = float(np.clip(off, -0.5, 0.5))
    return (lags[j] + off) / fs, float(y1)


def robust_learning_scale(
    fz_rows,
    harmonic_hz,
    gain: float,
    delay_cycles: float,
    *,
    delay_uncertainty_s: float,
    fn_uncertainty_rel: float = 0.0,
    gain_uncertainty_rel: float = 0.1,
) -> np.ndarray:
    """Per-harmonic factor (0..1) on a phasor learner's gain that keeps it stable over a band.

    The learning loop of one harmonic is a delayed integrator, ``U <- U - g r U(delayed by D
    cycles)`` with ``r = P_true / P_model`` at the harmonic: it converges iff ``g |r| D <
    pi / 2 - |arg r|`` (the continuous-time limit of :func:`repetitive_loop_radius`). Over the
    band (the model's fn within ``± fn_uncertainty_rel``, the transport delay within
    ``± delay_uncertainty_s``, the actuator gain within ``± gain_uncertainty_rel``) the worst
    phase ``phi = max |arg r|`` and magnitude ``max |r|`` give ``g_max = (pi / 2 - phi) /
    (max |r| D)``; the gain used is ``min(gain, g_max / 2)`` (half the phase left over as
    margin: the learner also averages the non-periodic response near a resonance rather than
    chasing it). A harmonic with ``phi >= 0.9 pi / 2`` has no robust gain and gets 0 (not
    learnt).

    Parameters
    ----------
    fz_rows
        (n, 2) model rows (fn [Hz], zeta) along the path; the worst row counts.
    harmonic_hz
        (H,) harmonic frequencies [Hz].
    gain
        The nominal learning gain per command cycle (command period / learning time).
    delay_cycles
        The loop's delay in command cycles (transport delay plus half the DFT window).
    delay_uncertainty_s
        Unknown part of the transport delay [s] (>= 0).
    fn_uncertainty_rel
        Relative uncertainty of the model's natural frequency (>= 0; e.g. 1.96 std / fn).
    gain_uncertainty_rel
        Relative uncertainty of the actuator gain, in [0, 1).

    Returns
    -------
    numpy.ndarray
        (H,) factors in [0, 1] on ``gain``.
    """
    rows = np.atleast_2d(np.asarray(fz_rows, float))
    f = np.asarray(harmonic_hz, float)[None, :]
    if not (delay_uncertainty_s >= 0 and fn_uncertainty_rel >= 0 and 0 <= gain_uncertainty_rel < 1
            and gain > 0 and delay_cycles > 0):  # fmt: skip
        raise ValueError("uncertainties >= 0 (gain one < 1), gain and delay_cycles > 0")

    def frf(fn, z):
        wn = 2 * np.pi * fn
        w = 2 * np.pi * f
        return wn**2 / (wn**2 - w**2 + 2j * z * wn * w)

    fn, z = rows[:, :1], rows[:, 1:2]
    nominal = frf(fn, z)
    phase = np.zeros(f.shape[1])
    mag = np.ones(f.shape[1])
    for scale in (1 - fn_uncertainty_rel, 1 + fn_uncertainty_rel):
        r = frf(fn * scale, z) / nominal
        phase = np.maximum(phase, np.max(np.abs(np.angle(r)), axis=0))
        mag = np.maximum(mag, np.max(np.abs(r), axis=0))
    phase = phase + 2 * np.pi * f[0] * delay_uncertainty_s
    mag = mag * (1 + gain_uncertainty_rel)
    left = np.pi / 2 - phase
    g_max = np.where(left > 0.1 * np.pi / 2, left / (mag * delay_cycles), 0.0)
    return np.clip(0.5 * g_max / gain, 0.0, 1.0)


class PeriodTracker:
    """Online excitation period from the measured force (shared by the controllers of a loop).

    Every ``update_periods`` excitation periods :func:`estimate_period` runs on the latest force
    samples; the estimate is smoothed (``smoothing``: weight of the new value) and kept within
    ``rel_range`` of the nominal period. ``correlation`` is the latest periodicity measure
    (NaN until the first estimate). Feed it once per command instant with :meth:`update`
    (repeated calls for the same ``k`` are ignored).

    Parameters
    ----------
    nominal_period_s
        Nominal excitation period [s] (tooth period ``60 / (rpm * teeth)``); the starting
        estimate and the centre of the search range.
    rel_range
        Relative search range of each estimate around the nominal period (0.1: ±10 %).
    window_periods
        Length of the correlated window in nominal periods.
    update_periods
        Nominal periods between two estimates.
    smoothing
        Weight of a new estimate in the smoothed period, in (0, 1] (1: no smoothing).
    lag_periods
        Whole number of periods the correlated windows lie apart (>= 1): the estimate is of
        ``lag_periods`` periods at once, so a lag error of one sample is ``lag_periods``
        times smaller on the period. The learners' phase is the integral of the period, so
        its wander is the period error's low-frequency part, which smoothing does not
        reduce and a longer lag does. The search range stays ``rel_range`` of the period
        (within it no other multiple of the period lies while ``rel_range < 1 / (2
        lag_periods)``).
    """

    def __init__(
        self,
        nominal_period_s: float,
        *,
        rel_range: float = 0.1,
        window_periods: float = 2.0,
        update_periods: float = 1.0,
        smoothing: float = 0.5,
        lag_periods: int = 1,
    ):
        if not (math.isfinite(nominal_period_s) and nominal_period_s > 0):
            raise ValueError(f"nominal_period_s must be > 0 [s], got {nominal_period_s!r}")
        if not 0 < smoothing <= 1:
            raise ValueError("smoothing must lie in (0, 1]")
        self.nominal_period_s = float(nominal_period_s)
        self.rel_range = float(rel_range)
        self.window_periods = float(window_periods)
        self.update_periods = float(update_periods)
        self.smoothing = float(smoothing)
        lag = int(lag_periods)
        if lag != lag_periods or lag < 1 or not rel_range < 1 / (2 * lag):
            raise ValueError("lag_periods must be a whole number >= 1 with rel_range < "
                             "1 / (2 lag_periods)")  # fmt: skip
        self.lag_periods = lag

    def reset(self, n_samples: int, sample_rate_hz: float) -> None:
        self._fs = float(sample_rate_hz)
        self._buf = np.zeros((int(n_samples), 3))
        self._len = 0
        self._last_k = -1
        self._next = 0
        self.period_s = self.nominal_period_s
        self.correlation = math.nan
        # (time [s], period [s], corr) of every estimate, preallocated: no growth per step
        n0 = self.nominal_period_s * self._fs
        every = max(1, round(self.update_periods * n0))
        self._hist = np.zeros((int(n_samples) // every + 2, 3))
        self._n_hist = 0

    @property
    def history(self) -> list[tuple[float, float, float]]:
        """Every estimate so far: (time [s], smoothed period [s], correlation)."""
        return [tuple(map(float, row)) for row in self._hist[: self._n_hist]]

    def update(self, k: int, force_n: np.ndarray) -> None:
        if k <= self._last_k:
            return
        self._last_k = k
        m = force_n.shape[0]
        self._buf[self._len : self._len + m] = force_n
        self._len += m
        n0 = self.nominal_period_s * self._fs
        lag = self.lag_periods
        need = (
            round(self.window_periods * n0)
            + math.ceil(lag * n0 * (1 + self.rel_range))
            + 1
            + (lag > 1)
        )  # one sample of rounding margin for a longer lag
        if self._len < need or self._len < self._next:
            return
        self._next = self._len + round(self.update_periods * n0)
        p, r = estimate_period(self._buf[: self._len], self._fs, lag * self.nominal_period_s,
                               rel_range=self.rel_range,
                               window_periods=self.window_periods / lag)  # fmt: skip
        p /= lag
        self.correlation = r
        if r > 0.3:  # only a periodic signal moves the estimate
            self.period_s += self.smoothing * (p - self.period_s)
        if self._n_hist < self._hist.shape[0]:
            self._hist[self._n_hist] = (self._len / self._fs, self.period_s, r)
            self._n_hist += 1


class TrackingFeedforward(ForceFeedforward):
    """:class:`~robovib.control.controllers.ForceFeedforward` on a :class:`PeriodTracker`'s period.

    Parameters
    ----------
    stiffness
        Direction -> static stiffness [N/m] (constant or a 1-column :class:`ScheduledTable`
        along the path), from the pose model.
    tracker
        The loop's :class:`PeriodTracker`; its nominal period is the initial excitation period
        and its running estimate the period of the prediction.
    delay_s
        Nominal transport delay [s] of the command channel.
    **kwargs
        Further options of :class:`~robovib.control.controllers.ForceFeedforward`
        (``n_periods``, ``include_mean``).
    """

    def __init__(self, stiffness, tracker: PeriodTracker, delay_s: float = 0.032, **kwargs):
        super().__init__(stiffness, tracker.nominal_period_s, delay_s, **kwargs)
        self.tracker = tracker

    def reset(self, coords, period_s: float, sample_rate_hz: float) -> None:
        super().reset(coords, period_s, sample_rate_hz)
        self._fs = float(sample_rate_hz)
        self.tracker.reset(self._buf.shape[0], sample_rate_hz)  # before any update: harmless

    def command(self, k: int, tracker_m: np.ndarray, force_n: np.ndarray) -> np.ndarray:
        self.tracker.update(k, force_n)
        self._n = self.tracker.period_s * self._fs
        self._p0 = max(1, math.ceil((self._delay + self._every) / self._n))
        return super().command(k, tracker_m, force_n)


class TrackingRepetitive(RepetitiveFeedback):
    """:class:`~robovib.control.controllers.RepetitiveFeedback` on the tracked period.

    The harmonics are those of a running phase ``theta`` advanced every sample by ``2 pi dt /
    T_est`` (``T_est`` from the :class:`PeriodTracker`); the residual's harmonics are the DFT of
    the last estimated period against ``theta`` and the correction is evaluated at the phase the
    correction will land at. The phasors therefore stay put when the spindle is off its nominal
    speed, and learn the amplitude and phase errors of the model, the actuator and the delay.

    A harmonic whose learning diverges (a delay or model error turning its loop phase past
    90°) is dropped: each harmonic's residual magnitude is smoothed over ``learning_time_s``
    and, once it exceeds ``divergence_ratio`` x its value in the first window (the open-loop
    residual: the largest over the first 2 learning times), its phasor is zeroed and the
    harmonic left alone for the rest of the run (:attr:`events` says which and when).

    Parameters
    ----------
    modes
        Direction -> :class:`ScheduledTable` with columns (fn [Hz], zeta) along the path, from
        the pose model.
    tracker
        The loop's :class:`PeriodTracker`; its nominal period is the initial excitation period
        and its running estimate advances the phase of the harmonics.
    delay_s
        Nominal transport delay [s] of the command channel.
    divergence_ratio
        A harmonic whose smoothed residual magnitude exceeds this multiple of its open-loop
        value is dropped (> 0; 1.2: 20 % above).
    divergence_test
        ``"residual"``: the residual alone decides (above). ``"correction"``: the harmonic is
        dropped only when, in addition, the tip motion its learnt correction makes through the
        model (``|P_model U_h|``) exceeds ``divergence_ratio`` x the open-loop residual: a
        diverging learner overshoots the disturbance it cancels, while a residual that grows
        from unlearnable (non-periodic) response near a resonance leaves the correction at the
        disturbance's size and the harmonic is kept.
    delay_uncertainty_s
        None (off), or the unknown part of the transport delay [s]: each harmonic's gain is
        then made robust over that delay, ``fn_uncertainty_rel`` and ``gain_uncertainty_rel``
        (:func:`robust_learning_scale`); a harmonic no gain keeps stable is not learnt.
    fn_uncertainty_rel, gain_uncertainty_rel
        Relative uncertainties of the model's fn and of the actuator gain (with
        ``delay_uncertainty_s``).
    model_at_tracked_period
        Evaluate the inverse model FRF ``1 / P`` at the harmonics of the *tracked* period
        (``True``) rather than the nominal one: near a resonance a few per cent of spindle-speed
        error turn the model's phase by tens of degrees (``d phase / d (f / fn) = 1 / zeta``
        there).
    period_multiple
        The learnt period in tracked periods (integer >= 1): 1 learns the tooth-passing lines;
        the number of teeth learns over one spindle revolution (the runout lines).
    identify_loop
        Identify each harmonic's loop factor online and learn with it (see
        :class:`LoopIdentifier`): the residual's harmonic (in command units, ``R / P_model``)
        against the mean of the phasor that acted on its DFT window, ``Z = D + lambda X``,
        by least squares with forgetting; ``lambda = g P_true e^{-j w delta} / P_model``
        holds the actuator gain, the unknown delay ``delta`` and the model's error at that
        harmonic. Once ``lambda`` is known to ``identify_rel_error`` (its standard error
        over its magnitude) the update divides by it: the learning then converges whatever
        the delay error (a ±16 ms error turns an 18 Hz harmonic's loop by ±104°, past the
        90° a fixed learner survives).
    identify_rel_error
        Relative standard error below which an identified loop factor is used (> 0).
    pool_loop_phase
        With ``identify_loop``: a harmonic whose own loop estimate is still too noisy takes
        the phase of a straight line in the harmonic number fitted to the others of its
        direction (the delay is common to them; ``LoopIdentifier(harmonic_numbers=...)``).
    pause_when_faded
        Learn only as much as the correction is applied: a guard (``FadeGuard``) that fades
        the correction to ``s`` sets :attr:`learning_scale` to ``s`` and the update is
        scaled by it (no wind-up while the correction is off: the residual then is the open
        loop's, and a learner that kept integrating it would overshoot when faded back in).
    **kwargs
        Further options of :class:`~robovib.control.controllers.RepetitiveFeedback`
        (``n_harmonics``, ``learning_time_s``, ``max_harmonic_ratio``).
    """

    def __init__(
        self,
        modes,
        tracker: PeriodTracker,
        delay_s: float = 0.032,
        *,
        divergence_ratio: float = 1.2,
        period_multiple: int = 1,
        divergence_test: str = "residual",
        model_at_tracked_period: bool = False,
        delay_uncertainty_s: float | None = None,
        fn_uncertainty_rel: float = 0.0,
        gain_uncertainty_rel: float = 0.1,
        identify_loop: bool = False,
        identify_rel_error: float = 0.2,
        pause_when_faded: bool = False,
        pool_loop_phase: bool = False,
        **kwargs,
    ):
        m = int(period_multiple)
        if m < 1 or m != period_multiple:
            raise ValueError("period_multiple must be an integer >= 1")
        super().__init__(modes, m * tracker.nominal_period_s, delay_s, **kwargs)
        if not divergence_ratio > 0:
            raise ValueError("divergence_ratio must be > 0")
        self.tracker = tracker
        self.divergence_ratio = float(divergence_ratio)
        if divergence_test not in ("residual", "correction"):
            raise ValueError(
                f"divergence_test must be 'residual' or 'correction', got {divergence_test!r}"
            )
        self.divergence_test = divergence_test
        self.model_at_tracked_period = bool(model_at_tracked_period)
        self.period_multiple = m
        self.delay_uncertainty_s = (
            None if delay_uncertainty_s is None else float(delay_uncertainty_s)
        )
        self.fn_uncertainty_rel = float(fn_uncertainty_rel)
        self.gain_uncertainty_rel = float(gain_uncertainty_rel)
        if not identify_rel_error > 0:
            raise ValueError("identify_rel_error must be > 0")
        self.identify_loop = bool(identify_loop)
        self.identify_rel_error = float(identify_rel_error)
        self.pause_when_faded = bool(pause_when_faded)
        self.pool_loop_phase = bool(pool_loop_phase)
        self.learning_scale = 1.0

    def reset(self, coords, period_s: float, sample_rate_hz: float) -> None:
        super().reset(coords, period_s, sample_rate_hz)
        n = self._y.shape[0]
        self.tracker.reset(n, sample_rate_hz)
        self._theta = np.zeros(n)
        self._phase = 0.0
        self._h = np.arange(1, self.n_harmonics + 1)
        self._eth = np.zeros((self.n_harmonics, n), complex)
        self._fs = float(sample_rate_hz)
        if self.period_multiple > 1:  # the tracked period's own harmonics are left to others
            own = self._h % self.period_multiple == 0
            for a in self._pinv:
                self._pinv[a] = map_rows(self._pinv[a], lambda p: np.where(own, 0.0, p))
        self._on = {a: np.ones(self.n_harmonics, bool) for a in self._pinv}
        if self.model_at_tracked_period:
            self._fz_rows = {a: tab.at(coords) for a, tab in self.modes.items()}
            self._own = (self._h % self.period_multiple == 0) if self.period_multiple > 1 else None
        self._gscale = {a: np.ones(self.n_harmonics) for a in self._pinv}
        if self.delay_uncertainty_s is not None:
            loop_delay = (self._delay + (self._window - 1) / 2) / self._every  # command cycles
            for a, tab in self.modes.items():
                self._gscale[a] = robust_learning_scale(
                    tab.values, self._hw / (2 * math.pi), self._gain, loop_delay,
                    delay_uncertainty_s=self.delay_uncertainty_s,
                    fn_uncertainty_rel=self.fn_uncertainty_rel,
                    gain_uncertainty_rel=self.gain_uncertainty_rel)  # fmt: skip
        self._mag = None
        self._mag0 = None
        self.events: list[GuardEvent] = []
        self.learning_scale = 1.0
        self._ident = None
        if self.identify_loop:
            # the longest window (tracked period within the tracker's range) + the delay
            longest = math.ceil(self.period_multiple * self.tracker.nominal_period_s
                                * (1 + self.tracker.rel_range) * self._fs)  # fmt: skip
            self._ident = LoopIdentifier(
                (self.n_harmonics, 3), self._every, self._delay, longest,
                forget_cycles=IDENTIFY_MEMORY_S / (self._every * self._dt),
                max_rel_error=self.identify_rel_error,
                cycles_per_window=longest / self._every,
                offset_cycles=(self.period_multiple - 1) * IDENTIFY_EVERY_CYCLES // 2,
                harmonic_numbers=self._h if self.pool_loop_phase else None)  # fmt: skip
            self._z = np.zeros((self.n_harmonics, 3), complex)
            self._step = np.zeros((self.n_harmonics, 3), complex)

    def _pinv_at(self, a: int, k: int, period: float) -> np.ndarray:
        """Inverse model FRF at the harmonics of the tracked ``period`` (not the nominal)."""
        fn, z = self._fz_rows[a][k][:2]
        wn = 2 * math.pi * fn
        hw = self._h * (2 * math.pi / period)
        p = wn**2 / (wn**2 - hw**2 + 2j * z * wn * hw)
        out = np.where(hw <= self.max_harmonic_ratio * wn, 1.0 / p, 0.0)
        if self._own is not None:
            out[self._own] = 0.0
        return out

    def command(self, k: int, tracker_m: np.ndarray, force_n: np.ndarray) -> np.ndarray:
        self.tracker.update(k, force_n)
        period = self.period_multiple * self.tracker.period_s
        w_dt = 2 * math.pi * self._dt / period
        m = tracker_m.shape[0]
        new = self._phase + w_dt * np.arange(1, m + 1)
        self._theta[self._len : self._len + m] = new
        # each sample's harmonic phasors, computed once (the DFT below slides over them)
        self._eth[:, self._len : self._len + m] = np.exp(-1j * np.outer(self._h, new))
        self._phase += w_dt * m
        self._y[self._len : self._len + m] = tracker_m
        self._len += m
        window = max(2, round(period * self._fs))
        if self._len >= window:
            lo = self._len - window
            seg = self._y[lo : self._len]
            seg = seg - seg.mean(axis=0)
            resid = 2.0 / window * (self._eth[:, lo : self._len] @ seg)
            mag = np.abs(resid)
            if self._mag is None:
                self._mag0 = mag.copy()
                self._mag = mag.copy()
                self._ref_until = self._len + round(2 * self.learning_time_s * self._fs)
            else:
                self._mag += self._gain * (mag - self._mag)
            if self._len <= self._ref_until:  # the open-loop reference: first 2 learning times
                self._mag0 = np.maximum(self._mag0, mag)
            for a, pinv in self._pinv.items():
                bad = self._on[a] & (self._mag[:, a] > self.divergence_ratio * self._mag0[:, a])
                row = self._pinv_at(a, k, period) if self.model_at_tracked_period else pinv[k]
                bad &= row != 0
                if self.divergence_test == "correction" and bad.any():
                    tip = np.abs(self._u[:, a]) / np.where(row != 0, np.abs(row), np.inf)
                    bad &= tip > self.divergence_ratio * self._mag0[:, a]
                for h in np.flatnonzero(bad):
                    self._on[a][h] = False
                    self._u[h, a] = 0.0
                    self.events.append(GuardEvent(self._len / self._fs, 0.0,
                        f"direction {a} harmonic {h + 1}: learning diverged (residual "
                        f"{self._mag[h, a] * 1e3:.4f} mm > {self.divergence_ratio:g} x open loop "
                        f"{self._mag0[h, a] * 1e3:.4f} mm), dropped"))  # fmt: skip
                if self._ident is None:
                    g = self._gain * (self.learning_scale if self.pause_when_faded else 1.0)
                    self._u[:, a] -= g * self._gscale[a] * resid[:, a] * row * self._on[a]
                else:
                    np.multiply(resid[:, a], row, out=self._z[:, a])
                    self._step[:, a] = self._gscale[a] * self._on[a]
        if self._ident is not None:
            if self._len >= window:
                self._ident.observe(self._z, window)
                self._step *= self._z
                self._step /= self._ident.factor
                self._step *= self._gain * (self.learning_scale if self.pause_when_faded else 1.0)
                self._u -= self._step
            self._ident.sent(self._u * self.learning_scale)
        target = self._phase + w_dt * (self._delay + np.arange(self._every))
        phase = np.exp(1j * np.outer(self._h, target)).mean(axis=1)
        return np.real(phase @ self._u)
