"""Extract the thesis' tables from ``shared/seed/thesis.md`` into CSV package data.

Run once from the repository root (the output is committed, so users never need the thesis)::

    python scripts/extract_thesis_tables.py [path/to/thesis.md]

Every table is written *as printed*: values are not corrected here. Known transcription
problems (the stiffness-column shift of Table A1, tests 59-60) are flagged by the loaders in
``robovib.datasets``, which also apply the documented corrections.

Layout of Table A1 in the markdown: one row per replicate, tab separated; the first replicate
row of a test carries ``test, X, Y, Rz``, the two following rows leave those four cells empty
and inherit the pose of the row above. Blank lines (page breaks) may sit anywhere inside.
"""

from __future__ import annotations

import csv
import re
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
DEFAULT_THESIS = REPO.parent / "shared" / "seed" / "thesis.md"
OUT_DIR = REPO / "src" / "robovib" / "datasets" / "data"

DIRECTIONS = ("x", "y", "z")
MODAL_COLUMNS = (
    [f"fn_{d}_hz" for d in DIRECTIONS]
    + [f"stiffness_{d}_mn_per_m" for d in DIRECTIONS]
    + [f"damping_{d}_kns_per_m" for d in DIRECTIONS]
)


def table_block(lines: list[str], caption_prefix: str) -> list[list[str]]:
    """Return the tab-separated rows that follow the caption line starting with ``caption_prefix``.

    Blank lines inside the table (page breaks) are skipped; the block ends at the first
    non-blank line without a tab.
    """
    start = None
    for i, line in enumerate(lines):
        if line.strip().startswith(caption_prefix):
            start = i
            break
    if start is None:
        raise ValueError(f"caption {caption_prefix!r} not found in the thesis")
    rows: list[list[str]] = []
    for line in lines[start + 1 :]:
        if not line.strip():
            continue
        if "\t" not in line:
            if rows:
                break
            continue
        rows.append([cell.strip() for cell in line.rstrip("\n").split("\t")])
    return rows


def number(cell: str) -> float:
    cleaned = re.sub(r"<[^>]+>", "", cell).strip()
    return float(cleaned)


def write_csv(name: str, header: list[str], rows: list[list[object]]) -> None:
    path = OUT_DIR / name
    with path.open("w", newline="") as fh:
        writer = csv.writer(fh, lineterminator="\n")
        writer.writerow(header)
        writer.writerows(rows)
    print(f"wrote {path.relative_to(REPO)} ({len(rows)} rows)")


def extract_modal_table(
    lines: list[str], caption: str, expect_rows: int, replicated: bool
) -> list[list[object]]:
    block = table_block(lines, caption)
    data_rows = block[2:]  # two header rows
    out: list[list[object]] = []
    pose: tuple[int, float, float, float] | None = None
    replicate = 0
    for cells in data_rows:
        if len(cells) != 13:
            raise ValueError(f"{caption}: expected 13 cells, got {len(cells)}: {cells}")
        if cells[0]:
            pose = (int(cells[0]), number(cells[1]), number(cells[2]), number(cells[3]))
            replicate = 1
        else:
            if pose is None or not replicated:
                raise ValueError(f"{caption}: row without pose and no pose above: {cells}")
            replicate += 1
        values = [number(c) for c in cells[4:]]
        if replicated:
            out.append([pose[0], replicate, *pose[1:], *values])
        else:
            out.append([*pose, *values])
    if len(out) != expect_rows:
        raise ValueError(f"{caption}: expected {expect_rows} rows, parsed {len(out)}")
    return out


def main(thesis_path: Path) -> None:
    lines = thesis_path.read_text(encoding="utf-8").splitlines()
    OUT_DIR.mkdir(parents=True, exist_ok=True)

    a1 = extract_modal_table(lines, "Table A1.", 180, replicated=True)
    write_csv("table_a1.csv", ["test", "replicate", "x_mm", "y_mm", "rz_deg", *MODAL_COLUMNS], a1)
    a2 = extract_modal_table(lines, "Table A2.", 30, replicated=False)
    write_csv("table_a2.csv", ["test", "x_mm", "y_mm", "rz_deg", *MODAL_COLUMNS], a2)

    # Table 1: ranges of the chapter-3 workspace (Cartesian and joint).
    block = table_block(lines, "Table 1.")
    write_csv(
        "table_1_ranges.csv",
        ["bound", "x_mm", "y_mm", "rz_deg", *[f"theta{i}_deg" for i in range(1, 7)]],
        [[r[0], *[number(c) for c in r[1:]]] for r in block[2:]],
    )

    # Table 2: cross-validation R2/RMSE of GPR and MLR (long format).
    block = table_block(lines, "Table 2.")
    outputs = [f"{q}_{d}" for d in DIRECTIONS for q in ("fn", "stiffness", "damping")]
    rows = []
    model = None
    for r in block[2:]:
        model = r[0] or model
        metric = "r2" if "R^2" in r[1] else "rmse"
        for name, cell in zip(outputs, r[2:], strict=True):
            rows.append([model, metric, name, number(cell)])
    write_csv("table_2_cv.csv", ["model", "metric", "output", "value"], rows)

    # Table 3: joint angles of the compliance tests.
    block = table_block(lines, "Table 3.")
    write_csv(
        "table_3_compliance_poses.csv",
        ["test", *[f"theta{i}_deg" for i in range(1, 7)]],
        [[int(r[0]), *[number(c) for c in r[1:]]] for r in block[1:]],
    )

    # Table 4: identified joint stiffness (printed in 1e6 N m/rad).
    block = table_block(lines, "Table 4.")
    write_csv(
        "table_4_joint_stiffness.csv",
        ["joint", "stiffness_1e6_nm_per_rad"],
        [[i + 1, number(c)] for i, c in enumerate(block[1])],
    )

    # Table 5: start/end joint angles of the chapter-4 path.
    block = table_block(lines, "Table 5.")
    write_csv(
        "table_5_path_joints.csv",
        ["position", *[f"theta{i}_deg" for i in range(1, 7)]],
        [[r[0].lower(), *[number(c) for c in r[1:]]] for r in block[1:]],
    )

    # Table 6: chapter-4 cross validation (damping *ratio* here, not coefficient).
    block = table_block(lines, "Table 6.")
    outputs6 = [f"{q}_{d}" for d in DIRECTIONS for q in ("fn", "stiffness", "damping_ratio")]
    rows = []
    for r in block[2:]:
        metric = "r2" if "R^2" in r[0] else "rmse"
        for name, cell in zip(outputs6, r[1:], strict=True):
            rows.append([metric, name, number(cell)])
    write_csv("table_6_cv_path.csv", ["metric", "output", "value"], rows)

    # Table 7: offset-mass start/end vibration amplitudes [mm].
    block = table_block(lines, "Table 7.")
    controllers = ["no_feedback", "pose_dependent", "constant_start", "constant_end"]
    rows = []
    for r in block[2:]:
        rpm = number(r[0])
        for i, cell in enumerate(r[1:]):
            where = "start" if i < 4 else "end"
            rows.append([rpm, where, controllers[i % 4], number(cell)])
    write_csv(
        "table_7_offset_mass.csv", ["speed_rpm", "path_point", "controller", "amplitude_mm"], rows
    )

    # Table 8: GPR predictions vs measurements at Positions 1 and 2.
    block = table_block(lines, "Table 8.")
    rows = []
    position = None
    for r in block[2:]:
        position = r[0] or position
        kind = r[1].lower()
        vals = [number(c) for c in r[2:]]
        rows.append([int(position), kind, *vals])
    write_csv(
        "table_8_positions.csv",
        [
            "position",
            "kind",
            "fn_x_hz",
            "stiffness_x_mn_per_m",
            "damping_ratio_x",
            "fn_z_hz",
            "stiffness_z_mn_per_m",
            "damping_ratio_z",
        ],
        rows,
    )

    # Table 9: printed LQR gains.
    block = table_block(lines, "Table 9.")
    write_csv(
        "table_9_gains.csv",
        ["position", "w1_x", "w2_x", "w1_z", "w2_z"],
        [[int(r[0]), *[number(c) for c in r[1:]]] for r in block[2:]],
    )

    # Tables 10 and 11: RMS vibration / surface deviation, open loop vs control (long format).
    for caption, fname, quantity in (
        ("Table 10.", "table_10_milling_vibration.csv", "rms_vibration_mm"),
        ("Table 11.", "table_11_surface_deviation.csv", "rms_surface_deviation_mm"),
    ):
        block = table_block(lines, caption)
        rows = []
        for r in block:
            if not r[0].isdigit():
                continue
            test, rpm, feed, ap = int(r[0]), number(r[1]), number(r[2]), number(r[3])
            # Column order printed in both tables: P1 X open, P1 X ctrl, P1 Z open, P1 Z ctrl, P2 ...
            # (Table 11's header row repeats "X Z X Z"; the thesis text pairs them the same way.)
            labels = [
                (1, "x", "open"),
                (1, "x", "control"),
                (1, "z", "open"),
                (1, "z", "control"),
                (2, "x", "open"),
                (2, "x", "control"),
                (2, "z", "open"),
                (2, "z", "control"),
            ]
            if caption == "Table 11.":
                labels = [
                    (1, "x", "open"),
                    (1, "z", "open"),
                    (1, "x", "control"),
                    (1, "z", "control"),
                    (2, "x", "open"),
                    (2, "z", "open"),
                    (2, "x", "control"),
                    (2, "z", "control"),
                ]
            for (pos, direction, mode), cell in zip(labels, r[4:], strict=True):
                rows.append([test, rpm, feed, ap, pos, direction, mode, number(cell)])
        write_csv(
            fname,
            [
                "test",
                "speed_rpm",
                "feed_mm_per_tooth",
                "axial_depth_mm",
                "position",
                "direction",
                "loop",
                quantity,
            ],
            rows,
        )

    # Table 12: FRF prediction RMSE before/after updating [um/N].
    block = table_block(lines, "Table 12.")
    rows = []
    for r in block[1:]:
        stage = "before" if r[0].lower().startswith("before") else "after"
        for d, cell in zip(DIRECTIONS, r[1:], strict=True):
            rows.append([stage, d, number(cell)])
    write_csv("table_12_frf_rmse.csv", ["stage", "direction", "rmse_um_per_n"], rows)

    # Table 13: optimizer iterations, "mean ± std" cells.
    block = table_block(lines, "Table 13.")
    rows = []
    for label, cell in zip(("complete_retraining", "updating"), block[1], strict=True):
        mean, std = re.findall(r"\d+(?:\.\d+)?", cell)
        rows.append([label, float(mean), float(std)])
    write_csv("table_13_iterations.csv", ["method", "iterations_mean", "iterations_std"], rows)


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else DEFAULT_THESIS)
