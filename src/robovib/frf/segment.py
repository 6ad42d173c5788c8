"""Cut a continuous hammer recording into hits (thesis §3.2.1: several hits per pose are averaged).

A free-running DAQ records one long force/response pair holding several impacts a few seconds
apart. The impacts are found in the force channel:

1. **Threshold**: ``|F| >= max(threshold * max|F|, noise_factor * sigma)``, with ``sigma`` the
   robust (median absolute deviation) noise level of the force channel.
2. **Pulses**: runs of samples above the threshold; runs closer than ``merge_s`` are one pulse.
3. **Hold-off**: a pulse that starts less than ``hold_off_s`` after the onset of the current hit
   belongs to that hit (it is a double hit, judged later by :func:`robovib.frf.check_hit`); a
   later pulse starts a new hit.
4. **Cut**: hit ``i`` starts ``pretrigger_s + merge_s`` before its onset and ends where the next hit
   starts; all hits get the shortest such length (averaging needs equal records; at most
   ``window_s``), but a hit with less than half the median span before the next impact is
   rejected as short (reported; it must not shorten every hit). A last hit with less than
   half the median spacing left before the end of the record is rejected as truncated
   (reported, never padded).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["HitSegmentation", "segment_hits"]


@dataclass(frozen=True)
class HitSegmentation:
    """Where the hits of a continuous record are.

    Attributes
    ----------
    starts
        (n_hits,) first sample of each kept hit.
    length
        Samples per hit (common to all kept hits).
    onsets
        (n_hits,) sample of each kept hit's first pulse onset.
    n_pulses
        (n_hits,) pulses inside each kept hit's hold-off window (> 1: a double hit candidate).
    rejected
        ``(onset_sample, reason)`` of impacts that did not form a hit.
    """

    starts: np.ndarray
    length: int
    onsets: np.ndarray
    n_pulses: np.ndarray
    rejected: tuple[tuple[int, str], ...] = ()

    @property
    def n_hits(self) -> int:
        return int(self.starts.size)


def _pulses(force: np.ndarray, level: float, merge: int) -> list[tuple[int, int]]:
    above = np.abs(force) >= level
    edges = np.diff(np.concatenate([[0], above.astype(np.int8), [0]]))
    starts, stops = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    runs: list[tuple[int, int]] = []
    for a, b in zip(starts.tolist(), stops.tolist(), strict=True):
        if runs and a - runs[-1][1] < merge:
            runs[-1] = (runs[-1][0], b)
        else:
            runs.append((a, b))
    return runs


def segment_hits(
    force,
    sample_rate_hz: float,
    *,
    threshold: float = 0.1,
    pretrigger_s: float = 0.01,
    hold_off_s: float = 0.5,
    window_s: float | None = None,
    merge_s: float = 0.002,
    noise_factor: float = 8.0,
) -> HitSegmentation:
    """Find the hits of a continuous force record (see the module docstring).

    Parameters
    ----------
    force
        (n_samples,) force record [N] (any unit; only its shape matters).
    sample_rate_hz
        Sample rate [Hz].
    threshold
        Detection level as a fraction of the record's largest |force| (0 < threshold < 1).
    pretrigger_s
        Signal kept before each onset [s].
    hold_off_s
        Pulses within this time after a hit's onset belong to that hit [s].
    window_s
        Longest hit kept [s] (None: up to the next hit).
    merge_s
        Runs above the threshold closer than this are one pulse [s].
    noise_factor
        The detection level is at least this many robust noise standard deviations.

    Returns
    -------
    HitSegmentation

    Raises
    ------
    ValueError
        On a non-1-D or non-finite record, a zero force, or out-of-range settings.
    """
    f = np.asarray(force, float)
    if f.ndim != 1 or f.size < 2:
        raise ValueError(f"force must be a 1-D record of >= 2 samples, got shape {f.shape}")
    if not np.all(np.isfinite(f)):
        raise ValueError("force record contains NaN or inf")
    fs = float(sample_rate_hz)
    if not (np.isfinite(fs) and fs > 0):
        raise ValueError(f"sample_rate_hz must be positive, got {sample_rate_hz!r} Hz")
    if not 0 < threshold < 1:
        raise ValueError(f"threshold must be in (0, 1) of the peak force, got {threshold!r}")
    for name, v in (
        ("pretrigger_s", pretrigger_s),
        ("hold_off_s", hold_off_s),
        ("merge_s", merge_s),
    ):
        if not (np.isfinite(v) and v >= 0):
            raise ValueError(f"{name} must be a finite number >= 0 s, got {v!r}")
    if window_s is not None and not (np.isfinite(window_s) and window_s > 0):
        raise ValueError(f"window_s must be a positive number of seconds, got {window_s!r}")
    peak = float(np.max(np.abs(f)))
    if peak == 0:
        raise ValueError("the force record is identically zero (no impact recorded)")
    sigma = 1.4826 * float(np.median(np.abs(f - np.median(f))))
    level = max(threshold * peak, noise_factor * sigma)
    pulses = _pulses(f, level, max(1, round(merge_s * fs)))
    hold = round(hold_off_s * fs)
    onsets: list[int] = []
    n_pulses: list[int] = []
    for a, _ in pulses:
        if onsets and a - onsets[-1] < hold:
            n_pulses[-1] += 1
        else:
            onsets.append(a)
            n_pulses.append(1)
    if not onsets:
        return HitSegmentation(np.zeros(0, int), 0, np.zeros(0, int), np.zeros(0, int))
    # The threshold crossing lags the pulse's first rise: keep merge_s more before it, so that
    # a trigger at a lower level still has the full pre-trigger.
    pre = round(pretrigger_s * fs) + round(merge_s * fs)
    starts = np.maximum(np.asarray(onsets) - pre, 0)
    ends = np.append(starts[1:], f.size)
    rejected: list[tuple[int, str]] = []
    keep = np.ones(len(onsets), bool)
    if len(onsets) > 1:
        spacing = float(np.median(np.diff(starts)))
        left = f.size - starts[-1]
        if left < 0.5 * spacing:
            keep[-1] = False
            rejected.append(
                (
                    int(onsets[-1]),
                    f"truncated: the record ends {left / fs:.3g} s after the impact at "
                    f"{onsets[-1] / fs:.4g} s (other hits have {spacing / fs:.3g} s)",
                )
            )
    # Hand-struck hits come at irregular spacings: all kept hits share the shortest span, but a
    # hit followed by the next impact (or the record end) after less than half the median span
    # is rejected, never allowed to shorten every hit (and the FRF resolution) below that.
    spans = (ends - starts).astype(float)
    median = float(np.median(spans[keep]))
    for k in np.flatnonzero(keep):
        if spans[k] < 0.5 * median:
            keep[k] = False
            after = "the next impact follows" if k + 1 < len(onsets) else "the record ends"
            rejected.append(
                (
                    int(onsets[k]),
                    f"short hit: {after} {spans[k] / fs:.3g} s after the impact at "
                    f"{onsets[k] / fs:.4g} s (median {median / fs:.3g} s)",
                )
            )
    length = int(np.min(spans[keep]))
    if window_s is not None:
        length = min(length, round(window_s * fs))
    return HitSegmentation(
        starts[keep], length, np.asarray(onsets)[keep], np.asarray(n_pulses)[keep], tuple(rejected)
    )
