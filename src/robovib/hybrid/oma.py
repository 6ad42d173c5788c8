"""FRFs from operational (milling) data, one per path segment (thesis §5.2.2, §5.3.2).

Milling forces are periodic (spindle and tooth-passing harmonics) plus broadband background
content; that background excites the structure at all frequencies, so Eq. 5
(H1 = Gxy / Gxx, Welch) gives the FRF between the harmonics. Per segment of the path:

* the force and tool-tip displacement channels are first mapped from the sensor frames to the
  tool tip by constant 3x3 matrices (``force_transform``, ``displacement_transform``, §5.3.2);
* H1 and the coherence per bin; bins within ``harmonic_tolerance_hz`` of a spindle-frequency
  harmonic (which includes the tooth-passing harmonics) and bins with coherence below
  ``min_coherence`` are *flagged*, never silently used: the pose model masks them out;
* the segment's pose is the path coordinate at its midpoint.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..frf.core import FRF
from ..frf.estimate import estimate_frf

__all__ = ["OMASegment", "oma_frfs"]


@dataclass(frozen=True)
class OMASegment:
    frf: FRF  #: compliance [m/N] of the segment
    flagged: np.ndarray  #: (n_f,) bool: harmonic or low-coherence bins
    s_mid_m: float  #: path coordinate of the segment midpoint
    n_samples: int


def oma_frfs(
    time_s,
    force_n,
    displacement_m,
    path_s_m,
    *,
    direction: str = "x",
    segment_length_m: float = 0.05,
    nperseg: int = 512,
    f_min_hz: float = 2.0,
    f_max_hz: float = 60.0,
    spindle_rpm: float | None = None,
    harmonic_tolerance_hz: float | None = None,
    min_coherence: float = 0.5,
    force_transform=None,
    displacement_transform=None,
    exclude_s_m: tuple[float, float] | None = None,
) -> list[OMASegment]:
    """OMA compliance FRFs of one direction for consecutive path segments.

    Parameters
    ----------
    time_s, force_n, displacement_m, path_s_m
        Synchronised records: (n,), (n, 3), (n, 3), (n,) — equal lengths, uniform sampling.
    segment_length_m
        Path length per FRF (thesis: 50 mm).
    exclude_s_m
        A path interval left out (e.g. 50 mm around a validation pose).
    """
    t = np.asarray(time_s, float)
    f = np.asarray(force_n, float)
    x = np.asarray(displacement_m, float)
    s = np.asarray(path_s_m, float)
    from .._checks import check_choice, check_int, check_number

    check_choice("direction", direction, ("x", "y", "z"))
    segment_length_m = check_number("segment_length_m", segment_length_m, "m", lo=0.0, lo_open=True)
    nperseg = check_int("nperseg", nperseg, lo=8)
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
            f"unsynchronised records: time {t.shape}, force {f.shape}, displacement {x.shape}, path {s.shape} "
            "(need (n,), (n, 3), (n, 3), (n,))"
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
            f_max_hz=f_max_hz, direction=direction, source="OMA",
        ).band(f_min_hz, f_max_hz)  # fmt: skip
        flagged = frf.coherence < min_coherence
        if spindle_rpm is not None:
            f_sp = spindle_rpm / 60.0
            tol = harmonic_tolerance_hz if harmonic_tolerance_hz is not None else 1.5 * frf.df_hz
            harmonic = np.abs(frf.frequency_hz - np.round(frf.frequency_hz / f_sp) * f_sp) <= tol
            flagged |= harmonic & (np.round(frf.frequency_hz / f_sp) >= 1)
        out.append(OMASegment(frf, flagged, s_mid, int(idx.size)))
    if not out:
        raise ValueError("every segment was excluded")
    return out
