"""Tables of poses (CSV): candidate poses, campaign poses; units in the column names."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

__all__ = ["read_pose_array", "read_pose_table"]


def _float(text: str) -> float:
    try:
        return float(text)
    except ValueError:
        return float("nan")


def _read_checked(path: str | Path, columns: Sequence[str]):
    """The table as read and the required columns as checked finite floats."""
    from ..files.csv_table import read_table
    from ..files.safe_read import check_input_file

    path = check_input_file(path, "pose table")  # a regular file below the size limit
    try:
        raw = read_table(path, what="pose table")
    except ValueError as exc:
        if "has a header but no data rows" in str(exc):
            raise ValueError(f"{path}: pose table has no rows") from None
        raise
    missing = [c for c in columns if c not in raw.header]
    if missing:
        raise ValueError(
            f"{path}: pose table lacks column(s) {', '.join(missing)} (has {', '.join(raw.header)})"
        )
    if not raw.rows:
        raise ValueError(f"{path}: pose table has no rows")
    values = {}
    for c in columns:
        v = np.array([_float(x) for x in raw.column(c)])
        bad = ~np.isfinite(v)
        if bad.any():
            i = int(np.argmax(bad))
            raise ValueError(
                f"{path} line {raw.lines[i]}: {c} = {raw.column(c)[i]!r} is not a finite number"
            )
        values[c] = v
    return raw, values


def read_pose_table(path: str | Path, columns: Sequence[str]):
    """Read a CSV of poses and check that ``columns`` are present, numeric and finite.

    Parameters
    ----------
    path
        CSV with a header row (any layout :func:`robovib.files.csv_table.read_table` reads:
        spreadsheet exports, ``x [mm]`` headers); other columns are kept.
    columns
        Required columns, units in the names (``x_mm``, ``rz_deg``, ``a1_deg``...).

    Returns
    -------
    pandas.DataFrame

    Raises
    ------
    ValueError
        Missing file or columns, no rows, non-numeric or non-finite cells (line named).
    """
    raw, values = _read_checked(path, columns)
    table = raw.to_frame()
    for c, v in values.items():
        table[c] = v
    return table


def read_pose_array(path: str | Path, columns: Sequence[str]) -> np.ndarray:
    """The ``columns`` of a CSV of poses as an (n, len(columns)) float array (no pandas).

    The same file layouts and checks as :func:`read_pose_table`; what a command at a few
    poses reads (``robovib model next-poses``) without importing pandas.

    Parameters
    ----------
    path : str or Path
        The CSV file.
    columns : sequence of str
        Columns to read, in this order.

    Returns
    -------
    numpy.ndarray (n, len(columns))
        The poses.

    Raises
    ------
    ValueError
        Missing file or columns, no rows, non-numeric or non-finite cells (line named).
    """
    _, values = _read_checked(path, columns)
    return np.column_stack([values[c] for c in columns])
