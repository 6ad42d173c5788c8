"""Measured test cuts (stable / chatter) from CSV, for overlaying on stability charts.

Format: a header row naming the columns with their units, then one cut per row::

    spindle_rpm,depth_mm,result
    1500,2.0,stable
    1500,3.5,chatter

The depth column may be ``depth_mm`` or ``depth_m``; ``result`` is ``stable`` or ``chatter``
(case-insensitive; ``1``/``0`` and ``true``/``false`` for chatter also accepted).

Test cuts at poses (issue 39: updating the pose model's forecast) add the columns ``x_mm``,
``y_mm`` and ``rz_deg`` (all three, or none)::

    x_mm,y_mm,rz_deg,spindle_rpm,depth_mm,result
    2400,0,45,1750,2.0,stable
"""

from __future__ import annotations

import csv
import io
from dataclasses import dataclass
from pathlib import Path

import numpy as np

__all__ = ["MeasuredCuts", "read_cuts_csv"]


@dataclass(frozen=True)
class MeasuredCuts:
    """Test cuts: speeds [rpm], axial depths [m], chatter observed (bool), all (n,).

    Attributes
    ----------
    spindle_rpm
        Spindle speeds [rpm].
    depth_m
        Axial depths of cut [m].
    chatter
        Whether chatter was observed (bool).
    pose_mm_deg
        (n, 3) poses (x [mm], y [mm], Rz [deg]) of the cuts, or None when the file has none.
    """

    spindle_rpm: np.ndarray
    depth_m: np.ndarray
    chatter: np.ndarray
    pose_mm_deg: np.ndarray | None = None

    def to_dict(self) -> dict:
        doc = {
            "spindle_rpm": [float(v) for v in self.spindle_rpm],
            "depth_m": [float(v) for v in self.depth_m],
            "chatter": [bool(v) for v in self.chatter],
        }
        if self.pose_mm_deg is not None:
            doc["pose_mm_deg"] = np.asarray(self.pose_mm_deg, float).tolist()
        return doc


_TRUE = {"chatter", "unstable", "1", "true", "yes"}
_FALSE = {"stable", "0", "false", "no"}


def read_cuts_csv(path: str | Path) -> MeasuredCuts:
    """Read measured cuts (module docs); raises ``ValueError`` naming the bad row or column.

    Parameters
    ----------
    path : str or pathlib.Path
        The CSV file (``spindle_rpm``, a depth column with its unit, ``result``).

    Returns
    -------
    MeasuredCuts
        The cuts, depths in metres.
    """
    from ..files.safe_read import read_bytes_checked

    p = Path(path)
    raw = read_bytes_checked(p, "cuts file")  # a regular file below the size limit
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise ValueError(
            f"{p}: not a text (UTF-8) cuts file: byte {exc.start} cannot be decoded"
        ) from None
    lines = io.StringIO(text, newline="")
    try:
        rows = list(csv.reader(ln for ln in lines if ln.strip() and not ln.startswith("#")))
    except csv.Error as exc:
        raise ValueError(f"{p}: not a readable CSV table ({exc})") from None
    if not rows:
        raise ValueError(f"{p}: empty cuts file")
    header = [h.strip().lower() for h in rows[0]]
    if "spindle_rpm" not in header or "result" not in header:
        raise ValueError(
            f"{p}: header must name spindle_rpm, depth_mm (or depth_m) and result, got {header}"
        )
    if "depth_mm" in header:
        dcol, scale = header.index("depth_mm"), 1e-3
    elif "depth_m" in header:
        dcol, scale = header.index("depth_m"), 1.0
    else:
        raise ValueError(f"{p}: no depth column with units (depth_mm or depth_m) in {header}")
    rcol, scol = header.index("result"), header.index("spindle_rpm")
    pose_names = ("x_mm", "y_mm", "rz_deg")
    given = [n for n in pose_names if n in header]
    if given and len(given) != 3:
        raise ValueError(f"{p}: give all of x_mm, y_mm, rz_deg for cuts at poses, got {given}")
    pcols = [header.index(n) for n in given]
    rpm, depth, chat, poses = [], [], [], []
    for i, row in enumerate(rows[1:], start=2):
        if len(row) != len(header):
            raise ValueError(
                f"{p}, line {i}: {len(row)} cells, expected {len(header)} like the header "
                f"({', '.join(header)})"
            )
        try:
            s, d = float(row[scol]), float(row[dcol]) * scale
        except (ValueError, IndexError) as exc:
            raise ValueError(f"{p}, line {i}: cannot read speed/depth from {row}") from exc
        if not (np.isfinite(s) and s > 0 and np.isfinite(d) and d > 0):
            raise ValueError(f"{p}, line {i}: speed [rpm] and depth must be positive, got {row}")
        r = row[rcol].strip().lower()
        if r not in _TRUE | _FALSE:
            raise ValueError(
                f"{p}, line {i}: result must be 'stable' or 'chatter', got {row[rcol]!r}"
            )
        if pcols:
            try:
                pose = [float(row[c]) for c in pcols]
            except (ValueError, IndexError) as exc:
                raise ValueError(
                    f"{p}, line {i}: cannot read x_mm, y_mm, rz_deg from {row}"
                ) from exc
            if not np.all(np.isfinite(pose)):
                raise ValueError(f"{p}, line {i}: pose must be finite, got {row}")
            poses.append(pose)
        rpm.append(s)
        depth.append(d)
        chat.append(r in _TRUE)
    if not rpm:
        raise ValueError(f"{p}: no cuts")
    return MeasuredCuts(
        np.array(rpm), np.array(depth), np.array(chat, bool), np.array(poses) if pcols else None
    )
