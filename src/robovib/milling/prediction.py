"""Tool-tip vibration during milling at a pose (thesis §3.5.2-3.5.3, Eq. 17).

Per direction (X, Y, Z uncoupled, as the thesis assumes) the tool tip is
``M x'' + C x' + K x = F`` with M, C, K of the pose's dominant mode (from the GP's predicted fn,
k, c: ``M = k / wn^2``) — or any sum of modes, or a measured/predicted multi-bin FRF.

The response to a force record is computed with the convolution theorem: ``X = H(f) F(f)``
on an FFT grid zero-padded to at least the record length plus ten decay times of the
slowest mode, so the circular convolution equals the linear one (no wrap-around); the mean
(static) part is carried by ``H(0) = 1/k`` like any other bin, and the system starts at rest.
This is the ODE solution from rest for the band-limited force through the samples (tested
against :func:`scipy.signal.lsim` with linear interpolation; a zero-order-hold input would lag
it by half a sample).

Summary figures as in Figs. 16-17: the mean deflection, and the average over spindle
revolutions of the peak-to-valley displacement within each revolution.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..frf.core import FRF
from ..modal.parameters import ModalParameters

__all__ = [
    "VibrationSummary",
    "convolve_force",
    "peak_to_valley_per_revolution",
    "resample_force",
    "summarise_vibration",
]


def resample_force(time_s, force, sample_rate_hz: float) -> np.ndarray:
    """Resample a uniformly sampled force record (n, ...) to ``sample_rate_hz``.

    Polyphase filtering (:func:`scipy.signal.resample_poly`) with a rational approximation of
    the rate ratio; raises if the time axis is not uniform (nothing is silently interpolated).

    Parameters
    ----------
    time_s : array_like
        (n,) uniform times [s].
    force : array_like
        (n, ...) force [N].
    sample_rate_hz : float
        Target rate [Hz].

    Returns
    -------
    numpy.ndarray
        The resampled force.
    """
    from fractions import Fraction

    from scipy import signal

    t = np.asarray(time_s, float)
    f = np.asarray(force, float)
    if t.ndim != 1 or f.shape[0] != t.size:
        raise ValueError(f"time ({t.shape}) and force ({f.shape}) lengths differ")
    dt = np.diff(t)
    if np.any(dt <= 0) or np.ptp(dt) > 1e-6 * np.mean(dt):
        raise ValueError("force record is not uniformly sampled")
    fs_in = 1.0 / np.mean(dt)
    ratio = Fraction(sample_rate_hz / fs_in).limit_denominator(1000)
    if abs(float(ratio) - sample_rate_hz / fs_in) > 1e-6 * sample_rate_hz / fs_in:
        raise ValueError(
            f"cannot resample {fs_in:g} Hz to {sample_rate_hz:g} Hz with a rational ratio"
        )
    if ratio == 1:
        return f.copy()
    return signal.resample_poly(f, ratio.numerator, ratio.denominator, axis=0)


def _padded_length(n: int, modes: Sequence[ModalParameters], sample_rate_hz: float) -> int:
    settle = max((10.0 / max(m.damping_ratio * m.omega_n, 1e-9) for m in modes), default=0.0)
    need = n + math.ceil(min(settle, 600.0) * sample_rate_hz)
    return 1 << math.ceil(math.log2(max(need, 2)))


def convolve_force(
    force,
    sample_rate_hz: float,
    modes: Sequence[ModalParameters] | None = None,
    frf: FRF | None = None,
) -> np.ndarray:
    """Displacement [m] (n,) of a tool tip under ``force`` [N] (n,), starting from rest.

    Give either ``modes`` (sum of modal receptances; exact) or a compliance ``frf`` (its
    complex compliance is interpolated onto the FFT grid; bins above its range get zero,
    below its first bin its first value — prefer FRFs that start near 0 Hz).

    Parameters
    ----------
    force : array_like
        (n,) force [N].
    sample_rate_hz : float
        Sample rate [Hz].
    modes : sequence of ModalParameters, optional
        Tool-tip modes.
    frf : FRF, optional
        Compliance FRF instead of ``modes``.

    Returns
    -------
    numpy.ndarray
        (n,) displacement [m].
    """
    f = np.asarray(force, float)
    if f.ndim != 1 or not np.all(np.isfinite(f)):
        raise ValueError("force must be a finite 1-D record")
    if (modes is None) == (frf is None):
        raise ValueError("give exactly one of modes or frf")
    if not sample_rate_hz > 0:
        raise ValueError(f"sample_rate_hz must be positive, got {sample_rate_hz!r}")
    n = f.size
    if modes is not None:
        n_fft = _padded_length(n, modes, sample_rate_hz)
        freq = np.fft.rfftfreq(n_fft, 1.0 / sample_rate_hz)
        h = np.sum([m.compliance(freq) for m in modes], axis=0)
    else:
        if frf.quantity != "compliance":
            raise ValueError("frf must be a compliance FRF (use FRF.to_compliance())")
        n_fft = 1 << math.ceil(math.log2(max(4 * n, 2)))
        freq = np.fft.rfftfreq(n_fft, 1.0 / sample_rate_hz)
        h = frf.interpolate(freq, outside=("hold", "zero")).values.copy()
        h[0] = h[0].real
    x = np.fft.irfft(np.fft.rfft(f, n_fft) * h, n_fft)[:n]
    return x


def peak_to_valley_per_revolution(
    displacement, sample_rate_hz: float, spindle_rpm: float
) -> np.ndarray:
    """Peak-to-valley displacement in each whole spindle revolution (n_rev,).

    Parameters
    ----------
    displacement : array_like
        (n,) displacement [m].
    sample_rate_hz : float
        Sample rate [Hz].
    spindle_rpm : float
        Spindle speed [rpm].

    Returns
    -------
    numpy.ndarray
        (n_rev,) peak-to-valley [m].
    """
    x = np.asarray(displacement, float)
    if not spindle_rpm > 0:
        raise ValueError(f"spindle_rpm must be positive, got {spindle_rpm!r}")
    per_rev = sample_rate_hz * 60.0 / spindle_rpm
    n_rev = int(x.size // per_rev)
    if n_rev < 1:
        raise ValueError("the record is shorter than one spindle revolution")
    edges = np.round(np.arange(n_rev + 1) * per_rev).astype(int)
    if np.all(np.diff(edges) > 0):  # one reduction per revolution, vectorised
        whole = x[: edges[-1]]
        return np.maximum.reduceat(whole, edges[:-1]) - np.minimum.reduceat(whole, edges[:-1])
    return np.array([np.ptp(x[edges[i] : edges[i + 1]]) for i in range(n_rev)])


@dataclass(frozen=True)
class VibrationSummary:
    """Mean deflection and per-revolution peak-to-valley of a tool-tip displacement.

    Attributes
    ----------
    mean_deflection_m
        Mean displacement [m].
    peak_to_valley_m, peak_to_valley_std_m
        Mean and std over the revolutions of the peak-to-valley displacement [m].
    """

    mean_deflection_m: float
    peak_to_valley_m: float  #: average over revolutions
    peak_to_valley_std_m: float  #: spread over revolutions


def summarise_vibration(
    displacement, sample_rate_hz: float, spindle_rpm: float, skip_s: float = 0.0
) -> VibrationSummary:
    """Mean deflection and average per-revolution peak-to-valley (after ``skip_s`` of transient).

    Parameters
    ----------
    displacement : array_like
        (n,) displacement [m].
    sample_rate_hz : float
        Sample rate [Hz].
    spindle_rpm : float
        Spindle speed [rpm].
    skip_s : float
        Transient left out [s].

    Returns
    -------
    VibrationSummary
        Mean deflection and peak-to-valley.
    """
    x = np.asarray(displacement, float)[round(skip_s * sample_rate_hz) :]
    pv = peak_to_valley_per_revolution(x, sample_rate_hz, spindle_rpm)
    return VibrationSummary(float(np.mean(x)), float(np.mean(pv)), float(np.std(pv)))
