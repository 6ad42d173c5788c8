"""Checks of a multi-mode table (``modes.csv``) before anything is fitted to it (issue 38).

A modes table is something engineers edit and send to each other. Damage that used to pass
quietly into a pose model, and what :func:`check_modes_table` does with it:

* a missing column (``row``, the recording key, above all) — refused, the column named;
* a blank ``mode_id`` (an untracked mode; ``track_modes`` writes them) — left out of the fit,
  every such line named in a warning;
* a non-finite or non-physical value (fn or k <= 0, c < 0) — refused, file line and column;
* the same (recording, mode) twice with different values — refused, both lines named (they
  used to be averaged); identical copies are counted once, with a warning;
* crossed labels: a mode id whose natural frequency falls into two separated clusters over
  the recordings (the mode-switch test of :func:`robovib.gp.detect_mode_switch`, rules 1-3)
  — refused, the lines of the smaller cluster named;
* an outlier against the mode's own spread: more than :data:`OUTLIER_ROBUST_Z` robust standard
  deviations (1.4826 MAD of the log value) *and* more than a factor
  (:data:`OUTLIER_MIN_FACTOR`: 2 in fn, 30 in k and c, whose fields vary more) from the mode's
  median — refused, line and column named. One fn of 1e6 Hz among 20 Hz modes made the GP
  predict fn = -26 449 Hz at an ordinary pose.

:func:`check_modal_table` applies the same care to the dominant-mode table (``modal.csv``):
non-physical values, one recording twice with different values, and gross outliers (a factor
10 in fn: a switch of the dominant mode, 3-4x, passes) are refused.

Every error and warning names the file, the line and the column (a DataFrame: its row number).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = [
    "DOMINANT_OUTLIER_MIN_FACTOR",
    "OUTLIER_MIN_FACTOR",
    "OUTLIER_ROBUST_Z",
    "ModesTableCheck",
    "check_modal_table",
    "check_modes_table",
]

#: Robust z (|log value - median| / (1.4826 MAD)) beyond which a value may be an outlier.
OUTLIER_ROBUST_Z = 10.0
#: ... and the factor from the mode's median it must also exceed, per quantity.
OUTLIER_MIN_FACTOR = {"fn_hz": 2.0, "stiffness_n_per_m": 30.0, "damping_ns_per_m": 30.0}
#: The same for the dominant mode of a direction (``modal.csv``), which may switch to another
#: mode of the arm (Table A1: 15-23 Hz and 61-65 Hz in X): only values no switch explains.
DOMINANT_OUTLIER_MIN_FACTOR = {"fn_hz": 10.0, "stiffness_n_per_m": 300.0, "damping_ns_per_m": 300.0}
_VALUES = ("fn_hz", "stiffness_n_per_m", "damping_ns_per_m")
_SHOWN = 6  # lines named in one message


@dataclass(frozen=True)
class ModesTableCheck:
    """A checked modes table.

    Attributes
    ----------
    table : pandas.DataFrame
        The rows to fit: tracked (non-blank ``mode_id``), one per (recording, mode id).
    warnings : tuple of str
        What was left out or merged, with file and lines.
    """

    table: object
    warnings: tuple[str, ...]


def _where(source: str, lines, idx) -> str:
    shown = [str(int(lines[i])) for i in idx[:_SHOWN]]
    more = f" and {len(idx) - _SHOWN} more" if len(idx) > _SHOWN else ""
    word = "line" if len(idx) == 1 else "lines"
    return f"{source} {word} {', '.join(shown)}{more}"


def _refuse_outliers(group, what: str, source: str, lines, factors) -> None:
    """Refuse a value far from its group's median in robust std and in ratio (line, column)."""
    idx = group.index.to_numpy()
    for c in _VALUES:
        v = np.log(group[c].to_numpy(float))
        med = float(np.median(v))
        spread = max(1.4826 * float(np.median(np.abs(v - med))), 0.01)
        z = np.abs(v - med) / spread
        far = np.flatnonzero((z > OUTLIER_ROBUST_Z) & (np.abs(v - med) > np.log(factors[c])))
        if far.size:
            raise ValueError(
                f"{_where(source, lines, idx[far])} column {c}: {np.exp(v[far[0]]):.4g} is an "
                f"outlier of {what} (median {np.exp(med):.4g}, {z[far[0]]:.0f} robust std away): "
                "correct or remove it"
            )


def _refuse_nonphysical(table, source: str, lines) -> None:
    """Refuse a non-finite value, fn or k <= 0 or c < 0 (line and column)."""
    for c in _VALUES:
        v = table[c].to_numpy(float)
        bad = np.flatnonzero(~np.isfinite(v) | ((v < 0) if c == "damping_ns_per_m" else (v <= 0)))
        if bad.size:
            need = ">= 0" if c == "damping_ns_per_m" else "> 0"
            raise ValueError(
                f"{_where(source, lines, table.index.to_numpy()[bad])} column {c}: "
                f"{float(v[bad[0]])!r} is not a finite value {need} (SI)"
            )


def check_modal_table(table, *, source: str = "modal table", lines=None) -> None:
    """Refuse non-physical values and gross outliers of a dominant-mode table (``modal.csv``).

    A value is refused where it is non-finite, fn or k <= 0 or c < 0, or more than
    :data:`OUTLIER_ROBUST_Z` robust std *and* a factor :data:`DOMINANT_OUTLIER_MIN_FACTOR`
    (10 in fn) from the direction's median: a dominant-mode switch (3-4x in fn) passes, a
    1e6 Hz typo does not. Rows with an empty value (unobserved) are left to the fit.

    Parameters
    ----------
    table : pandas.DataFrame
        ``direction`` and the fn, k, c columns.
    source : str
        The file's name, used in every message.
    lines : sequence of int, optional
        File line of each row (default: row numbers counted from 2).

    Raises
    ------
    ValueError
        The file, line(s) and column of the first bad value.

    Examples
    --------
    >>> import pandas as pd
    >>> from robovib.campaign.table_checks import check_modal_table
    >>> t = pd.DataFrame({"direction": "x", "fn_hz": [20.0, 21, 19, 22, 63, 20.5, 1e6],
    ...                   "stiffness_n_per_m": 3e6, "damping_ns_per_m": 7e3})
    >>> check_modal_table(t, source="modal.csv")
    Traceback (most recent call last):
    ...
    ValueError: modal.csv line 8 column fn_hz: 1e+06 is an outlier of direction x ...
    """
    n = len(table)
    lines = np.arange(2, n + 2) if lines is None else np.asarray(lines, int)
    if "direction" not in table.columns or any(c not in table.columns for c in _VALUES):
        return  # the caller names missing columns
    table = table.reset_index(drop=True)
    full = table[table[list(_VALUES)].notna().all(axis=1).to_numpy()]
    _refuse_nonphysical(full, source, lines)
    if "row" in full.columns:  # one recording, one direction: one dominant mode
        _refuse_conflicting_duplicates(full, ["row", "direction"], source, lines)
    for d, g in full.groupby("direction", sort=True):
        _refuse_outliers(g, f"direction {d}", source, lines, DOMINANT_OUTLIER_MIN_FACTOR)


def _cell_text(v) -> str:
    """A key cell as written (a recording number read as a float is shown as ``4``)."""
    try:
        f = float(v)
    except (TypeError, ValueError):
        return str(v)
    return str(int(f)) if f.is_integer() else str(v)


def _refuse_conflicting_duplicates(table, keys, source, lines) -> list[int]:
    """Refuse rows sharing ``keys`` with different values; return the identical extra copies."""
    key = table[keys].apply(lambda col: col.map(_cell_text))
    repeated = key.duplicated(keep=False).to_numpy()
    drop: list[int] = []
    if not repeated.any():
        return drop
    for vals_key, g in table[repeated].groupby([key[c][repeated] for c in keys], sort=False):
        vals = g[list(_VALUES)].to_numpy(float)
        if not np.allclose(vals, vals[0], rtol=1e-9, atol=0.0):
            diff = [c for j, c in enumerate(_VALUES) if not np.allclose(vals[:, j], vals[0, j])]
            what = ", ".join(f"{k} {v}" for k, v in zip(keys, vals_key, strict=True))
            raise ValueError(
                f"{_where(source, lines, g.index.to_numpy())}: {what} appears twice with "
                f"different {', '.join(diff)} (column {diff[0]}): keep one"
            )
        drop.extend(g.index[1:].tolist())
    return drop


def check_modes_table(
    table, *, source: str = "mode table", lines=None, inputs=("x_mm", "y_mm", "rz_deg")
) -> ModesTableCheck:
    """Check a modes table (module docstring); return the rows to fit and the warnings.

    Parameters
    ----------
    table : pandas.DataFrame
        The table as read (``row``, ``direction``, ``mode_id``, fn, k, c and the pose columns).
    source : str
        The file's name, used in every message.
    lines : sequence of int, optional
        File line of each row of ``table`` (:attr:`robovib.files.csv_table.CsvTable.lines`);
        default: row numbers counted from 2 (a header on line 1).
    inputs : sequence of str
        Pose columns the fit will use.

    Returns
    -------
    ModesTableCheck
        The tracked rows, deduplicated, and the warnings.

    Raises
    ------
    ValueError
        A missing column, a bad value, conflicting duplicates, crossed labels or an outlier:
        file, line(s) and column named.

    Examples
    --------
    >>> import pandas as pd
    >>> from robovib.campaign.table_checks import check_modes_table
    >>> t = pd.DataFrame({"row": [2, 2, 3], "direction": "x", "x_mm": [2100.0, 2100, 2200],
    ...     "mode_id": ["x1", "", "x1"], "fn_hz": [20.0, 41.0, 20.5],
    ...     "stiffness_n_per_m": 3e6, "damping_ns_per_m": 7e3})
    >>> check = check_modes_table(t, source="modes.csv", inputs=("x_mm",))
    >>> len(check.table), check.warnings[0][:45]
    (2, 'modes.csv line 3: blank mode_id (an untracked')
    """
    from ..gp.mode_switch import detect_mode_switch

    cols = ("row", "direction", "mode_id", *_VALUES, *inputs)
    missing = [c for c in cols if c not in table.columns]
    if missing:
        why = {
            "row": "the recording key: one value per recording, as campaign process writes it",
            "mode_id": "written by campaign process --modes-band (track_modes)",
        }
        raise ValueError(
            f"{source}: no column "
            + "; no column ".join(f"{c}" + (f" ({why[c]})" if c in why else "") for c in missing)
        )
    n = len(table)
    lines = np.arange(2, n + 2) if lines is None else np.asarray(lines, int)
    if lines.shape != (n,):
        raise ValueError(f"lines must give one file line per row ({n}), got {lines.shape}")
    table = table.reset_index(drop=True).assign(_line=lines)
    warnings: list[str] = []

    for c in ("row", "direction", *inputs):
        v = table[c]
        bad = np.flatnonzero(v.isna().to_numpy() | (v.astype(str).str.strip() == "").to_numpy())
        if bad.size:
            raise ValueError(f"{_where(source, lines, bad)}: column {c} is empty")
    ids = table["mode_id"].astype("string").fillna("").str.strip().astype(str)
    blank = np.flatnonzero((ids == "").to_numpy())
    if blank.size:
        fns = ", ".join(f"{v:.4g}" for v in table["fn_hz"].to_numpy(float)[blank[:_SHOWN]])
        warnings.append(
            f"{_where(source, lines, blank)}: blank mode_id (an untracked mode, fn {fns} Hz"
            f"{' ...' if blank.size > _SHOWN else ''}): left out of the fit"
        )
    table = table.assign(mode_id=ids)[ids != ""].reset_index(drop=True)
    lines = table["_line"].to_numpy(int)

    _refuse_nonphysical(table, source, lines)

    drop = _refuse_conflicting_duplicates(table, ["row", "mode_id"], source, lines)
    if drop:
        warnings.append(
            f"{_where(source, lines, np.array(drop))}: repeat an identical (row, mode_id) "
            "row: counted once"
        )
        table = table.drop(index=drop).reset_index(drop=True)
        lines = table["_line"].to_numpy(int)

    for k, g in table.groupby("mode_id", sort=True):
        idx = g.index.to_numpy()
        fn = g["fn_hz"].to_numpy(float)
        det = detect_mode_switch(fn, direction=str(k))
        if det.found:
            high = fn > det.threshold_hz
            small = high if high.sum() <= (~high).sum() else ~high
            if small.sum() >= 2:
                lo_hz, hi_hz = np.exp(np.log(fn[~high]).mean()), np.exp(np.log(fn[high]).mean())
                raise ValueError(
                    f"{_where(source, lines, idx[small])} column mode_id: crossed labels: mode "
                    f"{k}'s fn falls in two clusters ({lo_hz:.4g} Hz at {int((~high).sum())} and "
                    f"{hi_hz:.4g} Hz at {int(high.sum())} recordings); the lines named hold "
                    "another mode: relabel them"
                )
        _refuse_outliers(g, f"mode {k}", source, lines, OUTLIER_MIN_FACTOR)
    return ModesTableCheck(table.drop(columns="_line"), tuple(warnings))
