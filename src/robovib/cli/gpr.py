"""``robovib gpr``: GP models of the modal parameters over the workspace (thesis ch. 3)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from ._common import (
    JsonFlag,
    Table,
    check_kernel,
    console,
    emit_json,
    escape,
    fail,
    new_app,
)

app = new_app("GP models of the modal parameters over the workspace (thesis chapter 3).")


_Deg = Annotated[float | None, typer.Option(help="Pose input [deg] of a --model that uses it.")]


#: Engineering units of the table (JSON stays SI): SI unit -> (shown unit, factor).
_SHOWN = {"N/m": ("MN/m", 1e-6), "N*s/m": ("kN·s/m", 1e-3)}
_SUFFIXES = ("_hz", "_ns_per_m", "_n_per_m")


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
    kernel: Annotated[
        str,
        typer.Option(
            help="Refit the thesis model with this kernel ('isotropic', thesis Eq. 7; seconds) "
            "instead of loading the shipped one ('ard')."
        ),
    ] = "ard",
    seed: Annotated[
        int, typer.Option(help="Refit the thesis model with this optimiser seed (seconds).")
    ] = 0,
    mode_switch: Annotated[
        bool,
        typer.Option(
            "--mode-switch/--no-mode-switch",
            help="--no-mode-switch refits the thesis model with one smooth GP per output "
            "(seconds); default: the shipped model, ~63 Hz X-mode switch classified.",
        ),
    ] = True,
    model: Annotated[
        Path | None,
        typer.Option(
            "--model",
            help="Your pose model (.h5 from 'robovib model fit'); pose options follow its "
            "inputs (--x --y --z [mm], --rx --ry --rz, --a1..--a6 [deg]). Default: the thesis "
            "model shipped with robovib (loaded, not refitted).",
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
    """Predicted dominant-mode parameters (fn, k, c per direction, SI) at a pose with ±2σ.

    Without --model: the thesis' chapter-3 model of Table A1 (Z = 325 mm, Rx = Ry = 0), loaded
    from package data in milliseconds; --kernel isotropic, --seed or --no-mode-switch refit it.
    """
    from ..gp.saved_model import predict_at

    given = {"x_mm": x, "y_mm": y, "z_mm": z, "rx_deg": rx, "ry_deg": ry, "rz_deg": rz,
             "a1_deg": a1, "a2_deg": a2, "a3_deg": a3, "a4_deg": a4, "a5_deg": a5,
             "a6_deg": a6}  # fmt: skip
    pose = {k: v for k, v in given.items() if v is not None}
    refit = (check_kernel(kernel), seed, mode_switch) != ("ard", 0, True)
    if model is not None:
        if refit:
            fail("--kernel, --seed and --no-mode-switch refit the thesis model; they do not "
                 "apply to --model")  # fmt: skip
        from ..gp.saved_model import load_pose_predictor

        pm, source = load_pose_predictor(model), str(model)
    elif refit:
        from ..gp import get_chapter3_model

        pm = get_chapter3_model(kernel, "auto" if mode_switch else False, rng=seed)
        source = f"thesis chapter-3 model refitted (kernel {kernel}, seed {seed}, " + (
            "mode switch classified)" if mode_switch else "no mode switch)"
        )
    else:
        from ..gp.chapter3_model import load_chapter3_predictor

        pm, source = load_chapter3_predictor(), "thesis chapter-3 model (shipped, Table A1)"
    from ..campaign.quality import nonphysical_outputs
    from ..gp.calibration import calibration_status

    p = predict_at(pm, pose)
    bad = nonphysical_outputs([o["output"] for o in p.outputs], [o["mean"] for o in p.outputs])
    if bad:  # never print a negative frequency (issue 38)
        fail(f"the model predicts {', '.join(bad)} at {p.pose}: not a physical mode (a gross "
             "outlier in its training table, or a pose far from its data)")  # fmt: skip
    bands = calibration_status(pm)  # an uncalibrated model says so (issue 38)
    if json_out:
        emit_json({"model": source, **bands, **p.to_dict()})
        return
    con = console()
    where = ", ".join(f"{k}={v:g}" for k, v in p.pose.items())
    t = Table(title=f"Prediction at {where}", caption=source)
    for col in ("output", "unit", "mean", "± 2σ latent", "95 % of a new test"):
        t.add_column(col, justify="right")
    for r in p.outputs:
        unit, f = _SHOWN.get(r["unit"], (r["unit"] or "", 1.0))
        name = next((r["output"][: -len(u)] for u in _SUFFIXES if r["output"].endswith(u)),
                    r["output"])  # fmt: skip
        sets = " or ".join(f"[{f * a:.4g}, {f * b:.4g}]" for a, b in r["measurement_95"])
        t.add_row(escape(name), escape(unit), f"{f * r['mean']:.4g}", f"{2 * f * r['std']:.3g}",
                  escape(sets))  # fmt: skip
    con.print(t)
    con.print("latent: the modal parameter at this pose; a new test adds test-to-test scatter "
              "(two ranges where the dominant mode is uncertain)")  # fmt: skip
    if p.extrapolating:
        outside = ", ".join(p.outside_inputs) or "the combination of inputs"
        con.print(
            f"[yellow]warning:[/] {escape(outside)} outside the training poses: extrapolation"
        )
    for note in p.notes:
        con.print(f"[yellow]note:[/] {escape(note)}")
    if not bands["calibrated"]:
        con.print(f"[yellow]warning:[/] bands {escape(bands['bands'])}")
