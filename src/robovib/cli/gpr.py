"""``robovib gpr``: GP models of the modal parameters over the workspace (thesis ch. 3)."""

from __future__ import annotations

from pathlib import Path
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


_Deg = Annotated[float | None, typer.Option(help="Pose input [deg] of a --model that uses it.")]


@app.command("predict")
def predict(
    x: Annotated[
        float | None, typer.Option("--x", help="Tool-tip X in the robot base frame [mm].")
    ] = None,
    y: Annotated[
        float | None, typer.Option("--y", help="Tool-tip Y in the robot base frame [mm].")
    ] = None,
    rz: Annotated[
        float | None, typer.Option("--rz", help="Rotation about the tool axis [deg].")
    ] = None,
    kernel: KernelOpt = "ard",
    seed: SeedOpt = 0,
    mode_switch: ModeSwitchOpt = True,
    model: Annotated[
        Path | None,
        typer.Option(
            "--model",
            help="Your pose model (.h5 from 'robovib model fit'); pose options follow its "
            "inputs (--x --y --z [mm], --rx --ry --rz, --a1..--a6 [deg]). Default: the thesis model.",
        ),
    ] = None,
    z: Annotated[float | None, typer.Option("--z", help="Tool-tip Z [mm] (--model only).")] = None,
    rx: _Deg = None,
    ry: _Deg = None,
    a1: _Deg = None,
    a2: _Deg = None,
    a3: _Deg = None,
    a4: _Deg = None,
    a5: _Deg = None,
    a6: _Deg = None,
    json_out: JsonFlag = False,
) -> None:
    """Predicted dominant-mode parameters at a pose (Z = 325 mm, Rx = Ry = 0) with ±2σ."""
    if model is not None:
        given = {"x_mm": x, "y_mm": y, "z_mm": z, "rx_deg": rx, "ry_deg": ry, "rz_deg": rz,
                 "a1_deg": a1, "a2_deg": a2, "a3_deg": a3, "a4_deg": a4, "a5_deg": a5,
                 "a6_deg": a6}  # fmt: skip
        _predict_with_model(model, {k: v for k, v in given.items() if v is not None}, json_out)
        return
    if x is None or y is None or rz is None:
        raise typer.BadParameter("--x, --y and --rz are required (or give --model)")
    if any(v is not None for v in (z, rx, ry, a1, a2, a3, a4, a5, a6)):
        raise typer.BadParameter("--z, --rx, --ry, --a1..--a6 need a --model that uses them")
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


def _predict_with_model(model_path: Path, pose: dict, json_out: bool) -> None:
    from ..campaign import load_pose_model, predict_at

    p = predict_at(load_pose_model(model_path), pose)
    if json_out:
        emit_json({"model": str(model_path), **p.to_dict()})
        return
    con = console()
    where = ", ".join(f"{k}={v:g}" for k, v in p.pose.items())
    t = Table(title=f"Prediction of {model_path.name} at {where}")
    for col in ("output", "mean", "± 2σ", "range (2σ)"):
        t.add_column(col, justify="right")
    for r in p.outputs:
        t.add_row(escape(r["output"]), f"{r['mean']:.5g}", f"{2 * r['std']:.3g}",
                  escape(f"[{r['lower_2sigma']:.5g}, {r['upper_2sigma']:.5g}]"))  # fmt: skip
    con.print(t)
    if p.extrapolating:
        outside = ", ".join(p.outside_inputs) or "the combination of inputs"
        con.print(f"[yellow]warning:[/] {outside} outside the training poses: extrapolation")
