"""``robovib control simulate|design|replay``: the closed-loop studies on the virtual robot, a
controller file from your pose model, and that file run over a logged cut (issue 40).
Registered on the ``control`` group by :mod:`robovib.cli.control`."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import numpy as np
import typer

from ._common import (
    ForceOpt,
    JsonFlag,
    ModelOpt,
    SeedOpt,
    check_output,
    console,
    emit_json,
    escape,
    fail,
    save_figure,
    use_agg,
    workspace_model,
)
from ._control_options import (
    ActuatorOpt,
    ControllerOpt,
    DisturbanceOpt,
    parse_disturbances,
    pose_option,
)


def simulate(
    experiment: Annotated[str, typer.Argument(help="offset-mass (Table 7) or milling (Table 10).")],
    controller: ControllerOpt = None,
    actuator: ActuatorOpt = "pure-delay",
    disturbance: DisturbanceOpt = None,
    plot: Annotated[
        Path | None,
        typer.Option(
            help="PNG: offset-mass X vibration envelope per controller (first speed); milling "
            "RMS per cut and controller (X and Z figures: NAME_x.png, NAME_z.png)."
        ),
    ] = None,
    controller_file: Annotated[
        Path | None,
        typer.Option(
            "--controller-file",
            help="Run this controller file (control design) "
            "instead: milling only, at Positions 1 and 2 of its path.",
        ),
    ] = None,
    seed: SeedOpt = 0,
    json_out: JsonFlag = False,
) -> None:
    """Closed-loop runs on the virtual robot, controllers designed from the path model only."""
    check_output(plot, [controller_file] if controller_file is not None else [])
    from rich.progress import Progress

    from ..studies.control import simulate_control

    dist = parse_disturbances(disturbance)
    with Progress(transient=True, disable=json_out) as bar:
        task = bar.add_task("virtual EMA along the path, designs, closed-loop runs", total=None)
        try:
            result = simulate_control(experiment, controller or None, actuator=actuator,
                                      disturbances=dist, keep_traces=plot is not None,
                                      controller_file=controller_file, rng=seed)  # fmt: skip
        except ValueError as exc:
            fail(str(exc))
        bar.update(task, completed=1)
    frame = result.to_frame()
    if json_out:
        emit_json(result.to_dict())
    else:
        console().print(escape(frame.round(3).to_string(index=False)))
    if plot is not None:
        use_agg()
        if experiment == "offset-mass":
            save_figure(result.plot(), plot)
            written = [plot]
        else:
            written = [plot.with_name(f"{plot.stem}_{d}{plot.suffix}") for d in ("x", "z")]
            for d, path in zip(("x", "z"), written, strict=True):
                save_figure(result.plot(d), path)
        if not json_out:
            for path in written:
                typer.echo(f"wrote {path}")


def design(
    output: Annotated[
        Path, typer.Option("-o", "--output", help="Controller file to write (.json).")
    ],
    controller: Annotated[
        str,
        typer.Option(
            help="adaptive+force (recommended), feedforward+robust, robust, lqg, thesis, "
            "constant-start, constant-end, feedforward, repetitive, adaptive, "
            "adaptive+robust, adaptive-feedforward."
        ),
    ] = "adaptive+force",
    path_file: Annotated[
        Path | None,
        typer.Option(
            "--path",
            help="CSV of the tool path's poses, one column per model input "
            "(e.g. x_mm,y_mm,rz_deg), in path order.",
        ),
    ] = None,
    start: Annotated[
        str | None,
        typer.Option(help="Line start pose in the model's input units, e.g. 2350,450,30."),
    ] = None,
    end: Annotated[str | None, typer.Option(help="Line end pose (as --start).")] = None,
    directions: Annotated[str, typer.Option(help="Controlled directions, e.g. x,z.")] = "x,z",
    points: Annotated[int, typer.Option(help="Design points along the path (>= 5).")] = 21,
    rpm: Annotated[
        float | None,
        typer.Option(help="Nominal spindle speed [rpm]; default: given at reset/replay."),
    ] = None,
    teeth: Annotated[int, typer.Option(help="Cutter teeth.")] = 2,
    period_ms: Annotated[float, typer.Option(help="Command period [ms] (RSI: 4 ms).")] = 4.0,
    delay_ms: Annotated[float, typer.Option(help="Transport delay [ms] (KRC4: 32 ms).")] = 32.0,
    model_path: ModelOpt = None,
    force: ForceOpt = False,
    json_out: JsonFlag = False,
) -> None:
    """A controller file from your pose model along your path (gains, tracker, guard, checks)."""
    from ..control.controller_file import design_controller, write_controller_file
    from ..control.path_design import ControlPath
    from ..io import to_si

    inputs = [p for p in (path_file, model_path) if p is not None]
    check_output(output, inputs, force)
    if (start is None) != (end is None):
        fail("give both --start and --end (a line through the pose model), or --path")
    if (start is None) == (path_file is None):
        fail("give either --path (a CSV of poses) or --start/--end")
    model = workspace_model(model_path, require_inputs=None)
    names = tuple(model.input_names)
    try:
        if path_file is not None:
            from ..io.poses import read_pose_array

            vertices = read_pose_array(path_file, names)
        else:
            vertices = [pose_option(start, "--start"), pose_option(end, "--end")]
        path = ControlPath.through(names, vertices)
        doc = design_controller(model, path, controller,
                                directions=tuple(d.strip() for d in directions.split(",")),
                                n_points=points, period_s=to_si(period_ms, "ms"),
                                delay_s=to_si(delay_ms, "ms"), spindle_rpm=rpm, teeth=teeth)  # fmt: skip
    except ValueError as exc:
        fail(str(exc))
    write_controller_file(output, doc, inputs=inputs, force=force)
    summary = {"output": str(output), "controller": doc["controller"],
               "control_modes": doc["provenance"]["control_modes"],
               "path_length_m": path.length_m, "design_points": len(doc["grid_s_m"]),
               "extrapolating_points": doc["provenance"]["extrapolating_points"],
               "stability": {k: v for k, v in doc["stability"].items()
                             if k.endswith(("radius", "ratio")) and not k.startswith("feedback")}}  # fmt: skip
    if json_out:
        emit_json(summary, units={"design_points": "1 (count)", "extrapolating_points": "1 (count)",
                                  "force_model_worst_rms_ratio": "1 (ratio)",
                                  "robust_worst_spectral_radius": "1",
                                  "lqg_worst_spectral_radius": "1"})  # fmt: skip
        return
    modes = ", ".join(f"{d}: model output {m}" for d, m in summary["control_modes"].items())
    typer.echo(f"wrote {output}: {doc['controller']} along {path.length_m:.3f} m "
               f"({summary['design_points']} design points; {modes})")  # fmt: skip
    for key, by_dir in summary["stability"].items():
        for d, v in by_dir.items():
            worst = max(v) if isinstance(v, list) else v
            verdict = "< 1 over the band" if worst < 1 else "NOT < 1: this part is left out"
            if key.endswith("radius"):
                verdict = "stable over the band" if worst < 1 else "NOT stable over the band"
            typer.echo(f"  {key.replace('_', ' ')} ({d}): {worst:.3f} ({verdict})")
    st = doc["stability"]
    for d, r in st.get("feedback_r", {}).items():  # the axes given a feedback instead
        delays, gains = st["true_delays_s"], st.get("feedback_actuator_gains", [1.0])
        typer.echo(f"  feedback ({d}): delay-aware LQR, R = {r:.3g}, worst spectral radius "
                   f"{max(st['feedback_worst_spectral_radius'][d]):.3f} (stable over the band, "
                   f"true delays {min(delays) * 1e3:g}-{max(delays) * 1e3:g} ms, actuator gain "
                   f"{min(gains):g}-{max(gains):g})")  # fmt: skip
    if summary["extrapolating_points"]:
        typer.echo(f"warning: {summary['extrapolating_points']} design points lie outside the "
                   "model's training data (GP extrapolation)")  # fmt: skip


def replay_cmd(
    controller_file: Annotated[Path, typer.Argument(help="Controller file (control design).")],
    record: Annotated[
        Path,
        typer.Option(
            help="Logged cut CSV: time_s, force_{x,y,z}_n, displacement_{x,y,z}_m and "
            "path_s_m or x_m,y_m,rz_deg (the layout 'hybrid oma' reads)."
        ),
    ],
    rpm: Annotated[
        float | None, typer.Option(help="Spindle speed of the cut [rpm] (default the file's).")
    ] = None,
    teeth: Annotated[int | None, typer.Option(help="Cutter teeth (default the file's).")] = None,
    output: Annotated[
        Path | None,
        typer.Option(
            "-o",
            "--output",
            help="CSV of the commands: time_s, path_s_m, correction_{x,y,z}_mm, guard_scale.",
        ),
    ] = None,
    record_made: Annotated[
        str,
        typer.Option(
            help="The cut was logged 'without' this controller (its corrections are added to the "
            "tracker through the model, so the guard and learners see their effect) or 'with' it "
            "running (the record is fed as it is).",
            metavar="without|with",
        ),
    ] = "without",
    force: ForceOpt = False,
    json_out: JsonFlag = False,
) -> None:
    """What the controller would have commanded on a logged cut, what its guard did, and the
    vibration the model predicts with the correction."""
    from ..control.controller_file import load_controller
    from ..control.cut_replay import replay
    from ..io import read_milling_record_csv

    check_output(output, [controller_file, record], force)
    try:
        runtime = load_controller(controller_file)
        result = replay(runtime, read_milling_record_csv(record), spindle_rpm=rpm, teeth=teeth,
                        record_made=record_made)  # fmt: skip
    except ValueError as exc:
        fail(str(exc))
    if output is not None:
        from ..files.safe_write import atomic_output

        lines = ["time_s,path_s_m,correction_x_mm,correction_y_mm,correction_z_mm,guard_scale"]
        lines += [",".join(f"{v:.17g}" for v in (t, s, *u, g)) for t, s, u, g in zip(
            result.time_s, result.path_s_m, result.commands_mm, result.guard_scale, strict=True)]  # fmt: skip
        with atomic_output(output, inputs=[controller_file, record], force=force) as tmp:
            tmp.write_text("\n".join(lines) + "\n")
    events = [{"time_s": e.time_s, "target": e.target, "reason": e.reason} for e in result.events]
    peak = np.max(np.abs(result.commands_mm), axis=0)
    doc = {"controller": runtime.name, "commands": int(result.commands_mm.shape[0]),
           "peak_correction_mm": {d: float(peak[a]) for d, a in zip("xyz", range(3), strict=True)},
           "record_made": record_made, "guard_events": events, "rms_mm": result.rms_mm,
           "output": None if output is None else str(output)}  # fmt: skip
    if json_out:
        emit_json(doc, units={"target": "1 (guard fade target)", "commands": "count"})
        return
    typer.echo(f"{runtime.name}: {doc['commands']} commands over {result.time_s[-1]:.2f} s, "
               "peak correction " + ", ".join(f"{d} {v:.4f} mm" for d, v in doc["peak_correction_mm"].items()))  # fmt: skip
    typer.echo("guard: " + ("no event (full correction throughout)" if not events else ""))
    for e in events:
        typer.echo(f"  {e['time_s']:.2f} s -> {e['target']:g}: {e['reason']}")
    for d, v in result.rms_mm.items():
        typer.echo(f"RMS {d.upper()}: measured {v['measured']:.4f} mm, model open loop "
                   f"{v['predicted_open']:.4f} mm, model with the correction "
                   f"{v['predicted_corrected']:.4f} mm")  # fmt: skip
    if output is not None:
        typer.echo(f"wrote {output}")


def register(app: typer.Typer) -> None:
    """Add ``simulate``, ``design`` and ``replay`` to the ``control`` group, in that order.

    Parameters
    ----------
    app : typer.Typer
        The ``robovib control`` group.
    """
    app.command("simulate")(simulate)
    app.command("design")(design)
    app.command("replay")(replay_cmd)
