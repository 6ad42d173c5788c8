"""FRFs as CSV: the common export of modal-analysis software (frequency, real, imaginary).

Layout (read by :func:`robovib.io.read_table`, so spreadsheet exports with ``;`` and decimal
commas work too): optional ``#`` comment lines, a header naming each column with its unit, one
row per frequency::

    frequency_hz,real_m_per_n,imag_m_per_n[,coherence]

or several directions side by side (one frequency axis)::

    frequency_hz,x_real_m_per_n,x_imag_m_per_n,y_real_m_per_n,y_imag_m_per_n

Units (the same for the real and imaginary column of one FRF) and what they are read as:

* compliance: ``m_per_n``, ``mm_per_n``, ``um_per_n``
* mobility: ``m_per_s_per_n``, ``mm_per_s_per_n``
* accelerance: ``m_per_s2_per_n``, ``g_per_n``

Values are converted to SI at the edge; mobility and accelerance are converted to compliance
(divided by ``i w`` / ``-w^2``) unless ``compliance=False``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ..files.safe_write import atomic_output
from ..frf.core import FRF

__all__ = ["FRF_CSV_UNITS", "check_frf_has_phase", "read_frf_csv", "write_frf_csv"]

#: Largest |imaginary part| relative to max |H| at which an FRF counts as phase-free.
PHASE_FREE_TOLERANCE = 1e-9


def check_frf_has_phase(frf: FRF, where: str) -> FRF:
    """Refuse an FRF without phase: a real-valued or magnitude-only one (issue 38).

    A measured FRF is complex: near a resonance its imaginary part is as large as its
    magnitude. One whose imaginary part is zero at every frequency is a magnitude (or real
    part) export; stability limits computed from it are wrong without a word (a minimum stable
    depth of 80.7 mm against 9.76 mm from the complex FRF).

    Parameters
    ----------
    frf : FRF
        The FRF as read.
    where : str
        The file (and record) named in the error.

    Returns
    -------
    FRF
        ``frf``, unchanged.

    Raises
    ------
    ValueError
        The imaginary part is zero (to :data:`PHASE_FREE_TOLERANCE` of max |H|) everywhere.
    """
    v = np.asarray(frf.values)
    peak = float(np.max(np.abs(v))) if v.size else 0.0
    name = f"FRF{f' {frf.direction}' if frf.direction else ''}"
    if peak == 0.0:
        raise ValueError(f"{where}: the {name} is zero at every frequency: nothing was measured")
    if np.all(np.abs(np.imag(v)) <= PHASE_FREE_TOLERANCE * peak):
        raise ValueError(
            f"{where}: {name} has no phase (its imaginary part is zero at every frequency): a "
            "real-valued or magnitude-only FRF gives wrong modes and stability limits; export "
            "the complex FRF (real and imaginary parts)"
        )
    return frf


_G = 9.80665
#: CSV unit suffix -> (FRF quantity, factor to SI).
FRF_CSV_UNITS: dict[str, tuple[str, float]] = {
    "m_per_n": ("compliance", 1.0),
    "mm_per_n": ("compliance", 1e-3),
    "um_per_n": ("compliance", 1e-6),
    "m_per_s_per_n": ("mobility", 1.0),
    "mm_per_s_per_n": ("mobility", 1e-3),
    "m_per_s2_per_n": ("accelerance", 1.0),
    "g_per_n": ("accelerance", _G),
}
_SI_SUFFIX = {"compliance": "m_per_n", "mobility": "m_per_s_per_n", "accelerance": "m_per_s2_per_n"}


def _split(name: str, part: str, where: str) -> tuple[str | None, str]:
    """``[d_]real_<unit>`` -> (direction or None, unit)."""
    head, _, unit = name.partition(f"{part}_")
    direction = head.rstrip("_") or None
    if direction not in (None, "x", "y", "z"):
        raise ValueError(f"{where}: column {name!r}: direction prefix must be x_, y_ or z_")
    if unit not in FRF_CSV_UNITS:
        raise ValueError(
            f"{where}: column {name!r}: unknown unit {unit!r}; use one of "
            f"{', '.join(FRF_CSV_UNITS)}"
        )
    return direction, unit


def read_frf_csv(
    path: str | Path,
    *,
    direction: str | None = None,
    compliance: bool = True,
    min_frequency_hz: float | None = None,
) -> list[FRF]:
    """Read FRFs from CSV (module docs for the layout and units).

    Parameters
    ----------
    path
        The CSV file.
    direction
        Direction (x, y, z) of an FRF whose columns carry no prefix.
    compliance
        Convert mobility and accelerance to compliance [m/N] (default); else keep their
        quantity (SI: m/s/N, m/s²/N).
    min_frequency_hz
        Lowest frequency kept when converting to compliance [Hz] (default: the lowest
        positive frequency of the file; 0 Hz cannot be converted).

    Returns
    -------
    list of FRF
        One per direction, in column order; ``source="EMA"``, ``meta["file"]`` the file name.

    Raises
    ------
    ValueError
        No such file, no header / no ``frequency_hz`` column, a line with another number of
        cells than the header (:func:`robovib.io.read_table`, which reads the file: ``;`` and
        decimal commas too), a real column without its imaginary one (or units that differ
        between them), unknown unit or direction, a cell that is not a finite number (the
        column and line are named), frequencies not strictly increasing, coherence outside
        [0, 1], an FRF without phase (imaginary column zero: :func:`check_frf_has_phase`).
    OSError
        The file cannot be read.

    Examples
    --------
    >>> from robovib.datasets import example_path
    >>> from robovib.io import read_frf_csv
    >>> (frf,) = read_frf_csv(example_path("frf.csv"))  # frequency_hz,x_real_um_per_n,...
    >>> frf.direction, frf.quantity, frf.df_hz
    ('x', 'compliance', 0.25)
    """
    from ..files.csv_table import read_table

    p = Path(path)
    where = str(p)
    table = read_table(p, what="FRF CSV", comment="#")  # the one CSV reader (sniffed layout)
    header = list(table.header)
    if "frequency_hz" not in header:
        raise ValueError(
            f"{where}: no frequency_hz column in the header {header} (frequency in Hz)"
        )
    data: dict[str, np.ndarray] = {}
    for j, name in enumerate(header):
        col = np.empty(len(table.rows))
        for k, row in enumerate(table.rows):
            line = table.lines[k]
            try:
                v = float(row[j])
            except ValueError:
                raise ValueError(
                    f"{where}, line {line}: column {name!r}: {row[j]!r} is not a number"
                ) from None
            if not math.isfinite(v):
                raise ValueError(f"{where}, line {line}: column {name!r}: {v} is not finite")
            col[k] = v
        data[name] = col
    f = data["frequency_hz"]
    if f.size < 2 or np.any(np.diff(f) <= 0):
        raise ValueError(
            f"{where}: column 'frequency_hz' must hold >= 2 strictly increasing values"
        )
    reals = [h for h in header if "real_" in h]
    if not reals:
        raise ValueError(f"{where}: no real_<unit> column in {header} (e.g. real_m_per_n)")
    out = []
    for rname in reals:
        d, unit = _split(rname, "real", where)
        prefix = rname.split("real_")[0]
        iname = f"{prefix}imag_{unit}"
        if iname not in header:
            other = [h for h in header if h.startswith(f"{prefix}imag_")]
            if other:
                raise ValueError(f"{where}: columns {rname!r} and {other[0]!r} must have one unit")
            raise ValueError(f"{where}: column {rname!r} has no imaginary column {iname!r}")
        if d is not None and direction is not None and d != direction:
            raise ValueError(f"{where}: column {rname!r} is direction {d}, not {direction}")
        d = d or direction
        if d not in (None, "x", "y", "z"):
            raise ValueError(f"unknown direction {d!r}; use x, y or z")
        quantity, factor = FRF_CSV_UNITS[unit]
        coh_name = f"{d}_coherence" if f"{d}_coherence" in header else "coherence"
        coh = data.get(coh_name)
        if coh is not None and (np.any(coh < 0) or np.any(coh > 1)):
            raise ValueError(f"{where}: column {coh_name!r} must lie in [0, 1]")
        frf = FRF(f, factor * (data[rname] + 1j * data[iname]), coherence=coh, quantity=quantity,
                  direction=d, source="EMA", meta={"file": p.name})  # fmt: skip
        check_frf_has_phase(frf, f"{where}: columns {rname!r}, {iname!r}")
        if compliance and quantity != "compliance":
            fmin = min_frequency_hz if min_frequency_hz is not None else float(f[f > 0][0])
            frf = frf.to_compliance(fmin)
        out.append(frf)
    return out


def write_frf_csv(
    path: str | Path,
    frfs: FRF | Sequence[FRF],
    *,
    unit: str | None = None,
    inputs=(),
    force: bool = False,
) -> None:
    """Write FRFs as CSV (atomic): one FRF without prefix, several with ``x_``/``y_``/``z_``.

    Parameters
    ----------
    path
        Output file.
    frfs
        One FRF, or several of one quantity on one frequency axis with distinct directions.
    unit
        Column unit (a key of :data:`FRF_CSV_UNITS` of the FRFs' quantity); default SI.
    inputs, force
        See :func:`robovib.io.atomic_output`.

    Raises
    ------
    ValueError
        No FRF, mixed quantities or frequency axes, missing/duplicate directions for several
        FRFs, a unit of another quantity.
    """
    frfs = [frfs] if isinstance(frfs, FRF) else list(frfs)
    if not frfs:
        raise ValueError("no FRF to write")
    quantity = frfs[0].quantity
    unit = unit or _SI_SUFFIX[quantity]
    if unit not in FRF_CSV_UNITS or FRF_CSV_UNITS[unit][0] != quantity:
        ok = [u for u, (q, _) in FRF_CSV_UNITS.items() if q == quantity]
        raise ValueError(f"unit {unit!r} is not a {quantity} unit; use one of {', '.join(ok)}")
    f = frfs[0].frequency_hz
    for g in frfs[1:]:
        if (
            g.quantity != quantity
            or g.frequency_hz.shape != f.shape
            or not np.allclose(g.frequency_hz, f)
        ):
            raise ValueError("FRFs written to one CSV need one quantity and one frequency axis")
    if len(frfs) > 1:
        dirs = [g.direction for g in frfs]
        if None in dirs or len(set(dirs)) != len(dirs):
            raise ValueError(f"several FRFs in one CSV need distinct directions, got {dirs}")
        prefixes = [f"{d}_" for d in dirs]
    else:
        prefixes = [f"{frfs[0].direction}_" if frfs[0].direction else ""]
    scale = 1.0 / FRF_CSV_UNITS[unit][1]
    cols, names = [f], ["frequency_hz"]
    for pre, g in zip(prefixes, frfs, strict=True):
        cols += [scale * g.values.real, scale * g.values.imag]
        names += [f"{pre}real_{unit}", f"{pre}imag_{unit}"]
        if g.coherence is not None:
            cols.append(g.coherence)
            names.append(f"{pre}coherence")
    table = np.column_stack(cols)
    with atomic_output(path, inputs=inputs, force=force) as tmp, open(tmp, "w") as fh:
        fh.write(",".join(names) + "\n")
        for row in table:
            fh.write(",".join(f"{v:.12g}" for v in row) + "\n")
