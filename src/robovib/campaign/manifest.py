"""The campaign manifest: one CSV row per hammer recording and direction, with the pose.

Layout (header names exact, order free)::

    file,direction,x_mm,y_mm,z_mm,rz_deg[,rx_deg,ry_deg][,a1_deg..a6_deg][,replicate]
        [,force_sensitivity_mv_per_n,response_sensitivity_mv_per_unit,response_unit]

* ``file``: the recording (.csv, .uff, .unv), relative to the manifest's folder (or absolute);
* ``direction``: ``x``, ``y`` or ``z`` — the hammer and response direction (robot base frame);
* pose: tool-tip position [mm] and orientation [deg]; optional joint angles [deg];
* ``replicate``: repeat number of the same pose (default 0);
* sensitivities for voltage channels: hammer [mV/N], response [mV per ``response_unit``].

The file may come from a spreadsheet (BOM, ``;`` with decimal commas, tabs, ``x [mm]`` headers:
read by :func:`robovib.files.csv_table.read_table`). Rows that would count the same data twice are
errors (:func:`check_manifest_integrity`). Empty optional cells mean "not given". Unknown
columns are an error (a typo such as ``x_m``
would otherwise silently drop a pose coordinate).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

__all__ = [
    "JOINT_COLUMNS",
    "OPTIONAL_POSE_COLUMNS",
    "POSE_COLUMNS",
    "CampaignRow",
    "check_manifest_integrity",
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
        """(X, Y, Z [m], Rx, Ry, Rz [deg]) as stored with an FRF.

        Returns
        -------
        tuple of float
            The pose in SI (missing Rx, Ry: 0).
        """
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
        non-positive sensitivity, a joint-angle set given only in part, no rows, or rows that
        count the same data twice (:func:`check_manifest_integrity`); the message names the
        manifest line.
    """
    from ..files.csv_table import read_table
    from ..files.safe_read import check_input_file

    path = check_input_file(path, "manifest file")  # a regular file below the size limit
    try:
        table = read_table(path, what="manifest")
    except ValueError as exc:
        if "has a header but no data rows" in str(exc):
            raise ValueError(f"{path}: manifest has no rows") from None
        raise
    header = list(table.header)
    missing = [c for c in _REQUIRED if c not in header]
    if missing:
        raise ValueError(f"{path}: manifest lacks column(s) {', '.join(missing)}")
    unknown = [c for c in header if c not in _KNOWN]
    if unknown:
        raise ValueError(
            f"{path}: unknown manifest column(s) {', '.join(unknown)}; known: {', '.join(_KNOWN)}"
        )
    joints = [c for c in JOINT_COLUMNS if c in header]
    if joints and len(joints) != 6:
        raise ValueError(f"{path}: joint angles need all of a1_deg..a6_deg, got {joints}")
    rows = []
    for lineno, cells in zip(table.lines, table.rows, strict=True):
        where = f"{path} line {lineno}"
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
    check_manifest_integrity(rows, str(path))
    return rows


def _file_hash(path: Path) -> str | None:
    import hashlib

    if not path.is_file():
        return None  # reported when the row is processed
    h = hashlib.sha256()
    with path.open("rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def _pose_text(row: CampaignRow) -> str:
    return ", ".join(f"{k} = {v:g}" for k, v in row.pose.items())


def check_manifest_integrity(rows: list[CampaignRow], where: str = "manifest") -> None:
    """Rows that would count the same data twice, or two data sets as one, are errors.

    * a row repeated (same file, direction, pose and replicate);
    * the same recording for the same direction at two rows (at two poses, or twice at one
      pose: a replicate is a new recording);
    * two files with identical content (same SHA-256) at two rows (a copied file);
    * two different recordings at the same pose, direction and replicate number (declare
      replicates with the ``replicate`` column: 0, 1, ...).

    Parameters
    ----------
    rows
        The manifest rows (:func:`read_manifest`).
    where
        The manifest, for messages.

    Raises
    ------
    ValueError
        Naming the lines of the first conflict found and what to do.
    """
    problems = []
    seen_file: dict = {}
    seen_slot: dict = {}
    seen_hash: dict = {}
    for r in rows:
        pose_key = tuple(sorted(r.pose.items()))
        key = (r.file, r.direction)
        if key in seen_file:
            o = seen_file[key]
            if (tuple(sorted(o.pose.items())), o.replicate) == (pose_key, r.replicate):
                problems.append(f"line {r.row} repeats line {o.row} ({r.file.name}, {r.direction})")
            elif tuple(sorted(o.pose.items())) != pose_key:
                problems.append(
                    f"lines {o.row} and {r.row}: the same recording {r.file.name} "
                    f"({r.direction}) at two poses ({_pose_text(o)} / {_pose_text(r)})"
                )
            else:
                problems.append(
                    f"lines {o.row} and {r.row}: the same recording {r.file.name} ({r.direction}) "
                    f"as replicates {o.replicate} and {r.replicate}; a replicate is a new recording"
                )
            continue
        seen_file[key] = r
        slot = (pose_key, r.direction, r.replicate)
        if slot in seen_slot and seen_slot[slot].file != r.file:
            o = seen_slot[slot]
            problems.append(
                f"lines {o.row} and {r.row}: two recordings ({o.file.name}, {r.file.name}) at the "
                f"same pose, direction {r.direction} and replicate {r.replicate}; number "
                "replicates in the replicate column (0, 1, ...)"
            )
        seen_slot.setdefault(slot, r)
    by_path: dict = {}
    for r in rows:
        if r.file not in by_path:
            by_path[r.file] = _file_hash(r.file)
        digest = by_path[r.file]
        if digest is None:
            continue
        o = seen_hash.setdefault(digest, r)
        if o.file != r.file:
            problems.append(
                f"lines {o.row} and {r.row}: {o.file.name} and {r.file.name} have identical "
                f"content (SHA-256 {digest[:12]}...), a copied file, not new data"
            )
    if problems:
        raise ValueError(
            f"{where}: {len(problems)} duplicate(s) would count the same data twice: "
            + "; ".join(problems)
        )
