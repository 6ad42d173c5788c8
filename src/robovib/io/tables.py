"""CSV tables read and written by the command line: forces, path modes, milling
records and compliance tests. Column names carry their SI unit; everything returned is SI.

Writers go through a temporary file in the target folder renamed at the end (atomic).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ..modal.parameters import ModalParameters

__all__ = [
    "FORCE_COLUMNS",
    "MILLING_RECORD_COLUMNS",
    "PATH_MODE_COLUMNS",
    "read_compliance_tests_csv",
    "read_force_csv",
    "read_milling_record_csv",
    "read_path_modes_csv",
    "write_path_modes_csv",
]

FORCE_COLUMNS = ("time_s", "force_x_n", "force_y_n", "force_z_n")
PATH_MODE_COLUMNS = ("s_m", "fn_hz", "stiffness_n_per_m", "damping_ratio")
MILLING_RECORD_COLUMNS = (
    "time_s",
    "force_x_n",
    "force_y_n",
    "force_z_n",
    "displacement_x_m",
    "displacement_y_m",
    "displacement_z_m",
    "path_s_m",
)


def _atomic_write_text(path: Path, text: str, *, inputs=(), force: bool = False) -> None:
    """Atomic text output (:func:`robovib.io.atomic_output`): never output = input unless forced."""
    from ..files.safe_write import atomic_output

    with atomic_output(path, inputs=inputs, force=force) as tmp:
        tmp.write_text(text)


def _read_table(path, columns: Sequence[str], *, time_first: bool = False):
    """(DataFrame, (n, len(columns)) floats) of a CSV (:func:`robovib.files.csv_table.read_table`).

    ``time_first``: the first column is a time that must rise from line to line (2 rows or more).
    """
    from ..files.csv_table import read_table

    path = Path(path)
    table = read_table(path)
    missing = [c for c in columns if c not in table.header]
    if missing:
        raise ValueError(f"{path}: missing columns {missing} (need {', '.join(columns)})")
    data = np.column_stack([table.numbers(c, allow_empty=True) for c in columns])
    bad = ~np.isfinite(data)
    if bad.any():
        r, c = np.argwhere(bad)[0]
        raise ValueError(f"{path} line {table.lines[r]}: {columns[c]} is empty, NaN or inf")
    if time_first:
        if len(data) < 2:
            raise ValueError(f"{path}: {len(data)} sample; a record needs 2 or more")
        stuck = np.flatnonzero(np.diff(data[:, 0]) <= 0)
        if stuck.size:
            i = int(stuck[0]) + 1
            raise ValueError(
                f"{path} line {table.lines[i]}: {columns[0]} = {data[i, 0]:.9g} does not rise "
                f"after {data[i - 1, 0]:.9g} (line {table.lines[i - 1]}): the time must increase"
            )
    return table.to_frame(), data


def _header(path) -> tuple[str, ...]:
    from ..files.csv_table import read_table

    return read_table(path).header


def read_force_csv(path: str | Path) -> tuple[np.ndarray, np.ndarray]:
    """Measured cutting forces: columns ``time_s, force_x_n, force_y_n, force_z_n``.

    Returns
    -------
    time_s
        (n,) sample times [s].
    force_n
        (n, 3) forces in the base frame [N].

    Parameters
    ----------
    path : str or pathlib.Path
        The CSV file.

    Raises
    ------
    ValueError
        Missing column, NaN or inf, fewer than 2 rows, a time that does not rise.
    """
    _, data = _read_table(path, FORCE_COLUMNS, time_first=True)
    return data[:, 0], data[:, 1:]


def read_path_modes_csv(path: str | Path) -> tuple[np.ndarray, list[ModalParameters]]:
    """Dominant modes along a path: columns ``s_m, fn_hz, stiffness_n_per_m, damping_ratio``.

    Returns
    -------
    s_m
        (n,) path coordinates [m].
    modes
        One :class:`~robovib.modal.ModalParameters` per row.

    Parameters
    ----------
    path : str or pathlib.Path
        The CSV file.

    Raises
    ------
    ValueError
        Missing column, NaN/inf, or a non-physical mode.
    """
    _, data = _read_table(path, PATH_MODE_COLUMNS)
    modes = []
    for i, (_, fn, k, z) in enumerate(data, start=1):
        try:
            modes.append(ModalParameters(fn, k, z))
        except ValueError as exc:  # which row of which file
            raise ValueError(f"{path}, data row {i}: {exc}") from None
    return data[:, 0], modes


def write_path_modes_csv(
    path: str | Path, s_m, modes: Sequence[ModalParameters], *, inputs=(), force: bool = False
) -> None:
    """Write the table :func:`read_path_modes_csv` reads.

    Parameters
    ----------
    path : str or pathlib.Path
        The CSV file to write.
    s_m : array_like
        (n,) path coordinates [m].
    modes : sequence of ModalParameters
        One mode per coordinate.
    inputs : sequence of path
        Files the output was made from (never overwritten unless ``force``).
    force : bool
        Allow ``path`` to be one of ``inputs``.

    Raises
    ------
    ValueError
        ``s_m`` and ``modes`` of different lengths.
    """
    s = np.asarray(s_m, float).ravel()
    if s.size != len(modes):
        raise ValueError(f"{s.size} path coordinates but {len(modes)} modes")
    lines = [",".join(PATH_MODE_COLUMNS)]
    lines.extend(
        f"{si:.12g},{m.natural_frequency_hz:.12g},{m.stiffness_n_per_m:.12g},{m.damping_ratio:.12g}"
        for si, m in zip(s, modes, strict=True)
    )
    _atomic_write_text(Path(path), "\n".join(lines) + "\n", inputs=inputs, force=force)


def read_milling_record_csv(path: str | Path) -> dict[str, np.ndarray]:
    """Synchronised milling record along a path (e.g. ``robovib sim mill --path-s-from ...``).

    Columns ``time_s, force_{x,y,z}_n, displacement_{x,y,z}_m`` and either ``path_s_m`` (a cut
    along the chapter-4 path) or ``x_m, y_m, rz_deg`` (a cut in the workspace).

    Returns
    -------
    dict
        ``time_s`` (n,), ``force_n`` (n, 3) [N], ``displacement_m`` (n, 3) [m], and
        ``path_s_m`` (n,) [m] or ``pose`` (n, 3) [m, m, deg].

    Parameters
    ----------
    path : str or pathlib.Path
        The CSV file.

    Raises
    ------
    ValueError
        Missing column, NaN or inf.
    """
    head = _header(path)
    if "path_s_m" not in head and all(c in head for c in ("x_m", "y_m", "rz_deg")):
        cols = (*MILLING_RECORD_COLUMNS[:-1], "x_m", "y_m", "rz_deg")
        _, d = _read_table(path, cols, time_first=True)
        return {"time_s": d[:, 0], "force_n": d[:, 1:4], "displacement_m": d[:, 4:7],
                "pose": d[:, 7:10]}  # fmt: skip
    _, d = _read_table(path, MILLING_RECORD_COLUMNS, time_first=True)
    return {
        "time_s": d[:, 0],
        "force_n": d[:, 1:4],
        "displacement_m": d[:, 4:7],
        "path_s_m": d[:, 7],
    }


def read_compliance_tests_csv(path: str | Path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Static compliance tests: ``a1_deg..a6_deg, fx_n, fy_n, fz_n, mx_nm, my_nm, mz_nm,
    dx_m, dy_m, dz_m`` and optionally ``rx_rad, ry_rad, rz_rad``.

    Returns
    -------
    joints_deg
        (n, 6) joint angles [deg].
    wrench
        (n, 6) applied force [N] and moment [N m].
    displacement
        (n, 3) or (n, 6) measured translation [m] (and rotation [rad]).

    Parameters
    ----------
    path : str or pathlib.Path
        The CSV file.

    Raises
    ------
    ValueError
        Missing column, NaN or inf.
    """
    cols = [f"a{i}_deg" for i in range(1, 7)] + ["fx_n", "fy_n", "fz_n", "mx_nm", "my_nm", "mz_nm"]
    cols += ["dx_m", "dy_m", "dz_m"]
    header = _header(path)
    if "rx_rad" in header:
        cols += ["rx_rad", "ry_rad", "rz_rad"]
    _, d = _read_table(path, cols)
    return d[:, :6], d[:, 6:12], d[:, 12:]
