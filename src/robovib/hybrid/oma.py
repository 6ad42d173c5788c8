"""FRFs from operational (milling) data, one per path segment (thesis §5.2.2, §5.3.2).

Milling forces are periodic (spindle and tooth-passing harmonics) plus broadband background
content; that background excites the structure at all frequencies, so Eq. 5
(H1 = Gxy / Gxx, Welch) gives the FRF between the harmonics. Per segment of the path:

* the force and tool-tip displacement channels are first mapped from the sensor frames to the
  tool tip by constant 3x3 matrices (``force_transform``, ``displacement_transform``, §5.3.2);
* H1 and the coherence per bin; bins within ``harmonic_tolerance_hz`` of a spindle-frequency
  harmonic (which includes the tooth-passing harmonics) and bins with coherence below
  ``min_coherence`` are *flagged*, never silently used: the pose model masks them out;
* the segment's pose is the pose at its midpoint: the path coordinate (1-D ``path_s_m``) or
  the mean of the workspace pose columns (2-D poses, segmented by the XY distance travelled);
* each segment carries the H1 random error per bin (Bendat & Piersol, normalised error
  ``sqrt(1 - γ²) / (|γ| sqrt(2 n_d))`` x |H|), used as a noise floor by the robust update.

What OMA needs: broadband force content between the harmonics. When fewer than
``min_usable_fraction`` of the bins pass the checks (averaged over segments) an
:class:`OMAQualityWarning` says so (too little background excitation, too short segments).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from ..frf.core import FRF
from ..frf.estimate import estimate_frf

__all__ = [
    "OMAQualityWarning",
    "OMASegment",
    "debiased_coherence",
    "h1_random_error",
    "oma_frfs",
]


class OMAQualityWarning(UserWarning):
    """Too few OMA bins pass the coherence / harmonic checks to be useful."""


@dataclass(frozen=True)
class OMASegment:
    """One OMA FRF: a path segment's compliance with its flags and random error.

    Attributes
    ----------
    frf
        Compliance FRF of the segment [m/N] (Welch H1 estimate with its coherence).
    flagged
        (n_f,) bool: bins at spindle harmonics or with low coherence.
    s_mid_m
        Path coordinate of the segment's midpoint (2-D poses: distance travelled) [m].
    n_samples
        Time samples in the segment.
    pose_mid
        Mean pose of the segment (2-D poses), in their units; empty for path segments.
    """

    frf: FRF  #: compliance [m/N] of the segment
    flagged: np.ndarray  #: (n_f,) bool: harmonic or low-coherence bins
    s_mid_m: float  #: path coordinate of the midpoint (2-D poses: travelled distance [m])
    n_samples: int
    pose_mid: tuple[float, ...] = ()  #: mean pose of the segment (2-D poses), in their units

    @property
    def random_error_m_per_n(self) -> np.ndarray:
        """(n_f,) H1 random error std per bin [m/N] (Bendat & Piersol, from the coherence)."""
        return h1_random_error(self.frf.values, self.frf.coherence, self.frf.n_averages)


def debiased_coherence(coherence, n_averages: int) -> np.ndarray:
    """Coherence corrected for its estimation bias with few averages, in [0, 1].

    With ``n_d`` Welch averages the estimate of γ² is biased upwards by about
    ``(1 - γ²) / n_d`` (Bendat & Piersol §9.2.3: two unrelated signals give γ̂² ≈ 1 / n_d,
    one average always gives 1). Inverting ``E[γ̂²] ≈ γ² + (1 - γ²) / n_d`` gives
    ``γ² ≈ (n_d γ̂² - 1) / (n_d - 1)``; with one average nothing is known (0 returned).

    Parameters
    ----------
    coherence : array_like
        Estimated coherence γ̂² per bin, in [0, 1].
    n_averages : int
        Welch averages behind the estimate.

    Returns
    -------
    numpy.ndarray
        Debiased coherence per bin, in [0, 1].
    """
    coh = np.clip(np.asarray(coherence, float), 0.0, 1.0)
    n_d = int(n_averages)
    if n_d < 2:
        return np.zeros_like(coh)
    return np.clip((n_d * coh - 1.0) / (n_d - 1.0), 0.0, 1.0)


def h1_random_error(values, coherence, n_averages: int) -> np.ndarray:
    """H1 random error std per bin [units of ``values``] from the coherence.

    Bendat & Piersol's normalised random error ``sqrt(1 - γ²) / (|γ| sqrt(2 n_d))`` x |H|,
    with γ² the *debiased* coherence (:func:`debiased_coherence`): with the 2-3 averages of
    a 50 mm OMA segment the raw coherence of a bin without coherent content is ~0.5 and
    would understate its error several times. Floored at γ² = 1e-3 (error ~22 x |H|).

    Parameters
    ----------
    values : array_like
        H1 estimate per bin (complex or magnitude).
    coherence : array_like
        Estimated coherence per bin.
    n_averages : int
        Welch averages behind the estimate.

    Returns
    -------
    numpy.ndarray
        Random-error standard deviation per bin, in the units of ``values``.
    """
    n_d = max(int(n_averages), 1)
    coh = np.maximum(debiased_coherence(coherence, n_d), 1e-3)
    return np.abs(np.asarray(values)) * np.sqrt((1 - coh) / (2 * n_d * coh))


def oma_frfs(
    time_s,
    force_n,
    displacement_m,
    path_s_m,
    *,
    direction: str = "x",
    segment_length_m: float = 0.05,
    nperseg: int = 512,
    noverlap: int | None = None,
    window: str = "hann",
    f_min_hz: float = 2.0,
    f_max_hz: float = 60.0,
    spindle_rpm: float | None = None,
    harmonic_tolerance_hz: float | None = None,
    min_coherence: float = 0.5,
    force_transform=None,
    displacement_transform=None,
    exclude_s_m: tuple[float, float] | None = None,
    min_usable_fraction: float = 0.5,
) -> list[OMASegment]:
    """OMA compliance FRFs of one direction for consecutive path segments (Eq. 5 per segment).

    Parameters
    ----------
    time_s, force_n, displacement_m
        Synchronised records: (n,) [s], (n, 3) [N], (n, 3) [m] — uniform sampling.
    path_s_m
        (n,) path coordinate [m], or (n, d) poses whose first two columns are x, y [m]
        (segments by XY distance travelled; each segment's mean pose in ``pose_mid``).
    segment_length_m
        Path length per FRF [m] (thesis: 50 mm).
    nperseg, noverlap, window
        Welch segment [samples], overlap [samples] (default nperseg // 2) and window (SciPy
        name, e.g. ``"hann"``, ``"boxcar"``, ``"hamming"``); resolution = rate / nperseg.
    f_min_hz, f_max_hz
        Band kept [Hz].
    spindle_rpm, harmonic_tolerance_hz
        Flags bins within the tolerance (default 1.5 bins) of spindle harmonics.
    min_coherence
        Bins below are flagged.
    exclude_s_m
        A path interval left out (e.g. 50 mm around a validation pose) [m].
    min_usable_fraction
        Warn (:class:`OMAQualityWarning`) when fewer bins than this pass on average.
    direction : {"x", "y", "z"}
        Direction of the FRFs (force and displacement component).
    force_transform, displacement_transform : array_like (3, 3), optional
        Constant matrices taking the measured force / displacement to the tool tip
        (thesis §5.3.2), applied as ``record @ T.T``.

    Returns
    -------
    list of OMASegment

    Raises
    ------
    ValueError
        Unsynchronised or non-uniform records, NaN, unknown direction, segments shorter than
        one Welch window, bad overlap.

    See ``docs/methods.md`` section 7 (hybrid EMA + OMA model).

    Examples
    --------
    >>> import numpy as np
    >>> from robovib.hybrid import oma_frfs
    >>> rng = np.random.default_rng(0)
    >>> t = np.arange(20000) / 1000.0
    >>> f = rng.normal(size=(t.size, 3))
    >>> segs = oma_frfs(t, f, 1e-6 * f, 0.01 * t, segment_length_m=0.1, nperseg=256)
    >>> len(segs) >= 1
    True
    """
    t = np.asarray(time_s, float)
    f = np.asarray(force_n, float)
    x = np.asarray(displacement_m, float)
    s_in = np.asarray(path_s_m, float)
    if s_in.ndim == 2 and s_in.shape[0] == t.size and s_in.shape[1] >= 2:
        poses = s_in
        step = np.hypot(np.diff(s_in[:, 0]), np.diff(s_in[:, 1]))
        s = np.concatenate([[0.0], np.cumsum(step)])
    else:
        poses = None
        s = s_in
    from .._checks import check_choice, check_int, check_number

    check_choice("direction", direction, ("x", "y", "z"))
    segment_length_m = check_number("segment_length_m", segment_length_m, "m", lo=0.0, lo_open=True)
    nperseg = check_int("nperseg", nperseg, lo=8)
    if noverlap is not None and not 0 <= noverlap < nperseg:
        raise ValueError(f"noverlap must be in [0, nperseg={nperseg}) samples, got {noverlap}")
    f_min_hz = check_number("f_min_hz", f_min_hz, "Hz", lo=0.0)
    f_max_hz = check_number("f_max_hz", f_max_hz, "Hz", lo=0.0, lo_open=True)
    if f_min_hz >= f_max_hz:
        raise ValueError(f"f_min_hz={f_min_hz:g} Hz must be below f_max_hz={f_max_hz:g} Hz")
    check_number("min_coherence", min_coherence, "", lo=0.0, hi=1.0)
    if spindle_rpm is not None:
        check_number("spindle_rpm", spindle_rpm, "rpm", lo=0.0, lo_open=True)
    if not (
        t.ndim == 1 and f.shape == (t.size, 3) and x.shape == (t.size, 3) and s.shape == (t.size,)
    ):
        raise ValueError(
            f"unsynchronised records: time {t.shape}, force {f.shape}, displacement {x.shape}, path {s_in.shape} "
            "(need (n,), (n, 3), (n, 3), (n,) or (n, d))"
        )
    if not all(np.all(np.isfinite(a)) for a in (t, f, x, s)):
        raise ValueError("OMA records contain NaN or inf")
    dt = np.diff(t)
    if np.any(dt <= 0) or np.ptp(dt) > 1e-6 * np.mean(dt):
        raise ValueError("OMA records are not uniformly sampled")
    fs = 1.0 / np.mean(dt)
    if force_transform is not None:
        f = f @ np.asarray(force_transform, float).T
    if displacement_transform is not None:
        x = x @ np.asarray(displacement_transform, float).T
    axis = "xyz".index(direction)
    travelled = np.abs(s - s[0])
    n_seg = int(np.floor(travelled[-1] / segment_length_m + 1e-9))
    if n_seg < 1:
        raise ValueError(
            f"the record covers {travelled[-1]:.3f} m, less than one {segment_length_m} m segment"
        )
    out = []
    for k in range(n_seg):
        sel = (travelled >= k * segment_length_m) & (travelled < (k + 1) * segment_length_m)
        idx = np.flatnonzero(sel)
        s_mid = float(np.mean(s[idx]))
        if exclude_s_m is not None and exclude_s_m[0] <= s_mid <= exclude_s_m[1]:
            continue
        if idx.size < nperseg:
            raise ValueError(
                f"segment {k} has {idx.size} samples, fewer than one Welch window (nperseg={nperseg}); "
                "use longer segments or a shorter window"
            )
        frf = estimate_frf(
            f[idx, axis], x[idx, axis], fs, response_quantity="displacement", nperseg=nperseg,
            noverlap=noverlap, window=window, f_max_hz=f_max_hz, direction=direction, source="OMA",
        ).band(f_min_hz, f_max_hz)  # fmt: skip
        flagged = frf.coherence < min_coherence
        if spindle_rpm is not None:
            f_sp = spindle_rpm / 60.0
            tol = harmonic_tolerance_hz if harmonic_tolerance_hz is not None else 1.5 * frf.df_hz
            harmonic = np.abs(frf.frequency_hz - np.round(frf.frequency_hz / f_sp) * f_sp) <= tol
            flagged |= harmonic & (np.round(frf.frequency_hz / f_sp) >= 1)
        pose_mid = () if poses is None else tuple(float(v) for v in poses[idx].mean(axis=0))
        out.append(OMASegment(frf, flagged, s_mid, int(idx.size), pose_mid))
    if not out:
        raise ValueError("every segment was excluded")
    usable = 1.0 - float(np.mean([sg.flagged.mean() for sg in out]))
    if usable < min_usable_fraction:
        warnings.warn(
            f"only {100 * usable:.0f} % of the OMA bins ({direction}) pass the coherence "
            f"(>= {min_coherence}) and harmonic checks: too little broadband force content "
            "for OMA, or too few averages (longer segments / shorter nperseg)",
            OMAQualityWarning,
            stacklevel=2,
        )
    return out
