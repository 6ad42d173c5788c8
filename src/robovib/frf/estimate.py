"""FRF estimation from force and response time series by Welch averaging (thesis Eq. 3-5).

H1 = Gxy / Gxx is unbiased by noise on the response (output) channel, H2 = Gyy / Gyx by noise
on the force (input) channel; the ordinary coherence gamma^2 = |Gxy|^2 / (Gxx Gyy) = H1 / H2.
The spectral densities come from :func:`scipy.signal.csd` / :func:`scipy.signal.welch`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import signal

from .._checks import check_choice, check_number
from .core import FRF, RESPONSE_TO_QUANTITY

__all__ = ["SpectralDensities", "estimate_frf", "spectral_densities"]


@dataclass(frozen=True)
class SpectralDensities:
    """Averaged one-sided auto/cross spectral densities on a common frequency axis.

    Attributes
    ----------
    frequency_hz
        (n,) frequency axis [Hz].
    gxx, gyy
        (n,) force and response auto-spectra.
    gxy
        (n,) cross-spectrum ``conj(X) Y``.
    n_averages
        Number of segments averaged.
    """

    frequency_hz: np.ndarray
    gxx: np.ndarray  #: force auto-spectrum
    gyy: np.ndarray  #: response auto-spectrum
    gxy: np.ndarray  #: cross-spectrum conj(X) Y
    n_averages: int

    @property
    def h1(self) -> np.ndarray:
        return self.gxy / self.gxx

    @property
    def h2(self) -> np.ndarray:
        return self.gyy / np.conj(self.gxy)

    @property
    def coherence(self) -> np.ndarray:
        return np.abs(self.gxy) ** 2 / (self.gxx * self.gyy)


def _check_pair(force, response, name_f="force", name_r="response"):
    force = np.asarray(force, float)
    response = np.asarray(response, float)
    if force.ndim != 1 or response.ndim != 1:
        raise ValueError(
            f"{name_f} and {name_r} must be 1-D time series, got {force.shape} and {response.shape}"
        )
    if force.shape != response.shape:
        raise ValueError(
            f"{name_f} and {name_r} have mismatched lengths: {force.size} vs {response.size} samples"
        )
    if not (np.all(np.isfinite(force)) and np.all(np.isfinite(response))):
        raise ValueError(f"{name_f} or {name_r} contains NaN or inf")
    return force, response


def spectral_densities(
    force,
    response,
    sample_rate_hz: float,
    *,
    nperseg: int | None = None,
    window: str | tuple = "hann",
    noverlap: int | None = None,
) -> SpectralDensities:
    """Welch estimates of Gxx, Gyy and Gxy of one pair of equally sampled records.

    Parameters
    ----------
    force, response : array_like
        (n,) equally sampled records (force [N], response in SI).
    sample_rate_hz : float
        Sample rate [Hz].
    nperseg : int, optional
        Segment length (default: the whole record, one segment).
    window : str or tuple
        SciPy window of each segment.
    noverlap : int, optional
        Overlap of segments (default: half a segment).

    Returns
    -------
    SpectralDensities
        Gxx, Gyy, Gxy and the number of averages.
    """
    force, response = _check_pair(force, response)
    fs = float(sample_rate_hz)
    if not np.isfinite(fs) or fs <= 0:
        raise ValueError(f"sample_rate_hz must be positive, got {sample_rate_hz!r}")
    if np.all(force == 0):
        raise ValueError("the force signal is identically zero: no excitation, no FRF")
    nper = force.size if nperseg is None else int(nperseg)
    if nper > force.size:
        raise ValueError(f"nperseg={nper} exceeds the record length ({force.size} samples)")
    kw = dict(fs=fs, nperseg=nper, window=window, noverlap=noverlap, detrend=False)
    f, gxx = signal.welch(force, **kw)
    _, gyy = signal.welch(response, **kw)
    _, gxy = signal.csd(force, response, **kw)
    step = nper - (nper // 2 if noverlap is None else int(noverlap))
    n_avg = 1 + (force.size - nper) // max(step, 1)
    return SpectralDensities(f, gxx, gyy, gxy, n_avg)


def estimate_frf(
    force,
    response,
    sample_rate_hz: float,
    *,
    response_quantity: str = "acceleration",
    estimator: str = "H1",
    nperseg: int | None = None,
    window: str | tuple = "hann",
    noverlap: int | None = None,
    f_max_hz: float | None = None,
    direction: str | None = None,
    pose: tuple[float, ...] | None = None,
    source: str = "EMA",
) -> FRF:
    """FRF of a continuous force/response record by Welch averaging (Eq. 5).

    Parameters
    ----------
    force, response
        Equally sampled 1-D records [N] and [m, m/s or m/s²].
    sample_rate_hz
        Common sample rate; resample first if the channels differ.
    response_quantity
        ``"displacement"``, ``"velocity"`` or ``"acceleration"``: sets the FRF quantity
        (compliance, mobility, accelerance). Use :meth:`FRF.to_compliance` to convert.
    estimator
        ``"H1"`` (noise on the response) or ``"H2"`` (noise on the force).
    nperseg, window, noverlap
        Welch segmentation (SciPy's meaning); default: one Hann segment over the record.
    f_max_hz
        Keep bins up to this frequency [Hz]; must not exceed Nyquist.
    direction
        ``"x"``, ``"y"`` or ``"z"``: stored on the FRF.
    pose
        Tool-tip pose (X, Y, Z [m], Rx, Ry, Rz [deg]) stored on the FRF.
    source
        ``"EMA"`` (hammer) or ``"OMA"`` (operational): stored on the FRF.

    Returns
    -------
    FRF
        (n_f,) H1 or H2 estimate with coherence and ``n_averages`` (Welch segments).

    Raises
    ------
    ValueError
        Records not 1-D, of different length or with NaN; unknown quantity or estimator;
        ``f_max_hz`` above Nyquist.

    See ``docs/methods.md`` section 1 (Eq. 5).

    Examples
    --------
    >>> import numpy as np
    >>> from robovib.frf import estimate_frf
    >>> rng = np.random.default_rng(0)
    >>> force = rng.normal(size=4096)
    >>> frf = estimate_frf(force, 2e-6 * force, 1000.0, response_quantity="displacement",
    ...                    nperseg=512)
    >>> bool(np.allclose(frf.values, 2e-6))
    True
    """
    if response_quantity not in RESPONSE_TO_QUANTITY:
        raise ValueError(
            f"unknown response quantity {response_quantity!r}; expected one of {list(RESPONSE_TO_QUANTITY)}"
        )
    estimator = check_choice("estimator", estimator, ("H1", "H2"), case_insensitive=True)
    sd = spectral_densities(
        force, response, sample_rate_hz, nperseg=nperseg, window=window, noverlap=noverlap
    )
    return _frf_from_densities(
        sd, sample_rate_hz, response_quantity, estimator, f_max_hz, direction, pose, source
    )


def _frf_from_densities(
    sd, sample_rate_hz, response_quantity, estimator, f_max_hz, direction, pose, source, **extra
):
    # The name is checked here too (every path to an FRF passes here): "h1" must not become H2.
    estimator = check_choice("estimator", estimator, ("H1", "H2"), case_insensitive=True)
    nyquist = sample_rate_hz / 2
    if f_max_hz is not None:
        f_max_hz = check_number("f_max_hz", f_max_hz, "Hz", lo=0.0, lo_open=True)
        if f_max_hz > nyquist:
            raise ValueError(
                f"f_max_hz={f_max_hz:g} Hz is beyond the Nyquist frequency {nyquist:g} Hz"
            )
        df = sd.frequency_hz[1] - sd.frequency_hz[0] if sd.frequency_hz.size > 1 else np.inf
        if f_max_hz < 2 * df:
            raise ValueError(
                f"f_max_hz={f_max_hz:g} Hz keeps fewer than 2 bins (resolution {df:.3g} Hz)"
            )
    keep = sd.frequency_hz > 0
    if f_max_hz is not None:
        keep &= sd.frequency_hz <= f_max_hz
    if np.any(sd.gxx[keep] <= 0):
        raise ValueError(
            "the force spectrum is zero in part of the band: no excitation there, no FRF"
        )
    h = {"H1": sd.h1, "H2": sd.h2}[estimator]
    return FRF(
        frequency_hz=sd.frequency_hz[keep],
        values=h[keep],
        coherence=np.clip(sd.coherence[keep], 0.0, 1.0),  # rounding can exceed 1 by 1e-16
        quantity=RESPONSE_TO_QUANTITY[response_quantity],
        direction=direction,
        pose=pose,
        source=source,
        n_averages=sd.n_averages,
        estimator=estimator,
        **extra,
    )
