"""``robovib robot``: analytical KR500-3 model (kinematics, stiffness, eigenfrequencies, §3.4)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import numpy as np
import typer

from ..files.units import from_si
from ._common import (
    JsonFlag,
    ModelOpt,
    Table,
    console,
    emit_json,
    escape,
    new_app,
    save_figure,
    use_agg,
)

app = new_app(
    "Analytical KR500-3 model: kinematics, stiffness, mass, eigenfrequencies (thesis §3.4)."
)
XOpt = Annotated[float, typer.Option("--x", help="Tool-tip X [mm].")]
YOpt = Annotated[float, typer.Option("--y", help="Tool-tip Y [mm].")]
ZOpt = Annotated[float, typer.Option("--z", help="Tool-tip Z [mm].")]


@app.command("fk")
def fk(
    joints: Annotated[
        tuple[float, float, float, float, float, float],
        typer.Option(help="KUKA joint angles A1..A6 [deg]."),
    ],
    json_out: JsonFlag = False,
) -> None:
    """Tool-tip and flange position [mm] and orientation of given joint angles."""
    from ..robot import KR500

    robot = KR500()
    tip, flange = robot.fk(joints), robot.fk(joints, flange=True)
    cond = robot.condition_number(joints)
    doc = {"joints_deg": list(joints), "tool_tip_mm": from_si(tip[:3, 3], "mm"), "flange_mm": from_si(flange[:3, 3], "mm"),
           "rotation": tip[:3, :3], "jacobian_condition_number": cond}  # fmt: skip
    if json_out:
        emit_json(doc)
    else:
        typer.echo(
            f"tool tip [mm]: {np.round(doc['tool_tip_mm'], 2).tolist()}   flange [mm]: {np.round(doc['flange_mm'], 2).tolist()}"
        )
        typer.echo(f"Jacobian condition number: {cond:.3g}")


def _workspace_pose(x, y, z, rz):
    from ..robot import KR500, tool_down_orientation

    robot = KR500()
    from ..gp.pose_units import pose_in_units

    position_m = pose_in_units(("x_m", "y_m", "z_m"), {"x_mm": x, "y_mm": y, "z_mm": z})
    return robot, robot.ik(position_m, tool_down_orientation(rz))


@app.command("ik")
def ik(
    x: XOpt,
    y: YOpt,
    z: ZOpt = 325.0,
    rz: Annotated[
        float, typer.Option("--rz", help="Rotation about the (downward) tool axis [deg].")
    ] = 0.0,
    json_out: JsonFlag = False,
) -> None:
    """Joint angles for a tool-tip pose with the tool axis pointing down (chapter-3 convention)."""
    robot, q = _workspace_pose(x, y, z, rz)
    doc = {"joints_deg": q, "jacobian_condition_number": robot.condition_number(q)}
    if json_out:
        emit_json(doc)
    else:
        typer.echo(
            f"A1..A6 [deg]: {np.round(q, 3).tolist()}   (condition number {doc['jacobian_condition_number']:.3g})"
        )


@app.command("stiffness")
def stiffness(
    x: XOpt,
    y: YOpt,
    z: ZOpt = 325.0,
    rz: Annotated[float, typer.Option("--rz", help="Rotation about the tool axis [deg].")] = 0.0,
    model_path: ModelOpt = None,
    json_out: JsonFlag = False,
) -> None:
    """Analytical stiffness (Table 4 joint stiffness), principal directions and eigenfrequencies;
    a warning where it is off the measured pose model (chapter 3 or --model) by more than 2x."""
    from ..robot.dynamics import cartesian_modes, cartesian_stiffness

    robot, q = _workspace_pose(x, y, z, rz)
    k = cartesian_stiffness(robot, q)
    modes = cartesian_modes(robot, q)
    kt_vals, kt_vecs = modes.principal_stiffness()
    doc = {
        "joints_deg": q,
        "directional_stiffness_n_per_m": dict(
            zip("xyz", modes.directional_stiffness(), strict=True)
        ),
        "translational_principal_stiffness_n_per_m": kt_vals,
        "principal_directions": kt_vecs,
        "natural_frequencies_hz": modes.natural_frequencies_hz,
        "mode_directions": modes.directions,
        "cartesian_stiffness_6x6": k,
    }
    notes = _stiffness_against_measured(doc, x, y, z, rz, model_path)
    doc["notes"] = notes
    if json_out:
        emit_json(doc)
        return
    typer.echo(
        "directional stiffness [MN/m]: "
        + ", ".join(
            f"{d.upper()} {v / 1e6:.3f}" for d, v in doc["directional_stiffness_n_per_m"].items()
        )
    )
    for f, u in zip(modes.natural_frequencies_hz, modes.directions.T, strict=True):
        typer.echo(f"mode {f:7.2f} Hz  direction {np.round(u, 3).tolist()}")
    for note in notes:
        typer.echo(f"warning: {note}")


def _stiffness_against_measured(doc, x, y, z, rz, model_path) -> list[str]:
    """Where the analytical stiffness is off the measured pose model by more than 2x: say so
    (the rigid-link, joint-stiffness-only model of Table 4 leaves out link and gear
    compliance and the dominant mode's mass), and add the measured values to ``doc``."""
    from ..gp.chapter3_model import workspace_predictor

    if abs(z - 325.0) > 1e-9 and model_path is None:
        return []  # the measured model (Table A1) is of the plane Z = 325 mm
    model = workspace_predictor(model_path)
    row = model.mode_set(np.array([[x, y, rz]], float))[0]
    measured = {d: row[d][0].parameters.stiffness_n_per_m for d in "xyz" if d in row}
    doc["measured_model_stiffness_n_per_m"] = measured
    notes = []
    for d, km in measured.items():
        ka = doc["directional_stiffness_n_per_m"][d]
        if not (0.5 <= ka / km <= 2.0):
            softer = "softer" if ka < km else "stiffer"
            notes.append(
                f"{d.upper()}: the analytical model gives {ka / 1e6:.2f} MN/m, the measured pose "
                f"model's dominant mode {km / 1e6:.2f} MN/m: {abs(1 - ka / km):.0%} {softer} "
                "(joint stiffness only, rigid links; see `robovib robot compare`)"
            )
    return notes


@app.command("identify")
def identify(
    tests: Annotated[
        Path,
        typer.Argument(
            help="CSV: a1_deg..a6_deg, fx_n, fy_n, fz_n, mx_nm, my_nm, mz_nm, dx_m, dy_m, dz_m[, rx_rad, ry_rad, rz_rad]."
        ),
    ],
    json_out: JsonFlag = False,
) -> None:
    """Joint stiffnesses from compliance tests (thesis Eq. 12, Table 3/4 procedure)."""
    from ..io import read_compliance_tests_csv
    from ..robot import KR500
    from ..robot.dynamics import TABLE_4_JOINT_STIFFNESS, identify_joint_stiffness

    joints, wrench, disp = read_compliance_tests_csv(tests)
    k = identify_joint_stiffness(KR500(), joints, wrench, disp)
    doc = {
        "joint_stiffness_n_m_per_rad": k,
        "table_4_n_m_per_rad": TABLE_4_JOINT_STIFFNESS,
        "n_tests": len(joints),
    }
    if json_out:
        emit_json(doc)
    else:
        for i, (ki, ti) in enumerate(zip(k, TABLE_4_JOINT_STIFFNESS, strict=True)):
            typer.echo(f"A{i + 1}: {ki / 1e6:.3f} x 1e6 N m/rad   (thesis Table 4: {ti / 1e6:.2f})")


@app.command("compare")
def compare(
    plot: Annotated[
        Path | None, typer.Option(help="PNG of relative errors vs arm extension (thesis Fig. 11).")
    ] = None,
    gp_inputs: Annotated[
        bool,
        typer.Option(
            "--gp-inputs", help="Also compare GP inputs: Cartesian vs joint angles on Table A2."
        ),
    ] = False,
    json_out: JsonFlag = False,
) -> None:
    """Analytical model vs Table A1 measurements: relative errors of fn and stiffness per direction."""
    from ..studies.analytical import (
        compare_with_table_a1,
        comparison_summary,
        gp_input_comparison,
        plot_comparison,
    )

    table = compare_with_table_a1().to_frame()
    summary = comparison_summary(table)
    gp = gp_input_comparison().to_frame() if gp_inputs else None

    def draw() -> None:
        if plot is not None:
            use_agg()
            save_figure(plot_comparison(table), plot)

    if json_out:
        doc = {"summary": summary, "poses": table.to_dict(orient="records")}
        if gp is not None:
            doc["gp_inputs"] = gp.to_dict(orient="records")
        emit_json(doc)
        draw()
        return
    con = console()
    t = Table(
        title="Analytical (Table 4 joint stiffness, solid links) vs measured (Table A1 means)"
    )
    for col in ("quantity", "mean error", "min", "max"):
        t.add_column(col, justify="right")
    for key, v in summary.items():
        t.add_row(
            key,
            f"{100 * v['mean_rel_error']:+.0f} %",
            f"{100 * v['min']:+.0f} %",
            f"{100 * v['max']:+.0f} %",
        )
    con.print(t)
    if gp is not None:
        piv = gp.pivot(index="output", columns="inputs", values="mean_relative_error")
        t = Table(title="GP external validation on Table A2: mean relative error by input set")
        t.add_column("output")
        for c in piv.columns:
            t.add_column(escape(c), justify="right")
        for out, row in piv.iterrows():
            t.add_row(escape(out), *[f"{100 * v:.1f} %" for v in row])
        con.print(t)
    if plot is not None:
        draw()
        con.print(f"wrote {plot}")
