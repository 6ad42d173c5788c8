"""UFF dataset 58 (function at nodal DOF), ASCII, written in one pass.

pyuff's writer re-reads the whole file after each record, so writing n records costs O(n²);
here every record is formatted in memory and the file is written once (atomically: temporary
file + rename). The layout follows the UFF 58 specification (80-column records, abscissa
minimum and increment in E13.5, ordinates in E20.11, four per line) and is read back by pyuff.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..files.safe_write import atomic_output

__all__ = ["Record58", "format_58", "write_uff58"]


@dataclass(frozen=True)
class Record58:
    """One dataset 58 record: evenly spaced abscissa ``x0 + i dx``, real or complex ordinates.

    Attributes
    ----------
    data
        (n,) real or complex ordinates.
    x0, dx
        First abscissa value and spacing.
    func_type
        UFF function type (1 time response, 4 FRF, 6 coherence, 0 general).
    ordinate_spec, ordinate_label, abscissa_spec, abscissa_label
        UFF data-characteristic codes and unit labels of the axes.
    denominator_spec, denominator_label
        Same for the ordinate denominator (an FRF's force).
    load_case_id
        Load case (groups the records of one hit or one FRF).
    rsp_node, rsp_dir, ref_node, ref_dir
        Response and reference node and direction codes.
    ids
        The five ID lines.
    """

    data: np.ndarray
    x0: float
    dx: float
    func_type: int
    ordinate_spec: int
    ordinate_label: str
    abscissa_spec: int
    abscissa_label: str
    load_case_id: int = 0
    rsp_node: int = 1
    rsp_dir: int = 0
    ref_node: int = 1
    ref_dir: int = 0
    denominator_spec: int = 0
    denominator_label: str = "NONE"
    ids: tuple[str, str, str, str, str] = ("NONE", "NONE", "NONE", "NONE", "NONE")


def _numbers(values: np.ndarray) -> str:
    """E20.11 numbers, four per line (one C-level formatting call per record)."""
    if values.size == 0:
        return ""
    n_full, rem = divmod(values.size, 4)
    text = ("%20.11e%20.11e%20.11e%20.11e\n" * n_full) % tuple(values[: 4 * n_full].tolist())
    if rem:
        text += ("%20.11e" * rem + "\n") % tuple(values[4 * n_full :].tolist())
    return text


def _e13(x: float) -> str:
    """``x`` in a 13-character abscissa field: exact (shortest repr) when it fits, else E-format.

    A plain decimal such as ``13.671875`` is valid input for a Fortran E13.5 field and read
    exactly by pyuff; E13.5 itself would keep only 6 digits (13.6719), shifting every bin.
    """
    text = repr(float(x))
    if len(text) <= 12:
        return f"{text:>13s}"
    for digits in (6, 5):
        text = f"{x:13.{digits}e}"
        if len(text) == 13:
            return text
    raise ValueError(f"abscissa value {x!r} does not fit a 13-character UFF field")


def format_58(rec: Record58) -> str:
    """The ASCII text of one dataset 58 record (delimiters included).

    Parameters
    ----------
    rec : Record58
        The record.

    Returns
    -------
    str
        The record's lines.
    """
    data = np.asarray(rec.data)
    complex_ = np.iscomplexobj(data)
    if complex_:
        flat = np.empty(2 * data.size)
        flat[0::2], flat[1::2] = data.real, data.imag
    else:
        flat = np.asarray(data, float)
    if not np.all(np.isfinite(flat)):
        raise ValueError("UFF 58 record contains NaN or inf ordinates")
    for k, line in enumerate(rec.ids):
        if len(line) > 80 or "\n" in line:
            raise ValueError(
                f"UFF 58 ID line {k + 1} has {len(line)} characters; at most 80 fit "
                f"(would be cut: {line!r})"
            )
    head = [
        f"{-1:6d}",
        f"{58:6d}" + " " * 74,
        *(f"{s:<80s}" for s in rec.ids),
        f"{rec.func_type:5d}{0:10d}{0:5d}{rec.load_case_id:10d} {'NONE':>10s}{rec.rsp_node:10d}"
        f"{rec.rsp_dir:4d} {'NONE':>10s}{rec.ref_node:10d}{rec.ref_dir:4d}",
        f"{6 if complex_ else 4:10d}{data.size:10d}{1:10d}{_e13(rec.x0)}{_e13(rec.dx)}{0.0:13.5e}",
        f"{rec.abscissa_spec:10d}{0:5d}{0:5d}{0:5d} {'NONE':<20s} {rec.abscissa_label:<20s}",
        f"{rec.ordinate_spec:10d}{0:5d}{0:5d}{0:5d} {'NONE':<20s} {rec.ordinate_label:<20s}",
        f"{rec.denominator_spec:10d}{0:5d}{0:5d}{0:5d} {'NONE':<20s} {rec.denominator_label:<20s}",
        f"{0:10d}{0:5d}{0:5d}{0:5d} {'NONE':<20s} {'NONE':<20s}",
    ]
    return "\n".join(head) + "\n" + _numbers(flat) + f"{-1:6d}\n"


def write_uff58(path: str | Path, records, *, inputs=(), force: bool = False) -> None:
    """Write dataset 58 records to ``path`` in one pass (temporary file, then rename).

    See :func:`robovib.io.atomic_output` for ``inputs`` and ``force``.

    Parameters
    ----------
    path : str or pathlib.Path
        The file to write.
    records : iterable of Record58
        The records, in file order.
    inputs : sequence of path
        Files the output was made from (never overwritten unless ``force``).
    force : bool
        Allow ``path`` to be one of ``inputs``.
    """
    records = list(records)
    if not records:
        raise ValueError(f"{path}: nothing to write (no records)")
    text = "".join(format_58(r) for r in records)
    with atomic_output(path, inputs=inputs, force=force) as tmp:
        tmp.write_text(text, encoding="utf-8")
