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

import bisect
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .._linalg import solve_dare
from ..modal.parameters import ModalParameters
from .lqr import continuous_model, design_delay_aware_lqr, discretize, spectral_radius

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
    "design_kalman",
    "implemented_loop_matrix",
    "map_rows",
    "n_commands",
]


@dataclass(frozen=True)
class ScheduledTable:
    """Values designed at path distances ``s_m`` (n,), rows ``values`` (n, m); linear lookup.

    A single row (n = 1) is a constant. Outside ``s_m`` the end values are held.

    Attributes
    ----------
    s_m
        (n,) path distances [m].
    values
        (n, m) rows designed there.
    """

    s_m: np.ndarray
    values: np.ndarray

    def __post_init__(self) -> None:
        s = np.atleast_1d(np.asarray(self.s_m, float))
        v = np.asarray(self.values, float)
        v = v.reshape(s.size, -1)
        if s.ndim != 1 or not np.all(np.isfinite(s)) or not np.all(np.isfinite(v)):
            raise ValueError("scheduled table needs finite 1-D s_m [m] and finite values")
        if s.size > 1 and np.any(np.diff(s) <= 0):
            raise ValueError("scheduled table s_m [m] must be strictly increasing")
        object.__setattr__(self, "s_m", s)
        object.__setattr__(self, "values", v)

    @classmethod
    def constant(cls, values) -> ScheduledTable:
        return cls(np.array([0.0]), np.atleast_2d(np.asarray(values, float)))

    def at(self, coords) -> np.ndarray:
        """Rows at the path distances ``coords`` (n,) [m] (first column of (n, 3) poses).

        Parameters
        ----------
        coords : array_like
            (n,) path distances [m] or (n, 3) poses (first column used).

        Returns
        -------
        numpy.ndarray
            (n, m) interpolated rows.
        """
        if isinstance(coords, PathCursor):
            return LiveRows(self, coords)
        c = np.asarray(coords, float)
        s = c if c.ndim == 1 else c[:, 0]
        if self.s_m.size == 1:
            return np.repeat(self.values, s.size, axis=0)
        return np.column_stack(
            [np.interp(s, self.s_m, self.values[:, j]) for j in range(self.values.shape[1])]
        )


class PathCursor:
    """The path distance of the current command instant, for a controller run one step at a time.

    A planned run gives ``reset`` the coordinates of every command instant; a run-time
    controller (:class:`~robovib.control.runtime.RuntimeController`) learns the path distance
    at each step. ``reset(cursor, ...)`` makes every :class:`ScheduledTable` lookup a
    :class:`LiveRows` that reads the row at the cursor's current distance.

    Parameters
    ----------
    capacity
        Most command instants of a run (buffers are sized for it at ``reset``).
    nominal_s_m
        The path distance used where a controller needs one value for the run [m].
    """

    def __init__(self, capacity: int, nominal_s_m: float):
        if int(capacity) < 1 or not math.isfinite(nominal_s_m):
            raise ValueError("a path cursor needs capacity >= 1 and a finite nominal_s_m [m]")
        self.capacity = int(capacity)
        self.nominal_s_m = float(nominal_s_m)
        self.s_m = float(nominal_s_m)
        self.version = 0

    def __len__(self) -> int:
        return self.capacity

    def move_to(self, s_m: float) -> None:
        """Set the path distance of the next command instant.

        Parameters
        ----------
        s_m : float
            Path distance [m].
        """
        self.s_m = float(s_m)
        self.version += 1


class LiveRows:
    """A :class:`ScheduledTable`'s row at a :class:`PathCursor`'s distance (``rows[k]`` of a run).

    ``rows[k]`` (any ``k``) is the linearly interpolated row at the cursor's distance (end
    values held), computed once per cursor move into a buffer; ``rows[k, j]`` one value;
    ``rows[:, j]`` a column view. ``shape`` is (capacity, columns).

    Parameters
    ----------
    table
        The table.
    cursor
        The cursor.
    cols
        Column selection (default all).
    """

    def __init__(self, table: ScheduledTable, cursor: PathCursor, cols=None):
        self.table = table
        self.cursor = cursor
        self._scalar = cols is not None and np.ndim(cols) == 0  # rows[:, j]: rows[k] a number
        self._cols = np.arange(table.values.shape[1]) if cols is None else np.atleast_1d(cols)
        self._values = np.ascontiguousarray(table.values[:, self._cols])
        self._s = table.s_m.tolist()
        self._buf = np.empty(self._values.shape[1])
        self._tmp = np.empty_like(self._buf)
        self._version = -1

    @property
    def shape(self) -> tuple[int, int]:
        return (self.cursor.capacity, self._values.shape[1])

    def row(self) -> np.ndarray:
        """The row at the cursor's distance.

        Returns
        -------
        numpy.ndarray
            (m,) row (a buffer overwritten on the next move).
        """
        if self._version != self.cursor.version:
            self._version = self.cursor.version
            v, s, x = self._values, self._s, self.cursor.s_m
            if len(s) == 1 or x <= s[0]:
                self._buf[:] = v[0]
            elif x >= s[-1]:
                self._buf[:] = v[-1]
            else:
                i = bisect.bisect_right(s, x) - 1
                t = (x - s[i]) / (s[i + 1] - s[i])
                np.multiply(v[i], 1.0 - t, out=self._buf)
                np.multiply(v[i + 1], t, out=self._tmp)
                self._buf += self._tmp
        return self._buf

    def __getitem__(self, key):
        if isinstance(key, tuple):
            k, j = key
            if isinstance(k, slice):
                return LiveRows(self.table, self.cursor, self._cols[j])
            return self.row()[j]
        return self.row()[0] if self._scalar else self.row()


class LiveMap:
    """``fn`` of a :class:`LiveRows`' row, recomputed once per cursor move (``[k]`` as a run's).

    Parameters
    ----------
    rows
        The live rows.
    fn
        Row (m,) -> derived array.
    """

    def __init__(self, rows, fn):
        self.rows = rows
        self.fn = fn
        self._version = -1
        self._value = None

    @property
    def shape(self) -> tuple[int, ...]:
        return (self.rows.cursor.capacity, *np.shape(self[0]))

    def __getitem__(self, k):
        cursor = self.rows.cursor
        if self._version != cursor.version:
            self._version = cursor.version
            self._value = self.fn(self.rows.row())
        return self._value


def map_rows(rows, fn):
    """``fn`` of every row: ``fn(rows)`` for an array (n, m), a :class:`LiveMap` for live rows.

    ``fn`` takes (n, m) rows and returns (n, ...) values row by row (vectorised).

    Parameters
    ----------
    rows : numpy.ndarray or LiveRows or LiveMap
        The rows.
    fn : callable
        (n, m) -> (n, ...).

    Returns
    -------
    numpy.ndarray or LiveMap
        The derived rows.
    """
    if isinstance(rows, LiveRows):
        return LiveMap(rows, lambda r: fn(r[None, :])[0])
    if isinstance(rows, LiveMap):
        return LiveMap(rows.rows, lambda r, f0=rows.fn: fn(f0(r)[None, ...])[0])
    return fn(rows)


def n_commands(coords) -> int:
    """Command instants of a run: ``len(coords)``, or a :class:`PathCursor`'s capacity.

    Parameters
    ----------
    coords : array_like or PathCursor
        The run's coordinates.

    Returns
    -------
    int
        The number of command instants.
    """
    if isinstance(coords, PathCursor):
        return coords.capacity
    c = np.asarray(coords)
    return int(c.shape[0]) if c.ndim else 1


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


@dataclass(frozen=True)
class KalmanDesign:
    """Steady-state Kalman filter of one mode at the sensor rate (state [x, v]).

    ``phi`` (2, 2), ``gamma_u`` (2,) (applied correction [m] -> state), ``gain`` (2,) the
    filter gain ``L`` of the update ``x += L (y - x[0])``, ``p`` the a-priori covariance.

    Attributes
    ----------
    phi
        (2, 2) state transition over one sensor sample.
    gamma_u
        (2,) applied correction [m] -> state.
    gain
        (2,) filter gain ``L``.
    p
        (2, 2) a-priori covariance.
    """

    phi: np.ndarray
    gamma_u: np.ndarray
    gain: np.ndarray
    p: np.ndarray


def design_kalman(
    mode: ModalParameters,
    dt_s: float = 1e-3,
    *,
    force_std_n: float = 20.0,
    tracker_noise_m: float = 2e-6,
    tracker_resolution_m: float = 1e-5,
) -> KalmanDesign:
    """Kalman filter for ``[x, v]`` of ``mode`` from tracker samples every ``dt_s``.

    The unmeasured force is white process noise of std ``force_std_n`` [N] held over each
    sample; the tracker noise variance is ``tracker_noise_m**2 + tracker_resolution_m**2 / 12``
    (quantisation). The steady-state a-priori covariance solves the filter Riccati equation
    (DARE on the dual problem, :func:`robovib._linalg.solve_dare`; the same as python-control
    ``dlqe``, tested).

    Parameters
    ----------
    mode : ModalParameters
        The (model) mode.
    dt_s : float
        Sensor sample period [s].
    force_std_n : float
        Std of the unmeasured force [N] (process noise).
    tracker_noise_m, tracker_resolution_m : float
        Tracker white noise (std) and quantisation [m].

    Returns
    -------
    KalmanDesign
        The steady-state filter.
    """
    a, bu = continuous_model(mode, input="displacement")
    _, bf = continuous_model(mode, input="force")
    phi, gu = discretize(a, bu, dt_s)
    _, gf = discretize(a, bf, dt_s)
    qn = (gf @ gf.T) * force_std_n**2
    rn = np.array([[tracker_noise_m**2 + tracker_resolution_m**2 / 12.0]])
    c = np.array([[1.0, 0.0]])
    p = solve_dare(phi.T, c.T, qn, rn)
    gain = (p @ c.T @ np.linalg.inv(c @ p @ c.T + rn))[:, 0]
    return KalmanDesign(phi, gu[:, 0], gain, p)


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


def implemented_loop_matrix(
    mode: ModalParameters | Sequence[ModalParameters],
    gains: Sequence[float],
    period_s: float = 0.004,
    delay_steps: int = 8,
    *,
    velocity: str = "difference",
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
    n = nm + int(diff) + d
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
    if d == 0:
        big[:nm, :] += bd @ row[None, :]
        return big
    big[:nm, h0 + d - 1] += bd[:, 0]
    big[h0, :] = row
    for i in range(1, d):
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


__all__ += [
    "delay_aware_gains",
    "modal_correction_frf",
    "repetitive_loop_radius",
    "spectral_radius",
]
