"""The CSV layout of a hammer recording (see :mod:`robovib.io.recording`): its channel reader
and its writer."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ...files.units import si_factor
from .hammer import _QUANTITY_TO_SPEC, HammerRecording, Sensitivity
from .hits import (
    _channel_factor,
    _Channels,
    _printed_resolution,
    _split_column,
    _unit_from_column,
    sample_rate_from_time,
)

__all__ = ["write_recording_csv"]

_RESPONSE_UNIT = {"acceleration": "m_per_s2", "velocity": "m_per_s", "displacement": "m"}


def _csv_channels(
    path: Path,
    force_sensitivity: Sensitivity | None,
    response_sensitivity: Sensitivity | None,
) -> _Channels:
    from ...files.csv_table import read_table

    table = read_table(path, what="recording")
    header = list(table.header)
    rows = table.rows
    try:
        data = np.array(rows, dtype=float)
    except ValueError:
        for name in header:
            table.numbers(name)  # names the line and the cell
        raise
    renamed = [
        f"column {raw!r} read as {name}"
        for raw, name in zip(table.raw_header, header, strict=True)
        if raw.strip().lower() != name
    ]
    col = {h: i for i, h in enumerate(header)}
    time_cols = [h for h in header if h.startswith("time_")]
    force_cols = [h for h in header if h.startswith("force_")]
    resp_cols = [h for h in header if h.split("_", 1)[0] in _QUANTITY_TO_SPEC]
    if len(time_cols) != 1 or len(force_cols) != 1 or not resp_cols:
        raise ValueError(
            f"{path}: need exactly one time_*, one force_* and at least one "
            f"acceleration_*/velocity_*/displacement_* column, got {header}"
        )
    if not np.all(np.isfinite(data)):
        r, c = np.argwhere(~np.isfinite(data))[0]
        raise ValueError(f"{path} line {table.lines[r]}: NaN or inf in column {header[c]!r}")
    _, t_factor = si_factor(_unit_from_column(time_cols[0]), "time")
    _, f_dir, f_unit = _split_column(force_cols[0])
    f_factor = _channel_factor(f_unit, "force", force_sensitivity, str(path))
    hits = data[:, col["hit"]].astype(int) if "hit" in col else np.zeros(len(data), int)
    order = list(dict.fromkeys(hits.tolist()))  # hit numbers in file order
    ti = col[time_cols[0]]
    rates = []
    for h in order:
        sel = np.flatnonzero(hits == h)
        res = _printed_resolution(rows[i][ti] for i in sel) * t_factor
        where = f"{path} hit {h}" if "hit" in col else str(path)
        rates.append(sample_rate_from_time(data[sel, ti] * t_factor, res, where))
    if np.ptp(rates) > 1e-4 * rates[0]:
        raise ValueError(
            f"{path}: hits have mismatched sampling rates {sorted(set(np.round(rates, 3)))} Hz"
        )
    responses, quantity, direction, node = {}, {}, {}, {}
    for c in resp_cols:
        q, d, unit = _split_column(c)
        factor = _channel_factor(unit, q, response_sensitivity, str(path))
        responses[c] = [data[hits == h, col[c]] * factor for h in order]
        quantity[c], direction[c], node[c] = q, d, None
    return _Channels(
        forces=[data[hits == h, col[force_cols[0]]] * f_factor for h in order],
        responses=responses, quantity=quantity, direction=direction, node=node,
        force_direction=f_dir, sample_rate_hz=float(np.mean(rates)),
        labels=[f"hit {h}" for h in order], records_read=len(order) * (1 + len(resp_cols)),
        notes=[f"CSV read with {table.dialect}", *renamed], cut_short=not table.ends_with_newline,
        hit_rates=rates,
    )  # fmt: skip


def write_recording_csv(
    path: str | Path, recording: HammerRecording, *, inputs=(), force: bool = False
) -> None:
    """Write a hammer recording as CSV (``hit, time_s, force_n, <quantity>_<SI unit>``).

    The layout is the one :func:`robovib.io.read_recording_csv` reads.

    Parameters
    ----------
    path : str or pathlib.Path
        The ``.csv`` file to write.
    recording : HammerRecording
        The hits.
    inputs : sequence of path
        Files the output was made from (never overwritten unless ``force``).
    force : bool
        Allow ``path`` to be one of ``inputs``.

    Raises
    ------
    ValueError
        Unknown response quantity.
    """
    rec = recording
    if rec.response_quantity not in _RESPONSE_UNIT:
        raise ValueError(f"unknown response quantity {rec.response_quantity!r}")
    n = rec.forces.shape[1]
    t = np.arange(n) / rec.sample_rate_hz
    lines = [f"hit,time_s,force_n,{rec.response_quantity}_{_RESPONSE_UNIT[rec.response_quantity]}"]
    for h in range(rec.n_hits):
        lines.extend(
            f"{h},{t[i]:.15g},{rec.forces[h, i]:.9g},{rec.responses[h, i]:.9g}" for i in range(n)
        )
    from ...files.safe_write import atomic_output

    with atomic_output(Path(path), inputs=inputs, force=force) as tmp:
        tmp.write_text("\n".join(lines) + "\n")
