"""``robovib gpr``: GP models of the modal parameters over the workspace (thesis ch. 3)."""

from __future__ import annotations

from typing import Annotated

import typer

from ._common import (
    JsonFlag,
    KernelOpt,
    ModeSwitchOpt,
    SeedOpt,
    Table,
    check_kernel,
    console,
    emit_json,
    escape,
    new_app,
)

app = new_app("GP models of the modal parameters over the workspace (thesis ch. 3).")


@app.command("predict")
def predict(
    x: Annotated[float, typer.Option("--x", help="Tool-tip X in the robot base frame [mm].")],
    y: Annotated[float, typer.Option("--y", help="Tool-tip Y in the robot base frame [mm].")],
    rz: Annotated[float, typer.Option("--rz", help="Rotation about the tool axis [deg].")],
    kernel: KernelOpt = "ard",
    seed: SeedOpt = 0,
    mode_switch: ModeSwitchOpt = True,
    json_out: JsonFlag = False,
) -> None:
    """Predicted dominant-mode parameters at a pose (Z = 325 mm, Rx = Ry = 0) with ±2σ."""
    from ..gp.pose_prediction import predict_pose
    from ..studies.chapter3 import OUTPUT_LABELS, fit_chapter3_regressor

    model = fit_chapter3_regressor(kernel=check_kernel(kernel), mode_switch=mode_switch, rng=seed)
    p = predict_pose(model, x, y, rz, OUTPUT_LABELS)
    if json_out:
        emit_json(
            {
                "pose": {"x_mm": x, "y_mm": y, "z_mm": 325.0, "rz_deg": rz},
                "extrapolation": list(p.extrapolation),
                "x_high_mode_probability": p.x_high_mode_probability,
                "note": p.note,
                "predictions": [
                    {**r, "unit": r["output"].split("[")[-1].rstrip("]")} for r in p.records
                ],
            }
        )
        return
    con = console()
    t = Table(title=f"GPR prediction at X={x:g} mm, Y={y:g} mm, Rz={rz:g}° (Z=325 mm)")
    for col in ("output", "mean", "± 2σ", "range (2σ)"):
        t.add_column(col, justify="right")
    for r in p.records:
        t.add_row(
            escape(r["output"]),
            f"{r['mean']:.3f}",
            f"{2 * r['std']:.3f}",
            escape(f"[{r['lower_2sigma']:.3f}, {r['upper_2sigma']:.3f}]"),
        )
    con.print(t)
    if p.extrapolation:
        con.print(
            f"[yellow]warning:[/] {', '.join(p.extrapolation)} outside the calibrated workspace: extrapolation"
        )
    if p.note:
        con.print(f"[yellow]note:[/] {p.note}")
