"""Tables of poses (CSV): candidate poses, campaign poses; units in the column names."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

__all__ = ["read_pose_table"]


def read_pose_table(path: str | Path, columns: Sequence[str]):
    """Read a CSV of poses and check that ``columns`` are present, numeric and finite.

    Parameters
    ----------
    path
        CSV with a header row; other columns are kept.
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
    import pandas as pd

    path = Path(path)
    if not path.is_file():
        raise ValueError(f"{path}: no such pose table")
    try:
        table = pd.read_csv(path)
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as exc:
        raise ValueError(f"{path}: not a readable CSV table ({exc})") from None
    table.columns = [str(c).strip() for c in table.columns]
    missing = [c for c in columns if c not in table.columns]
    if missing:
        raise ValueError(
            f"{path}: pose table lacks column(s) {', '.join(missing)} (has {', '.join(table.columns)})"
        )
    if table.empty:
        raise ValueError(f"{path}: pose table has no rows")
    for c in columns:
        values = pd.to_numeric(table[c], errors="coerce").to_numpy(float)
        bad = ~np.isfinite(values)
        if bad.any():
            i = int(np.argmax(bad))
            raise ValueError(
                f"{path} line {i + 2}: {c} = {table[c].iloc[i]!r} is not a finite number"
            )
        table[c] = values
    return table
