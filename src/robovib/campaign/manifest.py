"""The campaign manifest: one CSV row per hammer recording and direction, with the pose.

Layout (header names exact, order free)::

    file,direction,x_mm,y_mm,z_mm,rz_deg[,rx_deg,ry_deg][,a1_deg..a6_deg][,replicate]
        [,force_sensitivity_mv_per_n,response_sensitivity_mv_per_unit,response_unit]

* ``file``: the recording (.csv, .uff, .unv), relative to the manifest's folder (or absolute);
* ``direction``: ``x``, ``y`` or ``z`` — the hammer and response direction (robot base frame);
* pose: tool-tip position [mm] and orientation [deg]; optional joint angles [deg];
* ``replicate``: repeat number of the same pose (default 0);
* sensitivities for voltage channels: hammer [mV/N], response [mV per ``response_unit``].

Empty optional cells mean "not given". Unknown columns are an error (a typo such as ``x_m``
would otherwise silently drop a pose coordinate).
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass, field
from pathlib import Path

__all__ = [
    "JOINT_COLUMNS",
    "OPTIONAL_POSE_COLUMNS",
    "POSE_COLUMNS",
    "CampaignRow",
    "read_manifest",
]

POSE_COLUMNS = ("x_mm", "y_mm", "z_mm", "rz_deg")
OPTIONAL_POSE_COLUMNS = ("rx_deg", "ry_deg")
JOINT_COLUMNS = tuple(f"a{i}_deg" for i in range(1, 7))
_OTHER = (
    "replicate",
    "force_sensitivity_mv_per_n",
    "response_sensitivity_mv_per_unit",
    "response_unit",
)
_REQUIRED = ("file", "direction", *POSE_COLUMNS)
_KNOWN = (*_REQUIRED, *OPTIONAL_POSE_COLUMNS, *JOINT_COLUMNS, *_OTHER)


@dataclass(frozen=True)
class CampaignRow:
    """One manifest row.

    Attributes
    ----------
    row
        Line number in the manifest (the header is line 1).
    file
        Absolute path of the recording.
    direction
        ``"x"``, ``"y"`` or ``"z"``.
    pose
        Pose columns given in the manifest -> value (mm, deg), in manifest column order.
    replicate
        Repeat number at this pose.
    force_sensitivity_mv_per_n, response_sensitivity_mv_per_unit, response_unit
        Voltage-channel sensitivities, or None.
    """

    row: int
    file: Path
    direction: str
    pose: dict = field(default_factory=dict)
    replicate: int = 0
    force_sensitivity_mv_per_n: float | None = None
    response_sensitivity_mv_per_unit: float | None = None
    response_unit: str = "g"

    def pose_tuple_si(self) -> tuple[float, ...]:
        """(X, Y, Z [m], Rx, Ry, Rz [deg]) as stored with an FRF."""
        p = self.pose
        return (
            p["x_mm"] / 1e3,
            p["y_mm"] / 1e3,
            p["z_mm"] / 1e3,
            p.get("rx_deg", 0.0),
            p.get("ry_deg", 0.0),
            p["rz_deg"],
        )


def _number(text: str, name: str, where: str, *, positive: bool = False) -> float:
    try:
        value = float(text)
    except ValueError:
        raise ValueError(f"{where}: {name} = {text!r} is not a number") from None
    if not math.isfinite(value):
        raise ValueError(f"{where}: {name} = {text!r} is not finite")
    if positive and value <= 0:
        raise ValueError(f"{where}: {name} must be positive, got {value:g}")
    return value


def read_manifest(path: str | Path) -> list[CampaignRow]:
    """Read and check a campaign manifest (layout in the module docstring).

    Parameters
    ----------
    path
        The manifest CSV; recording paths are relative to its folder.

    Returns
    -------
    list of CampaignRow

    Raises
    ------
    ValueError
        Missing/unknown columns, an unknown direction, a non-numeric or non-finite number, a
        non-positive sensitivity, a joint-angle set given only in part, or no rows; the
        message names the manifest line.
    """
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"{path}: no such manifest file")
    with path.open(newline="") as fh:
        reader = csv.reader(fh)
        try:
            header = [h.strip().lower() for h in next(reader)]
        except StopIteration:
            raise ValueError(f"{path}: empty manifest") from None
        lines = list(reader)
    missing = [c for c in _REQUIRED if c not in header]
    if missing:
        raise ValueError(f"{path}: manifest lacks column(s) {', '.join(missing)}")
    unknown = [c for c in header if c not in _KNOWN]
    if unknown:
        raise ValueError(
            f"{path}: unknown manifest column(s) {', '.join(unknown)}; known: {', '.join(_KNOWN)}"
        )
    if len(set(header)) != len(header):
        raise ValueError(f"{path}: duplicate manifest columns")
    joints = [c for c in JOINT_COLUMNS if c in header]
    if joints and len(joints) != 6:
        raise ValueError(f"{path}: joint angles need all of a1_deg..a6_deg, got {joints}")
    rows = []
    for lineno, cells in enumerate(lines, start=2):
        if not cells or all(not c.strip() for c in cells):
            continue
        where = f"{path} line {lineno}"
        if len(cells) != len(header):
            raise ValueError(f"{where}: {len(cells)} cells, expected {len(header)}")
        rec = {h: c.strip() for h, c in zip(header, cells, strict=True)}
        if not rec["file"]:
            raise ValueError(f"{where}: empty file name")
        direction = rec["direction"].lower()
        if direction not in ("x", "y", "z"):
            raise ValueError(f"{where}: unknown direction {rec['direction']!r}; use x, y or z")
        pose = {}
        for c in (*POSE_COLUMNS, *OPTIONAL_POSE_COLUMNS, *JOINT_COLUMNS):
            if c in rec:
                if not rec[c] and c not in POSE_COLUMNS:
                    continue
                pose[c] = _number(rec[c], c, where)
        fs = rec.get("force_sensitivity_mv_per_n", "")
        rs = rec.get("response_sensitivity_mv_per_unit", "")
        replicate = rec.get("replicate", "") or "0"
        try:
            rep = int(replicate)
        except ValueError:
            raise ValueError(f"{where}: replicate = {replicate!r} is not an integer") from None
        file = Path(rec["file"])
        rows.append(
            CampaignRow(
                row=lineno,
                file=file if file.is_absolute() else (path.parent / file).resolve(),
                direction=direction,
                pose=pose,
                replicate=rep,
                force_sensitivity_mv_per_n=_number(
                    fs, "force_sensitivity_mv_per_n", where, positive=True
                )
                if fs
                else None,
                response_sensitivity_mv_per_unit=_number(
                    rs, "response_sensitivity_mv_per_unit", where, positive=True
                )
                if rs
                else None,
                response_unit=rec.get("response_unit", "") or "g",
            )
        )
    if not rows:
        raise ValueError(f"{path}: manifest has no rows")
    return rows
