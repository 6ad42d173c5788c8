"""The fade-out guard of the controllers that survive a real cut (issue 41: its own module).

The controllers it guards: :mod:`robovib.control.adaptive`.

* :func:`amplification_test` — is the tracker signal larger than the open-loop estimate by
  something the window resolves?
* :class:`FadeGuard` — fades a controller's correction out, with a logged reason, when the
  force stops being periodic or the tracker signal is no smaller than the vibration the
  pose model says the cut would cause without the correction (a disturbance observer);
  :class:`GuardEvent` records each change.

It follows the ``reset`` / ``command`` protocol of :mod:`robovib.control.controllers`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import signal

from ..modal.parameters import ModalParameters
from .controllers import PathCursor, ScheduledTable, n_commands

__all__ = ["AmplificationTest", "FadeGuard", "GuardEvent", "amplification_test"]


#: The guard's default resolution in standard errors: a window counts as evidence only where
#: the correction's largest possible effect on the RMS exceeds one standard error of the RMS.
GUARD_Z_SCORE = 1.0


@dataclass(frozen=True)
class AmplificationTest:
    """The guard's test of one window: is the tracker signal larger than the open-loop estimate?

    Attributes
    ----------
    ratio
        RMS of the tracker signal over RMS of the open-loop estimate (both mean-removed).
    effect
        RMS of their difference (the correction's response) over RMS of the estimate: the
        largest change of the RMS the correction can make (triangle inequality).
    resolution
        ``z_score`` standard errors of the estimate's RMS over the window,
        ``z_score / sqrt(2 n_effective)``.
    n_effective
        Effective number of independent samples of the estimate's power in the window.
    amplified
        ``ratio > max_ratio`` and ``effect > resolution``.
    """

    ratio: float
    effect: float
    resolution: float
    n_effective: float
    amplified: bool


def amplification_test(y, y_open, *, max_ratio: float = 1.0,
                       z_score: float = GUARD_Z_SCORE) -> AmplificationTest:  # fmt: skip
    """Test whether ``y`` is larger than ``max_ratio`` x ``y_open`` by something the window resolves.

    The correction changes the window's RMS by at most the RMS of its response ``d = y -
    y_open`` (triangle inequality). The window estimates an RMS with a relative standard error
    ``1 / sqrt(2 n_eff)`` (Gaussian signal), ``n_eff = n / tau`` with ``tau = 1 + 2 sum_k rho_k``
    the integrated autocorrelation time of the estimate's power ``|y_open|^2``, summed by Geyer's
    initial positive sequence (Geyer 1992, *Statist. Sci.* 7: pairs ``rho_2m + rho_2m+1`` while
    positive; ``tau >= 1``). A correction whose largest possible effect is below ``z_score``
    standard errors cannot be told from the window's noise, and the window is no evidence
    against it; otherwise the window is amplified when ``RMS(y) > max_ratio RMS(y_open)``. On a
    noise-dominated cut the correction's effect is a fraction of a per cent of the noise and is
    kept; a correction that moves the tool as much as the vibration is judged strictly.

    Parameters
    ----------
    y
        (n,) or (n, m) tracker signal over the window.
    y_open
        The open-loop estimate, same shape.
    max_ratio
        The RMS ratio tested against (> 0; 1: "not reduced").
    z_score
        The resolution in standard errors of the RMS (> 0).

    Returns
    -------
    AmplificationTest

    Raises
    ------
    ValueError
        Mismatched shapes, fewer than 8 samples, non-finite values or bad thresholds.
    """
    a = np.asarray(y, float)
    b = np.asarray(y_open, float)
    if a.shape != b.shape:
        raise ValueError(f"y and y_open must have the same shape, got {a.shape} and {b.shape}")
    if a.ndim == 1:
        a, b = a[:, None], b[:, None]
    n = a.shape[0]
    if a.ndim != 2 or n < 8:
        raise ValueError(f"need (n, m) windows with n >= 8 samples, got shape {a.shape}")
    if not (np.all(np.isfinite(a)) and np.all(np.isfinite(b))):
        raise ValueError("y and y_open must be finite")
    if not (max_ratio > 0 and z_score > 0):
        raise ValueError("max_ratio and z_score must be > 0")
    return _amplification(a, b, float(max_ratio), float(z_score))


def _amplification(a, b, max_ratio: float, z_score: float) -> AmplificationTest:
    """:func:`amplification_test` on checked (n, m) float arrays (the guard's fast path)."""
    n = a.shape[0]
    a = a - a.mean(axis=0)
    b = b - b.mean(axis=0)
    d = a - b
    pb = np.sum(b * b, axis=1)
    var_open = float(np.mean(pb))
    var_y = float(np.sum(a * a)) / n
    var_d = float(np.sum(d * d)) / n
    if var_open == 0:
        amplified = var_y > 0
        return AmplificationTest(math.inf if amplified else 1.0, math.inf if amplified else 0.0,
                                 0.0, float(n), amplified)  # fmt: skip
    r = pb - var_open
    r0 = float(r @ r) / n
    tau = 1.0
    if r0 > 0:
        spec = np.fft.rfft(r, 2 * n)
        rho = np.fft.irfft(spec.real**2 + spec.imag**2, 2 * n)[:n] / (n * r0)
        pairs = rho[0 : n - 1 : 2] + rho[1:n:2]
        stop = np.flatnonzero(pairs <= 0)
        m = int(stop[0]) if stop.size else pairs.size
        tau = max(1.0, 2.0 * float(np.sum(pairs[:m])) - 1.0)
    n_eff = n / tau
    ratio = math.sqrt(var_y / var_open)
    effect = math.sqrt(var_d / var_open)
    resolution = z_score / math.sqrt(2.0 * n_eff)
    return AmplificationTest(ratio, effect, resolution, n_eff,
                             bool(ratio > max_ratio and effect > resolution))  # fmt: skip


@dataclass(frozen=True)
class GuardEvent:
    """A change of the :class:`FadeGuard`'s target: at ``time_s`` [s], to ``target`` (0 or 1).

    Also the record of a harmonic dropped by
    :class:`~robovib.control.adaptive.TrackingRepetitive` (``target`` 0).

    Attributes
    ----------
    time_s
        Time of the change since the start of the run [s].
    target
        The new target of the fade factor (0: correction off, 1: full).
    reason
        Why, in words (with the measured values that triggered it).
    """

    time_s: float
    target: float
    reason: str


class FadeGuard:
    """Fade a controller's correction out when it stops doing good; log why.

    Every ``check_s`` the guard looks at the last ``window_s``:

    * periodicity: the :class:`~robovib.control.adaptive.PeriodTracker`'s autocorrelation of
      the force at its period; below ``min_periodicity`` the force is not periodic and the
      correction is faded out (in again when it recovers above ``min_periodicity + 0.1``);
    * benefit: the tracker signal ``y`` against the open-loop estimate ``y - P u`` (``P`` the
      pose model's correction-to-tip response of each direction, ``u`` the corrections sent,
      ``delay_s`` late). If the RMS of ``y`` exceeds ``max_ratio`` x that of the estimate the
      correction is not reducing the vibration: faded out for good (latched). A window
      counts only where the correction's largest possible effect on the RMS exceeds
      ``z_score`` standard errors of the window's RMS (:func:`amplification_test`): on a cut
      where sensor noise dominates, the correction is far below that and is kept.

    The output is ``scale * inner``, ``scale`` moving toward its target at ``check_s /
    fade_time_s`` per check (the first check after ``warmup_s``). :attr:`events` lists the
    changes with their reasons.

    Parameters
    ----------
    inner
        The guarded controller.
    tracker
        The loop's :class:`~robovib.control.adaptive.PeriodTracker` (fed here too).
    modes
        Direction -> :class:`~robovib.modal.ModalParameters` (or a :class:`ScheduledTable`
        of (fn [Hz], zeta) rows, read at the middle of the run) of the pose model.
    delay_s
        Nominal transport delay [s].
    min_periodicity
        Autocorrelation at the tracked period below which the force counts as not periodic
        and the correction is faded out, in [0, 1).
    max_ratio
        The correction is faded out for good when the tracker signal's RMS exceeds this
        multiple of the open-loop estimate's RMS (> 0) by more than the window's noise.
    z_score
        The resolution of a window in standard errors of its RMS (> 0;
        :data:`GUARD_Z_SCORE`).
    window_s
        Length of the window the RMS values are taken over [s].
    check_s
        Time between two checks [s].
    fade_time_s
        Time of a full fade from 1 to 0 (or back) [s].
    warmup_s
        Time before the first check [s].
    """

    def __init__(
        self,
        inner,
        tracker,
        modes: dict,
        delay_s: float = 0.032,
        *,
        min_periodicity: float = 0.5,
        max_ratio: float = 1.0,
        z_score: float = GUARD_Z_SCORE,
        window_s: float = 0.5,
        check_s: float = 0.1,
        fade_time_s: float = 0.2,
        warmup_s: float = 0.5,
    ):
        if not (0 <= min_periodicity < 1 and max_ratio > 0 and window_s > 0 and check_s > 0
                and z_score > 0):  # fmt: skip
            raise ValueError("0 <= min_periodicity < 1, max_ratio, z_score, window_s, check_s > 0")
        self.inner = inner
        self.tracker = tracker
        self.modes = modes
        self.delay_s = float(delay_s)
        self.min_periodicity = float(min_periodicity)
        self.max_ratio = float(max_ratio)
        self.z_score = float(z_score)
        self.window_s = float(window_s)
        self.check_s = float(check_s)
        self.fade_time_s = float(fade_time_s)
        self.warmup_s = float(warmup_s)

    def reset(self, coords, period_s: float, sample_rate_hz: float) -> None:
        self.inner.reset(coords, period_s, sample_rate_hz)
        fs = float(sample_rate_hz)
        self._fs = fs
        every = round(period_s * fs)
        n_cmd = n_commands(coords)
        n = (n_cmd + 2) * every
        self.tracker.reset(n, fs)
        if isinstance(coords, PathCursor):  # a run-time controller: the path's nominal point
            mid = np.array([coords.nominal_s_m])
        else:
            mid = np.asarray(coords)[n_cmd // 2 : n_cmd // 2 + 1]
        self._filters = {}
        for a, m in self.modes.items():
            if isinstance(m, ScheduledTable):
                fn, z = m.at(mid)[0][:2]
            elif isinstance(m, ModalParameters):
                fn, z = m.natural_frequency_hz, m.damping_ratio
            else:
                fn, z = m
            wn = 2 * math.pi * fn
            b, aa, _ = signal.cont2discrete(([wn**2], [1, 2 * z * wn, wn**2]), 1 / fs, "zoh")
            b = np.atleast_1d(np.squeeze(b))
            self._filters[int(a)] = (b, aa, np.zeros(max(len(aa), len(b)) - 1))
        self._delay = round(self.delay_s * fs)
        self._sent = np.zeros((n + self._delay + every, 3))
        self._y = np.zeros((n, 3))
        self._yol = np.zeros((n, 3))
        self._len = 0
        self._scale = 1.0
        self._target = 1.0
        self._latched = False
        self._next_check = round(self.warmup_s * fs)
        self._every = every
        self._learners = [p for p in getattr(self.inner, "parts", (self.inner,))
                          if hasattr(p, "learning_scale")]  # fmt: skip
        self.events: list[GuardEvent] = []

    def all_events(self) -> list[GuardEvent]:
        """This guard's events and those of the guarded controllers (time order).

        Returns
        -------
        list of GuardEvent
            The events of this guard and of the guarded controller (or of its ``parts``),
            sorted by ``time_s``.
        """
        parts = getattr(self.inner, "parts", (self.inner,))
        inner = [e for p in parts for e in getattr(p, "events", [])]
        return sorted([*self.events, *inner], key=lambda e: e.time_s)

    @property
    def scale(self) -> float:
        """The current fade factor (0: correction off, 1: full)."""
        return self._scale

    def _set_target(self, target: float, reason: str) -> None:
        if target != self._target:
            self._target = target
            self.events.append(GuardEvent(self._len / self._fs, target, reason))

    def command(self, k: int, tracker_m: np.ndarray, force_n: np.ndarray) -> np.ndarray:
        self.tracker.update(k, force_n)
        m = tracker_m.shape[0]
        lo, hi = self._len, self._len + m
        self._y[lo:hi] = tracker_m
        idx = np.arange(lo, hi) - self._delay
        applied = np.where(idx[:, None] >= 0, self._sent[np.maximum(idx, 0)], 0.0)
        yol = tracker_m.copy()
        for a, (b, aa, zi) in self._filters.items():
            yu, zi_new = signal.lfilter(b, aa, applied[:, a], zi=zi)
            self._filters[a] = (b, aa, zi_new)
            yol[:, a] -= yu
        self._yol[lo:hi] = yol
        self._len = hi
        if self._len >= self._next_check:
            self._next_check = self._len + round(self.check_s * self._fs)
            self._check()
        step = self.check_s / self.fade_time_s * self._every / (self.check_s * self._fs)
        self._scale += float(np.clip(self._target - self._scale, -step, step))
        for part in self._learners:  # they learn only as much as their correction is applied
            part.learning_scale = self._scale
        u = self._scale * np.asarray(self.inner.command(k, tracker_m, force_n), float)
        self._sent[self._len - 1 : self._len - 1 + self._every] = u
        return u

    def _check(self) -> None:
        r = self.tracker.correlation
        if self._latched:
            return
        if math.isfinite(r) and r < self.min_periodicity:
            self._set_target(0.0, f"force not periodic: autocorrelation {r:.2f} at the period "
                                  f"< {self.min_periodicity:.2f}")  # fmt: skip
            return
        w = round(self.window_s * self._fs)
        if self._len >= w and self._scale > 0.5:
            seg = self._y[self._len - w : self._len]
            ol = self._yol[self._len - w : self._len]
            test = _amplification(seg, ol, self.max_ratio, self.z_score)
            if test.amplified:
                rms = np.sqrt(np.sum(np.var(seg, axis=0)))
                rms_ol = np.sqrt(np.sum(np.var(ol, axis=0)))
                self._latched = True
                self._set_target(0.0, f"tracker signal not reduced: RMS {rms * 1e3:.4f} mm = "
                                      f"{test.ratio:.4f} x open-loop estimate {rms_ol * 1e3:.4f} mm "
                                      f"> {self.max_ratio:.2f}, the correction's effect "
                                      f"{test.effect:.3f} above the window's resolution "
                                      f"{test.resolution:.3f} ({test.n_effective:.0f} independent samples)")  # fmt: skip
                return
        if math.isfinite(r) and r >= self.min_periodicity + 0.1:
            self._set_target(1.0, f"force periodic again: autocorrelation {r:.2f}")
