"""Are the hits long enough for the band? FRF lines in a band against the hit length.

An FRF from hits of ``N`` samples at ``fs`` has lines ``df = fs / N = 1 / T`` apart (``T`` the
hit length, thesis §3.2.1), so a band of width ``B`` holds about ``B T`` lines. A mode fit
needs a few of them: :func:`check_lines_in_band` counts the lines and says how long the hits
must be. Both ``robovib frf compute`` and the campaign (:mod:`robovib.campaign.process`) use it.
"""

from __future__ import annotations

import numpy as np

from .core import FRF

__all__ = ["BandTooShortError", "check_lines_in_band"]


class BandTooShortError(ValueError):
    """Fewer FRF lines in a band than needed: the hits are too short for it.

    Parameters
    ----------
    message : str
        The error message.
    n_lines, min_lines, df_hz, hit_samples, hit_duration_s, band_hz, needed_s
        Stored as the attributes below (keyword-only).

    Attributes
    ----------
    n_lines : int
        Lines in the band.
    min_lines : int
        Lines needed.
    df_hz : float
        FRF resolution [Hz].
    hit_samples : int
        Samples per hit.
    hit_duration_s : float
        Hit length [s].
    band_hz : tuple of float
        The band ``(low, high)`` [Hz].
    needed_s : float
        Hit length that gives ``min_lines`` lines over the band's width [s].
    """

    def __init__(self, message, *, n_lines, min_lines, df_hz, hit_samples, hit_duration_s,
                 band_hz, needed_s):  # fmt: skip
        super().__init__(message)
        self.n_lines, self.min_lines, self.df_hz = n_lines, min_lines, df_hz
        self.hit_samples, self.hit_duration_s = hit_samples, hit_duration_s
        self.band_hz, self.needed_s = band_hz, needed_s


def check_lines_in_band(
    frf: FRF,
    band_hz: tuple[float, float],
    *,
    hit_samples: int,
    sample_rate_hz: float,
    min_lines: int = 5,
    band_name: str = "band",
) -> int:
    """Count the FRF lines in ``low <= f <= high`` and refuse fewer than ``min_lines``.

    Parameters
    ----------
    frf : FRF
        The FRF (its lines ``frequency_hz``, resolution ``df_hz``).
    band_hz : (float, float)
        The band ``(low, high)`` [Hz], both ends included.
    hit_samples : int
        Samples per hit the FRF was averaged from.
    sample_rate_hz : float
        Sample rate of the hits [Hz].
    min_lines : int
        Fewest lines accepted.
    band_name : str
        What the band is, for the message (e.g. ``"fit band"``).

    Returns
    -------
    int
        The number of lines in the band.

    Raises
    ------
    BandTooShortError
        Fewer than ``min_lines`` lines in the band; the message gives the resolution, the hit
        length and the length needed (``min_lines / (high - low)`` seconds).

    Examples
    --------
    >>> import numpy as np
    >>> from robovib.frf import FRF
    >>> f = np.arange(0.0, 101.0, 2.0)  # hits of 0.5 s: lines 2 Hz apart
    >>> check_lines_in_band(FRF(f, np.ones(f.size, complex)), (40.0, 50.0), hit_samples=500,
    ...                     sample_rate_hz=1000.0)
    6
    """
    lo, hi = (float(v) for v in band_hz)
    f = np.asarray(frf.frequency_hz)
    n_lines = int(np.count_nonzero((f >= lo) & (f <= hi)))
    if n_lines >= min_lines:
        return n_lines
    duration_s = hit_samples / sample_rate_hz
    needed_s = min_lines / max(hi - lo, 1e-12)
    raise BandTooShortError(
        f"FRF resolution df = {frf.df_hz:.3g} Hz from hits of {hit_samples} samples = "
        f"{duration_s:.3g} s leaves {n_lines} lines in the {band_name} {lo:.4g}-{hi:.4g} Hz, "
        f"fewer than {min_lines}: the hits are too short for this band (need >= {needed_s:.3g} s)",
        n_lines=n_lines, min_lines=min_lines, df_hz=frf.df_hz, hit_samples=hit_samples,
        hit_duration_s=duration_s, band_hz=(lo, hi), needed_s=needed_s,
    )  # fmt: skip
