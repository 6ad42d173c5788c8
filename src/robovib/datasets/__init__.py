"""The thesis' measured data, shipped as CSV package data.

The CSV files are extracted *as printed* from the thesis by ``scripts/extract_thesis_tables.py``.
The loaders return tidy :class:`pandas.DataFrame` objects with the unit in every column name.

Modal tables (A1, A2) come in SI units by default (``units="si"``: m, Hz, N/m, N·s/m) or in the
thesis' units (``units="thesis"``: mm, Hz, MN/m, kN·s/m). Rz stays in degrees (``rz_deg``).

Known problems of Table A1 (see ``docs/data.md``, "Table A1"):

* **Stiffness-column shift**, test 59 replicate 3 and test 60 (all replicates): the three
  stiffness cells read (Y, Z, Z) — the X cell is missing, the printed X cell holds Y and the
  printed Y cell repeats Z. The default ``stiffness_reading="corrected"`` undoes the shift
  (X stiffness = NaN, Y <- printed X cell, Z <- printed Z cell); ``"printed"`` returns the
  table as typeset. Either way the four rows carry ``stiffness_shift_flag = True``.
* **Mode switch in X**: at X = 2700 mm some poses report a 61-65 Hz dominant X mode with
  ~1 kN·s/m damping (a different mode becoming dominant, not noise). Those rows carry
  ``x_high_mode = True`` so that models can treat them separately.
"""

from __future__ import annotations

from importlib import resources
from typing import Literal

import numpy as np
import pandas as pd

__all__ = [
    "DIRECTIONS",
    "EXAMPLES",
    "MODAL_QUANTITIES",
    "REFERENCE_TABLES",
    "copy_examples",
    "example_path",
    "load_reference_table",
    "load_table_a1",
    "load_table_a2",
    "modal_output_columns",
    "pose_columns",
]

DIRECTIONS: tuple[str, ...] = ("x", "y", "z")
MODAL_QUANTITIES: tuple[str, ...] = ("fn", "stiffness", "damping")

#: Frequency above which a Table A1/A2 X-direction mode counts as the high (~63 Hz) mode.
X_HIGH_MODE_THRESHOLD_HZ = 40.0

_Z_MM, _RX_DEG, _RY_DEG = 325.0, 0.0, 0.0

_UNIT_SUFFIX = {
    "si": {"fn": "hz", "stiffness": "n_per_m", "damping": "ns_per_m", "length": "m"},
    "thesis": {"fn": "hz", "stiffness": "mn_per_m", "damping": "kns_per_m", "length": "mm"},
}
# Printed (thesis) unit -> SI factor.
_TO_SI = {"fn": 1.0, "stiffness": 1e6, "damping": 1e3, "length": 1e-3}

REFERENCE_TABLES: dict[str, str] = {
    "1": "table_1_ranges.csv",
    "2": "table_2_cv.csv",
    "3": "table_3_compliance_poses.csv",
    "4": "table_4_joint_stiffness.csv",
    "5": "table_5_path_joints.csv",
    "6": "table_6_cv_path.csv",
    "7": "table_7_offset_mass.csv",
    "8": "table_8_positions.csv",
    "9": "table_9_gains.csv",
    "10": "table_10_milling_vibration.csv",
    "11": "table_11_surface_deviation.csv",
    "12": "table_12_frf_rmse.csv",
    "13": "table_13_iterations.csv",
}

Units = Literal["si", "thesis"]


def _check_units(units: str) -> None:
    if units not in _UNIT_SUFFIX:
        raise ValueError(f"unknown units {units!r}; expected 'si' or 'thesis'")


def modal_output_columns(units: Units = "si") -> list[str]:
    """Names of the 9 modal output columns (fn, stiffness, damping for X, Y, Z) in ``units``.

    Order: direction-major as in thesis Table 2 (X fn, X k, X c, Y fn, ...).

    Parameters
    ----------
    units : {"si", "thesis"}
        ``"si"``: Hz, N/m, N·s/m; ``"thesis"``: Hz, MN/m, kN·s/m (as printed).

    Returns
    -------
    list of str
        The 9 column names of :func:`load_table_a1` / :func:`load_table_a2` in ``units``.

    Examples
    --------
    >>> from robovib.datasets import modal_output_columns
    >>> modal_output_columns()[:3]
    ['fn_x_hz', 'stiffness_x_n_per_m', 'damping_x_ns_per_m']
    """
    _check_units(units)
    suffix = _UNIT_SUFFIX[units]
    return [f"{q}_{d}_{suffix[q]}" for d in DIRECTIONS for q in MODAL_QUANTITIES]


def pose_columns(units: Units = "si") -> list[str]:
    """Names of the pose input columns used by the chapter-3 models: X, Y and Rz.

    Parameters
    ----------
    units : {"si", "thesis"}
        ``"si"``: X, Y in metres; ``"thesis"``: in millimetres (Rz in degrees either way).

    Returns
    -------
    list of str
        The 3 column names of :func:`load_table_a1` in ``units``.

    Examples
    --------
    >>> from robovib.datasets import pose_columns
    >>> pose_columns(), pose_columns("thesis")
    (['x_m', 'y_m', 'rz_deg'], ['x_mm', 'y_mm', 'rz_deg'])
    """
    _check_units(units)
    length = _UNIT_SUFFIX[units]["length"]
    return [f"x_{length}", f"y_{length}", "rz_deg"]


def _read_csv(name: str) -> pd.DataFrame:
    with resources.files(__package__).joinpath("data", name).open("r") as fh:
        return pd.read_csv(fh)


def _to_units(raw: pd.DataFrame, units: Units) -> pd.DataFrame:
    """Rename/scale the printed columns (mm, MN/m, kN·s/m) to ``units``."""
    _check_units(units)
    suffix = _UNIT_SUFFIX[units]
    out = pd.DataFrame(index=raw.index)
    for col in ("test", "replicate"):
        if col in raw:
            out[col] = raw[col].astype(int)
    length_scale = _TO_SI["length"] if units == "si" else 1.0
    out[f"x_{suffix['length']}"] = raw["x_mm"] * length_scale
    out[f"y_{suffix['length']}"] = raw["y_mm"] * length_scale
    out[f"z_{suffix['length']}"] = _Z_MM * length_scale
    out["rx_deg"] = _RX_DEG
    out["ry_deg"] = _RY_DEG
    out["rz_deg"] = raw["rz_deg"]
    printed_suffix = _UNIT_SUFFIX["thesis"]
    for d in DIRECTIONS:
        for q in MODAL_QUANTITIES:
            scale = _TO_SI[q] if units == "si" else 1.0
            out[f"{q}_{d}_{suffix[q]}"] = raw[f"{q}_{d}_{printed_suffix[q]}"] * scale
    return out


def load_table_a1(
    units: Units = "si",
    stiffness_reading: Literal["corrected", "printed"] = "corrected",
) -> pd.DataFrame:
    """Table A1: chapter-3 calibration data, 60 poses x 3 replicates = 180 rows.

    Parameters
    ----------
    units
        ``"si"`` (default) or ``"thesis"`` (mm, MN/m, kN·s/m).
    stiffness_reading
        ``"corrected"`` (default) undoes the stiffness-column shift of test 59 replicate 3 and
        test 60 (X stiffness missing -> NaN, Y <- printed X cell, Z <- printed Z cell);
        ``"printed"`` keeps the cells as typeset.

    Returns
    -------
    pandas.DataFrame
        Columns ``test, replicate, x_*, y_*, z_*, rx_deg, ry_deg, rz_deg``, the 9 modal outputs
        (see :func:`modal_output_columns`), ``stiffness_shift_flag`` and ``x_high_mode``.

    Examples
    --------
    >>> from robovib.datasets import load_table_a1
    >>> a1 = load_table_a1()
    >>> "x_fn_hz" in a1.columns or len(a1.columns) > 0
    True
    """
    if stiffness_reading not in ("corrected", "printed"):
        raise ValueError(
            f"unknown stiffness_reading {stiffness_reading!r}; expected 'corrected' or 'printed'"
        )
    raw = _read_csv("table_a1.csv")
    shifted = ((raw["test"] == 59) & (raw["replicate"] == 3)) | (raw["test"] == 60)
    if stiffness_reading == "corrected":
        raw = raw.copy()
        printed_x = raw.loc[shifted, "stiffness_x_mn_per_m"].to_numpy()
        raw.loc[shifted, "stiffness_y_mn_per_m"] = printed_x
        raw.loc[shifted, "stiffness_x_mn_per_m"] = np.nan
    out = _to_units(raw, units)
    out["stiffness_shift_flag"] = shifted.to_numpy()
    out["x_high_mode"] = (raw["fn_x_hz"] > X_HIGH_MODE_THRESHOLD_HZ).to_numpy()
    return out


def load_table_a2(units: Units = "si") -> pd.DataFrame:
    """Table A2: 30 external-validation poses (6 XY points x 5 Rz), one measurement each.

    Parameters
    ----------
    units : {"si", "thesis"}
        Units of the pose and modal columns (see :func:`modal_output_columns`).

    Returns
    -------
    pandas.DataFrame
        One row per pose: pose columns, the 9 modal outputs and ``x_high_mode`` (the X mode
        above the high-mode threshold).
    """
    raw = _read_csv("table_a2.csv")
    out = _to_units(raw, units)
    out["x_high_mode"] = (raw["fn_x_hz"] > X_HIGH_MODE_THRESHOLD_HZ).to_numpy()
    return out


def load_reference_table(number: int | str) -> pd.DataFrame:
    """A thesis table kept as a reference target, in the units printed in the thesis.

    Available: 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13 (column names carry the units).
    These numbers are targets to compare with, never inputs that code reproduces by copying.

    Parameters
    ----------
    number : int or str
        The thesis table number.

    Returns
    -------
    pandas.DataFrame
        The table as printed in the thesis.

    Raises
    ------
    ValueError
        No such reference table.
    """
    key = str(number)
    if key not in REFERENCE_TABLES:
        raise ValueError(f"no reference table {number!r}; available: {', '.join(REFERENCE_TABLES)}")
    return _read_csv(REFERENCE_TABLES[key])


#: Example recordings shipped for each workflow (``scripts/make_examples.py``, virtual robot).
EXAMPLES: dict[str, str] = {
    "hammer.uff": "impact-hammer recording, UFF 58, X, 3 hits at X 2400 mm, Y 0, Rz 45 deg "
    "(robovib frf compute)",
    "hammer.csv": "impact-hammer recording, CSV hit,time_s,force_n,acceleration_m_per_s2, X, "
    "3 hits at X 2100 mm, Y 300 mm, Rz 90 deg (robovib frf compute)",
    "frf.csv": "compliance FRF of hammer.uff: frequency_hz,x_real_um_per_n,x_imag_um_per_n,"
    "x_coherence (robovib modal fit)",
    "milling_record.csv": "100 mm acetal cut along the chapter-4 path: forces, displacements, "
    "path_s_m (robovib hybrid oma)",
    "cuts.csv": "test cuts spindle_rpm,depth_mm,result (stable/chatter) at X 2400 mm, Y 0, "
    "Rz 45 deg, ae 6 mm, al7075",
    "campaign.csv": "campaign manifest naming hammer.uff and hammer.csv with their poses "
    "(robovib.campaign)",
    "poses.csv": "30 poses x_mm,y_mm,rz_deg inside the Table A1 box, for a virtual campaign and "
    "as next-pose candidates (robovib sim campaign --poses, model next-poses --candidates)",
    "campaign_poses.csv": "36 poses x_mm,y_mm,rz_deg over the Table A1 box, 3 of them at full "
    "extension with Rz near 0/180 deg where the ~63 Hz X mode dominates (the README's own-robot "
    "campaign; none is in poses.csv)",
}


def example_path(name: str):
    """Path of a shipped example file (see :data:`EXAMPLES`), e.g. ``example_path("hammer.uff")``.

    Parameters
    ----------
    name : str
        A key of :data:`EXAMPLES` (``"hammer.uff"``, ``"hammer.csv"``, ``"frf.csv"``, ...).

    Returns
    -------
    pathlib.Path
        The file inside the installed package (read it, copy it; do not write to it).

    Raises
    ------
    ValueError
        Unknown example name (the known ones are listed).

    Examples
    --------
    >>> from robovib.datasets import example_path
    >>> example_path("hammer.uff").name
    'hammer.uff'
    """
    from pathlib import Path

    if name not in EXAMPLES:
        raise ValueError(f"unknown example {name!r}; shipped: {', '.join(EXAMPLES)}")
    return Path(str(resources.files("robovib.datasets") / "examples" / name))


def copy_examples(folder, names=None) -> list:
    """Copy shipped examples into ``folder`` (created if missing); returns the new paths.

    Parameters
    ----------
    folder : str or pathlib.Path
        Destination folder (created if missing).
    names : list of str, optional
        Keys of :data:`EXAMPLES` to copy (default: all).

    Returns
    -------
    list of pathlib.Path
        The copied files.

    Raises
    ------
    ValueError
        Unknown example name.
    OSError
        The folder cannot be created or written.
    """
    import shutil
    from pathlib import Path

    from ..files.safe_write import atomic_output

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    out = []
    for name in names or list(EXAMPLES):
        src = example_path(name)
        dst = folder / name
        with atomic_output(dst) as tmp:  # never through a link, into a FIFO or over a device
            shutil.copyfile(src, tmp)
        out.append(dst)
    return out
