"""Command-line interface of robovib (thin: parsing, unit conversion at the edge, printing)."""

from __future__ import annotations

import json
import sys
from typing import Annotated

import numpy as np
import typer
from rich.console import Console
from rich.markup import escape
from rich.table import Table

app = typer.Typer(
    help="robovib: pose-dependent dynamics of machining robots.",
    no_args_is_help=True,
    add_completion=False,
)
gpr_app = typer.Typer(help="GP models of the modal parameters over the workspace (thesis ch. 3).")
app.add_typer(gpr_app, name="gpr")

JsonFlag = Annotated[
    bool, typer.Option("--json", help="Print one JSON document instead of tables.")
]
KernelOpt = Annotated[
    str,
    typer.Option(
        help="GP kernel: 'ard' (one length scale per input) or 'isotropic' (thesis Eq. 7)."
    ),
]
SeedOpt = Annotated[int, typer.Option(help="Seed of fold shuffles and optimiser restarts.")]
ModeSwitchOpt = Annotated[
    bool,
    typer.Option(
        "--mode-switch/--no-mode-switch",
        help="Classify the ~63 Hz X-mode switch at full extension (default) or smooth over it with one GP (thesis).",
    ),
]


def _console() -> Console:
    return Console(file=sys.stdout, width=max(Console().width, 140))


def _emit_json(doc: dict) -> None:
    typer.echo(json.dumps(doc, indent=2, allow_nan=True, default=_json_default))


def _json_default(obj):
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, np.generic):
        return obj.item()
    raise TypeError(f"not JSON serialisable: {type(obj).__name__}")


def _check_kernel(kernel: str) -> str:
    if kernel not in ("ard", "isotropic"):
        raise typer.BadParameter(f"unknown kernel {kernel!r}; use 'ard' or 'isotropic'")
    return kernel


@app.command()
def demo(
    kernel: KernelOpt = "ard",
    seed: SeedOpt = 0,
    printed_stiffness: Annotated[
        bool,
        typer.Option(
            help="Use Table A1's stiffness cells as printed (tests 59-60 shifted) instead of the corrected reading."
        ),
    ] = False,
    mode_switch: ModeSwitchOpt = True,
    json_out: JsonFlag = False,
) -> None:
    """Chapter-3 study on the shipped thesis data: GPR vs thesis Table 2, MLR, external validation."""
    from .gp.study import chapter3_study

    study = chapter3_study(
        kernel=_check_kernel(kernel),
        stiffness_reading="printed" if printed_stiffness else "corrected",
        mode_switch=mode_switch,
        rng=seed,
    )
    if json_out:
        frame = study.to_frame()
        _emit_json(
            {
                "settings": study.settings,
                "outputs": frame.reset_index(names="output").to_dict(orient="records"),
            }
        )
        return
    con = _console()
    s = study
    variant = "X-mode switch classified" if mode_switch else "one GP per output"
    t = Table(
        title=f"5-fold CV of the modal-parameter GPR on Table A1 (kernel={kernel}, {variant}, seed={seed})"
    )
    for col in (
        "output",
        "thesis GPR R²",
        "thesis RMSE",
        "plain CV R²",
        "plain RMSE",
        "grouped CV R²",
        "grouped RMSE",
    ):
        t.add_column(col, justify="right")
    for i, name in enumerate(s.outputs):
        t.add_row(
            escape(name),
            f"{s.thesis_gpr_r2[i]:.2f}",
            f"{s.thesis_gpr_rmse[i]:.2f}",
            f"{s.gpr_plain_r2[i]:.2f}",
            f"{s.gpr_plain_rmse[i]:.2f}",
            f"{s.gpr_grouped_r2[i]:.2f}",
            f"{s.gpr_grouped_rmse[i]:.2f}",
        )
    con.print(t)
    con.print(
        "plain CV = the thesis' protocol (replicates of a test pose stay in training); "
        "grouped CV = all replicates of a pose held out together (prediction at unseen poses)."
    )
    t = Table(title="2nd-order MLR baseline")
    for col in (
        "output",
        "thesis MLR R²",
        "thesis RMSE",
        "in-sample R²",
        "in-sample RMSE",
        "5-fold CV R²",
        "CV RMSE",
    ):
        t.add_column(col, justify="right")
    for i, name in enumerate(s.outputs):
        t.add_row(
            escape(name),
            f"{s.thesis_mlr_r2[i]:.2f}",
            f"{s.thesis_mlr_rmse[i]:.2f}",
            f"{s.mlr_insample_r2[i]:.2f}",
            f"{s.mlr_insample_rmse[i]:.2f}",
            f"{s.mlr_cv_r2[i]:.2f}",
            f"{s.mlr_cv_rmse[i]:.2f}",
        )
    con.print(t)
    t = Table(
        title="External validation on Table A2 (30 unseen poses), GPR fitted on all of Table A1"
    )
    for col in ("output", "RMSE", "mean rel. error", "max rel. error"):
        t.add_column(col, justify="right")
    for i, name in enumerate(s.outputs):
        t.add_row(
            escape(name),
            f"{s.external_rmse[i]:.3f}",
            f"{100 * s.external_mean_relative_error[i]:.1f} %",
            f"{100 * s.external_max_relative_error[i]:.1f} %",
        )
    con.print(t)


@gpr_app.command("predict")
def gpr_predict(
    x: Annotated[float, typer.Option("--x", help="Tool-tip X in the robot base frame [mm].")],
    y: Annotated[float, typer.Option("--y", help="Tool-tip Y in the robot base frame [mm].")],
    rz: Annotated[float, typer.Option("--rz", help="Rotation about the tool axis [deg].")],
    kernel: KernelOpt = "ard",
    seed: SeedOpt = 0,
    mode_switch: ModeSwitchOpt = True,
    json_out: JsonFlag = False,
) -> None:
    """Predicted dominant-mode parameters at a pose (Z = 325 mm, Rx = Ry = 0) with ±2σ."""
    from .datasets import X_HIGH_MODE_THRESHOLD_HZ
    from .gp.study import OUTPUT_LABELS, fit_chapter3_model

    pose = np.array([[x, y, rz]], dtype=float)
    if not np.all(np.isfinite(pose)):
        raise typer.BadParameter("pose coordinates must be finite numbers")
    model = fit_chapter3_model(kernel=_check_kernel(kernel), mode_switch=mode_switch, rng=seed)
    base = model.low_model_ if mode_switch else model
    lo, hi = base.X_train_.min(axis=0), base.X_train_.max(axis=0)
    outside = [
        name
        for name, v, a, b in zip(("x", "y", "rz"), pose[0], lo, hi, strict=True)
        if v < a or v > b
    ]
    mean, std = model.predict(pose, return_std=True)
    mean, std = mean[0], std[0]
    records = [
        {
            "output": label,
            "mean": float(m),
            "std": float(s),
            "lower_2sigma": float(m - 2 * s),
            "upper_2sigma": float(m + 2 * s),
        }
        for label, m, s in zip(OUTPUT_LABELS, mean, std, strict=True)
    ]
    note = None
    p_high = float(model.high_mode_probability(pose)[0]) if mode_switch else None
    if p_high is not None and 0.2 < p_high < 0.8:
        note = (
            f"P(~63 Hz X mode dominant) = {p_high:.2f}: the data cannot tell which X mode dominates "
            "here; the X values are those of the more probable mode"
        )
    elif p_high is None and mean[0] - 2 * std[0] < X_HIGH_MODE_THRESHOLD_HZ < mean[0] + 2 * std[0]:
        note = "the X band straddles the 16-23 Hz / ~63 Hz mode switch: the dominant X mode is uncertain here"
    if json_out:
        _emit_json(
            {
                "pose": {"x_mm": x, "y_mm": y, "z_mm": 325.0, "rz_deg": rz},
                "extrapolation": outside,
                "x_high_mode_probability": p_high,
                "note": note,
                "predictions": records,
            }
        )
        return
    con = _console()
    t = Table(title=f"GPR prediction at X={x:g} mm, Y={y:g} mm, Rz={rz:g}° (Z=325 mm)")
    for col in ("output", "mean", "± 2σ", "range (2σ)"):
        t.add_column(col, justify="right")
    for r in records:
        t.add_row(
            escape(r["output"]),
            f"{r['mean']:.3f}",
            f"{2 * r['std']:.3f}",
            escape(f"[{r['lower_2sigma']:.3f}, {r['upper_2sigma']:.3f}]"),
        )
    con.print(t)
    if outside:
        con.print(
            f"[yellow]warning:[/] {', '.join(outside)} outside the calibrated workspace: extrapolation"
        )
    if note:
        con.print(f"[yellow]note:[/] {note}")


def main() -> None:
    app()


if __name__ == "__main__":
    main()
