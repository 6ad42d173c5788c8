"""Channels to hits: SI factors of channels, the sample rate of a printed time column, the
pairing of force and response records, continuous records cut at the impacts, and the
:class:`~robovib.io.recording.hammer.ReadReport` of what was read."""

from __future__ import annotations

import decimal
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ...files.units import si_factor
from .hammer import _DIR_CODE, _SEGMENT, HammerRecording, ReadReport, Sensitivity

__all__ = ["sample_rate_from_time"]


def _channel_factor(
    label: str, expected: str, sensitivity: Sensitivity | None, where: str
) -> float:
    """SI factor of a channel; voltage labels (V, mV) need a sensitivity of the right quantity."""
    key = label.strip().lower()
    if key in ("v", "mv"):
        if sensitivity is None:
            raise ValueError(
                f"{where}: the {expected} channel is in {label}; give its sensitivity (mV per unit)"
            )
        quantity, per_unit = si_factor(sensitivity.unit)
        if quantity != expected:
            raise ValueError(
                f"{where}: sensitivity is per {sensitivity.unit} ({quantity}), the channel is {expected}"
            )
        if not sensitivity.mv_per_unit > 0:
            raise ValueError(
                f"{where}: sensitivity must be positive, got {sensitivity.mv_per_unit}"
            )
        return (1e3 if key == "v" else 1.0) / sensitivity.mv_per_unit * per_unit
    return si_factor(label, expected)[1]


def sample_rate_from_time(time_s: np.ndarray, resolution_s, where: str) -> float:
    """Sample rate [Hz] of a printed time column, tolerating rounding up to its resolution.

    The sample interval is the least-squares slope of time against sample index; each step must
    match it within the printed resolution ``resolution_s`` (a rounded value is off by at most
    half of it, a step by at most all of it). A larger deviation is a gap, named by sample and
    time.

    Parameters
    ----------
    time_s
        (n,) sample times [s].
    resolution_s
        Printed resolution [s]: one value, or one per sample (a step is allowed the coarser
        of its two ends).
    where
        The file (and hit) for messages.

    Returns
    -------
    float
        The sample rate [Hz].

    Raises
    ------
    ValueError
        Fewer than 2 samples, non-increasing time, or a gap.
    """
    t = np.asarray(time_s, float)
    if t.size < 2:
        raise ValueError(f"{where}: fewer than 2 samples")
    dt = np.diff(t)
    if np.any(dt <= 0):
        i = int(np.argmax(dt <= 0)) + 1
        raise ValueError(
            f"{where}: time column is not uniformly sampled: time does not increase at sample {i} "
            f"(t = {t[i]:.9g} s)"
        )
    # A gap (a missing sample, a jump) is found against the median step first, so that it is
    # named where it is, not where it tilts the least-squares slope.
    step = float(np.median(dt))
    gap = np.abs(dt - step) > 0.25 * step
    if np.any(gap):
        i = int(np.argmax(gap)) + 1
        raise ValueError(
            f"{where}: time column is not uniformly sampled: step of {dt[i - 1]:.9g} s before "
            f"sample {i} (t = {t[i]:.9g} s), expected {step:.9g} s; a gap or a changed rate"
        )
    idx = np.arange(t.size, dtype=float)
    slope, _ = np.polyfit(idx, t, 1)
    # A step off by a quarter interval or more is never rounding (a missing sample is a whole one).
    res = np.broadcast_to(np.asarray(resolution_s, float), t.shape)
    res_step = np.maximum(res[:-1], res[1:])  # each step: the coarser of its two printed times
    tol = np.minimum(1.001 * res_step + 1e-9 * slope + 1e-15, 0.25 * slope)
    bad = np.abs(dt - slope) > tol
    if np.any(bad):
        i = int(np.argmax(bad)) + 1
        raise ValueError(
            f"{where}: time column is not uniformly sampled: step of {dt[i - 1]:.9g} s before "
            f"sample {i} (t = {t[i]:.9g} s), expected {slope:.9g} s ± {res_step[i - 1]:.3g} s "
            "(the printed resolution); a gap or a changed rate"
        )
    return float(1.0 / slope)


def _printed_resolution(cells) -> np.ndarray:
    """The last printed digit of each numeric string (e.g. '0.000195' -> 1e-6); a DAQ printing
    ``%.10g`` gives fewer decimals once the time passes 1 s."""
    out = []
    for c in cells:
        try:
            e = decimal.Decimal(c.strip()).as_tuple().exponent
        except (decimal.InvalidOperation, AttributeError):
            e = None
        out.append(10.0**e if isinstance(e, int) else 0.0)
    return np.asarray(out, float)


def _unit_from_column(name: str) -> str:
    unit = name.split("_", 1)[1]
    return unit.replace("_per_", "/").replace("s2", "s^2")


def _split_column(name: str) -> tuple[str, str | None, str]:
    """``acceleration_x_m_per_s2`` -> ("acceleration", "x", "m/s^2")."""
    quantity, rest = name.split("_", 1)
    direction = None
    head, _, tail = rest.partition("_")
    if head in _DIR_CODE and tail:
        direction, rest = head, tail
    return quantity, direction, rest.replace("_per_", "/").replace("s2", "s^2")


@dataclass
class _Channels:
    """Raw hits as read: force and each response channel, lists of 1-D arrays per hit."""

    forces: list
    responses: dict  # key -> list of arrays (same hit order as forces)
    quantity: dict  # key -> quantity
    direction: dict  # key -> direction or None
    node: dict  # key -> node or None
    force_direction: str | None
    sample_rate_hz: float
    labels: list  # hit labels
    records_read: int
    rejected: list = field(default_factory=list)
    notes: list = field(default_factory=list)
    cut_short: bool = False  # the file ends without a line end (or inside a record)
    hit_rates: list | None = None  # per-hit sample rates (CSV), averaged over the kept hits


def _channel_name(key, ch: _Channels) -> str:
    d = ch.direction[key]
    node = ch.node[key]
    return f"{ch.quantity[key]}{' ' + d if d else ''}{f' node {node}' if node is not None else ''}"


def _cut_continuous(ch: _Channels, where: str, segment: str, seg_kw: dict) -> str:
    """Cut single-record channels into hits at the impacts; returns the layout."""
    from ...frf.segment import segment_hits

    if segment == "never" or (segment == "auto" and len(ch.forces) != 1):
        return "paired"
    if len(ch.forces) != 1:
        raise ValueError(
            f"{where}: segment='always' needs one continuous record per channel, "
            f"found {len(ch.forces)} hits"
        )
    seg = segment_hits(ch.forces[0], ch.sample_rate_hz, **seg_kw)
    if seg.n_hits <= 1 and not seg.rejected:
        return "paired" if segment == "auto" else "continuous"
    fs = ch.sample_rate_hz
    for onset, reason in seg.rejected:
        ch.rejected.append((f"impact at {onset / fs:.4g} s", reason))
    f0 = ch.forces[0]
    ch.forces = [f0[s : s + seg.length] for s in seg.starts]
    for key, rs in ch.responses.items():
        ch.responses[key] = [rs[0][s : s + seg.length] for s in seg.starts]
    ch.labels = [f"impact at {o / fs:.4g} s" for o in seg.onsets]
    ch.notes.append(
        f"continuous record of {f0.size / fs:.4g} s cut into {seg.n_hits} hits of "
        f"{seg.length / fs:.4g} s"
    )
    return "continuous"


def _equal_lengths(ch: _Channels, where: str) -> None:
    """Give every hit the common length; a hit shorter than it is rejected, never the others cut.

    The common length is the upper median of the hit lengths (at least half the hits are that
    long). Shorter hits are rejected by name and length (averaging them would cut every hit
    and coarsen the FRF resolution); longer ones lose only their tail beyond it (noted). A
    short last hit in a file that ends without a line end is a file cut short: an error.
    """
    lengths = [len(f) for f in ch.forces]
    if ch.cut_short:
        ch.notes.append("the file ends without a line end: its last value may be cut short")
    if len(set(lengths)) <= 1:
        return
    n = int(np.sort(lengths)[len(lengths) // 2])
    if ch.cut_short and lengths[-1] < n:
        raise ValueError(
            f"{where}: the file ends inside {ch.labels[-1]} ({lengths[-1]} samples, the other "
            f"hits {n}) without a line end: a truncated or damaged file"
        )
    keep = []
    for i, m in enumerate(lengths):
        if m < n:
            ch.rejected.append(
                (ch.labels[i], f"short hit: {m} samples ({m / ch.sample_rate_hz:.4g} s), the "
                 f"others {n} ({n / ch.sample_rate_hz:.4g} s)")
            )  # fmt: skip
        else:
            keep.append(i)
    longer = sorted({lengths[i] for i in keep if lengths[i] > n})
    if longer:
        ch.notes.append(f"hits of {longer} samples cut to the common length {n}")
    ch.forces = [ch.forces[i][:n] for i in keep]
    ch.responses = {k: [v[i][:n] for i in keep] for k, v in ch.responses.items()}
    ch.labels = [ch.labels[i] for i in keep]
    if ch.hit_rates is not None:  # a rejected short hit's (less precise) rate does not count
        ch.hit_rates = [ch.hit_rates[i] for i in keep]
        ch.sample_rate_hz = float(np.mean(ch.hit_rates))


def _finish(ch: _Channels, path: Path, segment: str, seg_kw: dict) -> list[HammerRecording]:
    if segment not in _SEGMENT:
        raise ValueError(f"unknown segment mode {segment!r}; expected one of {_SEGMENT}")
    if not ch.forces:
        detail = "; ".join(f"{h}: {r}" for h, r in ch.rejected)
        raise ValueError(f"{path}: no complete hit (force + response) found ({detail})")
    layout = _cut_continuous(ch, str(path), segment, seg_kw)
    _equal_lengths(ch, str(path))
    names = tuple(_channel_name(k, ch) for k in ch.responses)
    report = ReadReport(
        str(path), layout, ch.records_read, len(ch.forces),
        tuple(ch.rejected), names, tuple(ch.notes),
    )  # fmt: skip
    out = []
    forces = np.array(ch.forces)
    for key, rs in ch.responses.items():
        out.append(
            HammerRecording(
                forces,
                np.array(rs),
                ch.sample_rate_hz,
                ch.quantity[key],
                direction=ch.direction[key],
                reference_direction=ch.force_direction,
                response_node=ch.node[key],
                report=report,
            )
        )
    return out
