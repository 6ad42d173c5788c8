"""Order statistics without ``numpy.ma``.

NumPy 2's ``np.median``, ``np.percentile`` and plain ``np.unique`` check for masked arrays and so
import ``numpy.ma`` (20-100 ms) on first use: too much for a command meant to start in well under a
second. These give the same values (linear interpolation between order statistics, NumPy's
default method) for the 1-D cases robovib's pose commands use.
"""

from __future__ import annotations

import numpy as np

__all__ = ["median", "percentile"]


def percentile(a, q):
    """``np.percentile(a, q)`` of the flattened ``a`` (linear method); NaN where ``a`` has a NaN.

    Parameters
    ----------
    a : array_like
        Values (flattened), at least one.
    q : float or array_like
        Percentiles in [0, 100].

    Returns
    -------
    float or numpy.ndarray
        The percentiles, shaped like ``q``.
    """
    s = np.sort(np.ravel(np.asarray(a, float)))
    qa = np.asarray(q, float)
    if s.size == 0:
        raise ValueError("percentile of no values")
    if np.any((qa < 0) | (qa > 100)) or not np.all(np.isfinite(qa)):
        raise ValueError(f"percentiles must be in [0, 100], got {q!r}")
    if np.isnan(s[-1]):
        out = np.full(qa.shape, np.nan)
    else:
        out = np.interp(qa / 100.0 * (s.size - 1), np.arange(s.size), s)
    return float(out) if out.ndim == 0 else out


def median(a) -> float:
    """``np.median(a)`` of the flattened ``a``; NaN where ``a`` has a NaN."""
    return percentile(a, 50.0)
