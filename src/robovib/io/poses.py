"""Tables of poses (CSV): candidate poses, campaign poses; units in the column names."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

__all__ = ["read_pose_table"]


def _float(text: str) -> float:
    try:
        return float(text)
    except ValueError:
        return float("nan")


def read_pose_table(path: str | Path, columns: Sequence[str]):
    """Read a CSV of poses and check that ``columns`` are present, numeric and finite.

    Parameters
    ----------
    path
        CSV with a header row (any layout :func:`robovib.io.csv_table.read_table` reads:
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
    from .csv_table import read_table

    path = Path(path)
    if not path.is_file():
        raise ValueError(f"{path}: no such pose table")
    try:
        raw = read_table(path, what="pose table")
    except ValueError as exc:
        if "has a header but no data rows" in str(exc):
            raise ValueError(f"{path}: pose table has no rows") from None
        raise
    table = raw.to_frame()
    missing = [c for c in columns if c not in table.columns]
    if missing:
        raise ValueError(
            f"{path}: pose table lacks column(s) {', '.join(missing)} (has {', '.join(table.columns)})"
        )
    if table.empty:
        raise ValueError(f"{path}: pose table has no rows")
    for c in columns:
        values = np.array([_float(v) for v in raw.column(c)])
        bad = ~np.isfinite(values)
        if bad.any():
            i = int(np.argmax(bad))
            raise ValueError(
                f"{path} line {raw.lines[i]}: {c} = {raw.column(c)[i]!r} is not a finite number"
            )
        table[c] = values
    return table
