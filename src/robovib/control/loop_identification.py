"""Online identification of a harmonic learner's loop (issue 40).

A repetitive learner of the tooth lines (:class:`~robovib.control.adaptive.TrackingRepetitive`)
converges only while each harmonic's loop phase error stays below 90°; an unknown transport
delay ``delta`` turns a harmonic at ``f`` by ``360° f delta`` (±16 ms: ±104° at 18 Hz).
:class:`LoopIdentifier` estimates each harmonic's loop factor from the learner's own
corrections, so the learner can rotate its update by the identified phase.
"""

from __future__ import annotations

import cmath
import math

import numpy as np

__all__ = ["IDENTIFY_EVERY_CYCLES", "IDENTIFY_MEMORY_S", "LoopIdentifier"]

_FIRST = np.array([1, 0, 2, 1, 0, 1])  # z, x, w, z, x, z
_SECOND = np.array([2, 2, 2, 1, 0, 0])  # w, w, w, z, x, x

#: Memory of the online loop identification [s] (time constant of its forgetting).
IDENTIFY_MEMORY_S = 20.0
#: Largest identified phase a pooled fit uses (beyond, a phase may have wrapped).
_MAX_POOL_PHASE = math.radians(170.0)
#: Command cycles between two loop estimates (the sums are updated every cycle; the estimate
#: costs ~30 us; two learners of a loop estimate in different cycles).
IDENTIFY_EVERY_CYCLES = 5


class LoopIdentifier:
    """Each learnt harmonic's loop factor, identified from the learner's own corrections.

    A harmonic learner sends phasors ``U_j`` (one per command cycle); the residual's harmonic
    measured over a DFT window, in command units (``Z = R / P_model``), is the disturbance's
    (``D``) plus the effect of the phasors that acted on that window: ``Z = D + lambda X``
    with ``X`` the mean of those phasors (sent between ``window + delay`` and ``delay`` ago)
    and ``lambda = g P_true(j w) e^{-j w delta} / P_model(j w)``: 1 for a perfect model,
    actuator and delay; its phase is the loop's phase error (``w delta`` for an unknown delay
    ``delta``), its magnitude the gain error.

    ``lambda`` is estimated with an instrumental variable, the phasors one window + delay
    earlier still (``W``): ``lambda = cov(Z, W) / cov(X, W)`` over the cycles seen, with
    exponential forgetting (``forget_cycles``). A least-squares fit on ``X`` itself is biased:
    ``X`` holds the learner's reactions to the noise of earlier, overlapping windows. The
    standard error counts ``cycles_per_window`` consecutive (overlapping) windows as one
    sample. Every :data:`IDENTIFY_EVERY_CYCLES` cycles, where the standard error is below
    ``max_rel_error |lambda|`` (the corrections moved enough against the noise: the first
    learning transient, a diverging harmonic), :attr:`factor` takes the estimate's *phase*;
    elsewhere it keeps its last value (1 at the start). The magnitude is not used: where the
    learner follows a disturbance that changes, ``X`` moves with ``-D`` and the estimate's
    magnitude is biased low (the learner's robust gain covers the gain error instead).

    Parameters
    ----------
    shape
        (harmonics, directions) of the phasors.
    every
        Sensor samples per command cycle.
    delay_samples
        Nominal transport delay [samples].
    longest_window
        Longest DFT window [samples] the learner will use.
    forget_cycles
        Time constant of the forgetting [command cycles] (> 1).
    max_rel_error
        Relative standard error below which an estimate is used (> 0).
    cycles_per_window
        Command cycles per DFT window (>= 1): the correlation length of the residuals.
    offset_cycles
        The estimates run at the cycles ``k`` with ``k % IDENTIFY_EVERY_CYCLES ==
        offset_cycles`` (two learners of one loop estimate in different cycles).
    harmonic_numbers
        None, or the (harmonics,) harmonic numbers ``h`` of the rows (frequency ``h / T``):
        the phases are then also *pooled* per direction. The loop's phase error is mostly
        the unknown delay (``-w delta``, linear in ``h``) and a slowly varying model error,
        so ``arg lambda_h ~ a + b h``, fitted by weighted least squares (weights ``1 /
        rel_error^2``) to every harmonic whose estimate has a relative standard error below
        1 and a phase within ±170°, at least 3 of them. A harmonic whose own estimate is
        not yet good enough takes the fitted phase where the fit's standard error at ``h``
        (scaled up by the fit's reduced chi-square when above 1) is below
        ``max_rel_error``: near a resonance the non-periodic response keeps each harmonic's
        own estimate noisy for a whole cut, while together they fix the delay.
    """

    def __init__(self, shape, every: int, delay_samples: int, longest_window: int, *,
                 forget_cycles: float, max_rel_error: float, cycles_per_window: float,
                 offset_cycles: int = 0, harmonic_numbers=None):  # fmt: skip
        if not (every >= 1 and delay_samples >= 0 and longest_window >= 1 and forget_cycles > 1
                and max_rel_error > 0 and cycles_per_window >= 1):  # fmt: skip
            raise ValueError("every, longest_window >= 1, delay_samples >= 0, forget_cycles > 1, "
                             "max_rel_error > 0, cycles_per_window >= 1")  # fmt: skip
        self._every = int(every)
        self._delay = int(delay_samples)
        q1 = math.ceil((longest_window + delay_samples) / every)
        self._lag_extra = math.ceil(longest_window / every)
        self._ring = 3 * q1 + self._lag_extra + 4
        self._cum = np.zeros((self._ring, *shape), complex)  # cumulative sums of U_j
        self._zero = np.zeros(shape, complex)
        self._k = 0
        self._rho = 1.0 - 1.0 / float(forget_cycles)
        self._max_rel = float(max_rel_error)
        self._ncorr = float(cycles_per_window)
        self._offset = int(offset_cycles) % IDENTIFY_EVERY_CYCLES
        self._n = 0.0
        # running sums of x, z, w, z w*, x w*, |w|^2, |z|^2, |x|^2, z x* (stacked)
        self._acc = np.zeros((9, *shape), complex)
        self._new = np.zeros((9, *shape), complex)
        self._h = None
        if harmonic_numbers is not None:
            h = np.asarray(harmonic_numbers, float)
            if h.shape != (shape[0],) or not np.all(h > 0):
                raise ValueError(f"harmonic_numbers must be {shape[0]} numbers > 0")
            self._h = h[:, None]
            self._hlist = h.tolist()
        self.factor = np.ones(shape, complex)
        self.estimate = np.full(shape, np.nan + 0j)
        self.rel_error = np.full(shape, np.inf)
        #: Where the last estimate took the pooled phase (``harmonic_numbers``).
        self.pooled = np.zeros(shape, bool)

    def _cum_at(self, j: int) -> np.ndarray:
        return self._cum[j % self._ring] if j >= 0 else self._zero

    def observe(self, z: np.ndarray, window: int) -> None:
        """Add one cycle's residual to the fit (before this cycle's phasors are sent).

        Parameters
        ----------
        z : numpy.ndarray
            (harmonics, directions) residual harmonics in command units (``R / P_model``).
        window : int
            Length [samples] of the DFT window they were measured over.
        """
        k = self._k  # this cycle; cycles 0 .. k - 1 were sent
        q0 = self._delay // self._every + 1
        q1 = max(q0, math.ceil((window + self._delay) / self._every))
        span = 1.0 / (q1 - q0 + 1)
        lag = 2 * q1 + self._lag_extra
        new = self._new
        x, zz, w = new[0], new[1], new[2]
        np.subtract(self._cum_at(k - q0), self._cum_at(k - q1 - 1), out=x)
        x *= span
        zz[...] = z
        np.subtract(self._cum_at(k - lag + q1 - q0), self._cum_at(k - lag - 1), out=w)
        w *= span
        wc = np.conj(w)
        np.multiply(zz, wc, out=new[3])
        np.multiply(x, wc, out=new[4])
        np.multiply(w, wc, out=new[5])
        np.multiply(zz, np.conj(zz), out=new[6])
        xc = np.conj(x)
        np.multiply(x, xc, out=new[7])
        np.multiply(zz, xc, out=new[8])
        self._acc *= self._rho
        self._acc += new
        self._n = self._rho * self._n + 1.0
        if k % IDENTIFY_EVERY_CYCLES == self._offset and self._n > 2 * self._ncorr:
            self._estimate()

    def _estimate(self) -> None:
        acc = self._acc
        # centred sums: (z, w), (x, w), (w, w), (z, z), (x, x), (z, x) [conjugate second]
        c = acc[3:] - acc[_FIRST] * np.conj(acc[_SECOND]) * (1.0 / self._n)
        czw, cxw, cww, czz, cxx, czx = c
        den = np.abs(cxw)
        ok = den > 1e-12 * np.abs(acc[7])
        lam = czw / np.where(ok, cxw, 1.0)
        # the variance of z - lam x per cycle, and the instrumental variable's standard error
        res = czz.real - 2 * (lam.conj() * czx).real + (lam * lam.conj()).real * cxx.real
        mag = np.abs(lam)
        # rel^2 = res ncorr cww / (n |cxw|^2 |lam|^2) = res ncorr cww / (n |czw|^2)
        rel2 = res * cww.real * (self._ncorr / self._n) / np.maximum(np.abs(czw) ** 2, 1e-300)
        self.estimate[...] = np.where(ok, lam, np.nan)
        self.rel_error[...] = np.sqrt(np.maximum(rel2, 0.0))
        use = ok & (rel2 < self._max_rel**2) & (mag > 0.25) & (mag < 4.0)
        np.divide(lam, mag, out=self.factor, where=use)
        if self._h is not None:
            self._pool(ok & (mag > 0.25) & (mag < 4.0), use)

    def _pool(self, ok: np.ndarray, own: np.ndarray) -> None:
        """Phases of the harmonics without a good own estimate from ``a + b h`` (see class).

        Plain Python over the few harmonics and directions: ~20 small NumPy calls would cost
        more than the arithmetic (this runs inside the command cycle)."""
        self.pooled[...] = False
        need = ok & ~own
        if not need.any():
            return
        lim = self._max_rel**2
        hs = self._hlist
        for d in np.flatnonzero(need.any(axis=0)).tolist():
            lam = self.estimate[:, d].tolist()
            rel = self.rel_error[:, d].tolist()
            okd = ok[:, d].tolist()
            pts = []
            for i, h in enumerate(hs):
                if okd[i] and rel[i] < 1.0:
                    ph = cmath.phase(lam[i])
                    if abs(ph) < _MAX_POOL_PHASE:
                        pts.append((h, ph, 1.0 / max(rel[i], 0.02) ** 2))
            if len(pts) < 3:
                continue
            s0 = s1 = s2 = t0 = t1 = 0.0
            for h, ph, w in pts:
                s0 += w
                s1 += w * h
                s2 += w * h * h
                t0 += w * ph
                t1 += w * h * ph
            det = s0 * s2 - s1 * s1
            if not det > 1e-12 * s0 * s2:
                continue
            a = (s2 * t0 - s1 * t1) / det
            b = (s0 * t1 - s1 * t0) / det
            chi2 = sum(w * (ph - a - b * h) ** 2 for h, ph, w in pts) / (len(pts) - 2)
            scale = max(chi2, 1.0) / det
            for i in np.flatnonzero(need[:, d]).tolist():
                h = hs[i]
                if (s2 - 2 * s1 * h + s0 * h * h) * scale < lim:
                    self.factor[i, d] = cmath.exp(1j * (a + b * h))
                    self.pooled[i, d] = True

    def sent(self, u: np.ndarray) -> None:
        """Record this cycle's phasors, after the learning update.

        Parameters
        ----------
        u : numpy.ndarray
            (harmonics, directions) phasors of the correction applied this cycle.
        """
        i = self._k % self._ring
        if self._k:
            np.add(self._cum[(self._k - 1) % self._ring], u, out=self._cum[i])
        else:
            self._cum[i] = u
        self._k += 1
