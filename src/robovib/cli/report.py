"""``robovib report``: one self-contained HTML page to hand on (tables, figures, settings,
provenance) for the chapter-3 study, a pose model, a lobes run or a control study."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from ._common import (
    JsonFlag,
    KernelOpt,
    ModelOpt,
    ModeSwitchOpt,
    SeedOpt,
    check_kernel,
    emit_json,
    new_app,
    workspace_model,
)

app = new_app(
    "Self-contained HTML reports (tables, figures, settings, provenance) to hand on: "
    "chapter3, model, lobes, control."
)
HtmlOpt = Annotated[Path, typer.Option("-o", "--output", help="HTML file to write.")]


def _check(output: Path, *inputs) -> None:
    """Refuse a bad output path before any work (missing/read-only folder, output = input)."""
    from ..io import check_output_path

    check_output_path(output, inputs=inputs)


def _done(report, output: Path, json_out: bool, *inputs) -> None:
    from ..report import write_report

    write_report(report, output, inputs=inputs)
    if json_out:
        emit_json({"output": str(output), "title": report.title})
    else:
        typer.echo(f"wrote {output}: {report.title}")


@app.command("chapter3")
def chapter3(
    output: HtmlOpt,
    kernel: KernelOpt = "ard",
    n_splits: Annotated[int, typer.Option(help="Cross-validation folds (thesis: 5).")] = 5,
    mode_switch: ModeSwitchOpt = True,
    seed: SeedOpt = 0,
    json_out: JsonFlag = False,
) -> None:
    """The chapter-3 study (GPR vs thesis Table 2, MLR, external validation) as a page."""
    from ..studies.reports import chapter3_study_report

    _check(output)
    _done(chapter3_study_report(kernel=check_kernel(kernel), n_splits=n_splits,
                                mode_switch=mode_switch, rng=seed), output, json_out)  # fmt: skip


@app.command("model")
def model(
    model_file: Annotated[
        Path,
        typer.Argument(help="Pose model HDF5 (campaign/user pose model, or `hybrid fit` model)."),
    ],
    output: HtmlOpt,
    json_out: JsonFlag = False,
) -> None:
    """A saved pose model: training range, fit at the training poses, predictions, provenance."""
    from ..report import model_report

    _check(output, model_file)
    _done(model_report(model_file), output, json_out, model_file)


@app.command("lobes")
def lobes(
    output: HtmlOpt,
    x: Annotated[float, typer.Option("--x", help="Tool-tip X [mm].")],
    y: Annotated[float, typer.Option("--y", help="Tool-tip Y [mm].")],
    rz: Annotated[float, typer.Option("--rz", help="Rotation about the tool axis [deg].")],
    ae: Annotated[float, typer.Option("--ae", help="Radial depth of cut [mm].")] = 6.0,
    material_name: Annotated[
        str, typer.Option("--material", help="Cutting-coefficient preset: al7075 or acetal.")
    ] = "al7075",
    feed: Annotated[str, typer.Option(help="Feed direction in the base frame: x or y.")] = "x",
    rpm_range: Annotated[
        str, typer.Option("--rpm-range", help="Speeds MIN:MAX:N [rpm] (as mill lobes).")
    ] = "100:3000:200",
    method: Annotated[
        str,
        typer.Option(help="sdm (semi-discretization, flip lobes; as mill lobes) or zoa (fast)."),
    ] = "sdm",
    samples: Annotated[
        int,
        typer.Option(
            help="Monte-Carlo samples of the pose model: probability of a stable cut (0: none)."
        ),
    ] = 0,
    seed: SeedOpt = 0,
    model_path: ModelOpt = None,
    json_out: JsonFlag = False,
) -> None:
    """Stability lobes at a pose from a pose model (either kind; default chapter 3), as a page."""
    from ..report import lobes_study_report
    from ._parsers import parse_rpm_range

    _check(output, *([model_path] if model_path else []))
    model = None if model_path is None else workspace_model(model_path, seed)
    _done(lobes_study_report(x, y, rz, ae_mm=ae, material=material_name, feed=feed,
                             spindle_rpm=parse_rpm_range(rpm_range), method=method, rng=seed, model=model,
                             n_samples=samples), output, json_out,
          *([model_path] if model_path else []))  # fmt: skip


@app.command("control")
def control(
    output: HtmlOpt,
    path_file: Annotated[
        Path | None,
        typer.Option(
            "--path-file",
            help="CSV of modes along a path: s_m, fn_hz, stiffness_n_per_m, damping_ratio. Default: virtual-robot EMA along the chapter-4 path.",
        ),
    ] = None,
    direction: Annotated[
        str, typer.Option(help="Direction of the path model or, with --model, of the pose model.")
    ] = "x",
    start: Annotated[
        str | None,
        typer.Option(
            help="With --model: line start pose in the model's input units (2200,-300,0)."
        ),
    ] = None,
    end: Annotated[str | None, typer.Option(help="With --model: line end pose.")] = None,
    points: Annotated[int, typer.Option(help="Design points along --start/--end (>= 5).")] = 20,
    seed: SeedOpt = 0,
    model_path: ModelOpt = None,
    json_out: JsonFlag = False,
) -> None:
    """LQR gain schedule along a path (a path file, the virtual robot, or a pose model of either
    kind along --start/--end) and the thesis Table 9 comparison, as a page."""
    from ..studies.reports import control_study_report

    inputs = [p for p in (path_file, model_path) if p is not None]
    _check(output, *inputs)
    if (model_path is None) != (start is None or end is None) or (start is None) != (end is None):
        raise ValueError("give --model with --start and --end (a line through the pose model), "
                         "or none of them")  # fmt: skip
    if model_path is not None and path_file is not None:
        raise ValueError("give either --path-file or --model, not both")
    line = None
    if model_path is not None:
        line = (workspace_model(model_path, seed, require_inputs=None),
                [float(v) for v in start.split(",")], [float(v) for v in end.split(",")],
                points)  # fmt: skip
    _done(control_study_report(path_file, direction=direction, rng=seed, line=line), output,
          json_out, *inputs)  # fmt: skip
