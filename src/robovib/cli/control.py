"""``robovib control``: pose-dependent LQR vibration control (thesis ch. 4)."""

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
    Table,
    about_file,
    check_output,
    console,
    emit_json,
    escape,
    fail,
    new_app,
    save_figure,
    use_agg,
    workspace_model,
)
from ._control_options import ActuatorOpt, ControllerOpt, DisturbanceOpt, parse_disturbances

app = new_app("Pose-dependent LQR vibration control (thesis chapter 4).")


@app.command("gains")
def gains(
    x: Annotated[float, typer.Option("--x", help="Tool-tip X [mm].")],
    y: Annotated[float, typer.Option("--y", help="Tool-tip Y [mm].")],
    rz: Annotated[float, typer.Option("--rz", help="Rotation about the tool axis [deg].")],
    direction: Annotated[str, typer.Option(help="x, y or z.")] = "x",
    period_ms: Annotated[float, typer.Option(help="Command period [ms] (RSI: 4 ms).")] = 4.0,
    delay_ms: Annotated[float, typer.Option(help="Actuator delay [ms] (KRC4: 32 ms).")] = 32.0,
    r: Annotated[float, typer.Option("--r", help="Input weight R (Q = diag(1, 0.001)).")] = 0.001,
    model_path: ModelOpt = None,
    json_out: JsonFlag = False,
) -> None:
    """LQR gains W = [w1, w2] at a pose from the GP's predicted mode, with the delay analysis."""
    from ..control import (
        delay_analysis,
        design_delay_aware_lqr,
        design_lqr,
        loop_margins,
        tune_r_for_delay,
    )
    from ..gp.contract import pick_mode
    from ..io import from_si, to_si
    from ..milling.workflow import pose_extrapolation, pose_modes

    if direction not in ("x", "y", "z"):
        fail(f"unknown direction {direction!r}: give x, y or z")
    model = workspace_model(model_path)
    pose_modes(model, (x, y, rz))  # checks the pose, names a bad coordinate
    picked = pick_mode(model, (x, y, rz), direction)  # one mode: says which, of several
    outside = list(pose_extrapolation(model, (x, y, rz)))
    mode = picked.mode.parameters
    period_s, delay_s = to_si(period_ms, "ms"), to_si(delay_ms, "ms")
    d = design_lqr(mode, period_s, r=[[r]])
    da = delay_analysis(d, delay_s)
    tuned, r_tuned = tune_r_for_delay(mode, period_s, delay_s)
    aware = design_delay_aware_lqr(mode, period_s, delay_s, r=[[1.0]])
    margins = loop_margins(d, round(delay_ms / period_ms))
    max_delay_ms = from_si(da.max_stable_delay_s, "ms")
    tuned_stable = delay_analysis(tuned, delay_s).stable
    if da.stable:
        lead = {"design": "lqr", "gains": list(d.gains), "stable_with_delay": True,
                "advice": f"the LQR gains (R = {r:g}) are stable with the delay"}  # fmt: skip
    elif aware.spectral_radius < 1:
        lead = {"design": "delay-aware-lqr", "gains": list(aware.gains), "stable_with_delay": True,
                "advice": "the delay-aware LQR (R = 1) on [x, v, u_{k-1}..u_{k-d}]; the 2-gain "
                          "W of the thesis is unstable with the delay at this R"}  # fmt: skip
    else:
        lead = {"design": None, "gains": None, "stable_with_delay": False,
                "advice": "no state feedback designed here is stable with the delay: use "
                          "feedforward (feedforward+robust) or repetitive control "
                          "(adaptive+force): robovib control design"}  # fmt: skip
    doc = {
        "recommended": lead,
        "extrapolation": outside, "mode_id": picked.mode.mode_id,
        **({"mode_choice": picked.reason} if picked.reason else {}),
        "mode": mode.to_dict(), "w1": d.gains[0], "w2": d.gains[1], "spectral_radius_no_delay": d.spectral_radius,
        "stable_with_delay": da.stable, "spectral_radius_with_delay": da.spectral_radius,
        "max_stable_delay_ms": max_delay_ms,
        "delay_tuned": {"r": r_tuned, "w1": tuned.gains[0], "w2": tuned.gains[1]},
        "delay_aware": {"gains": aware.gains, "spectral_radius": aware.spectral_radius},
        "margins_with_delay": {"gain_margins": margins.gain_margins, "phase_crossovers_hz": margins.phase_crossovers_hz,
                               "phase_margins_deg": margins.phase_margins_deg, "gain_crossovers_hz": margins.gain_crossovers_hz},
    }  # fmt: skip
    if json_out:
        emit_json(doc)
        return
    if picked.reason:
        typer.echo(f"note: {picked.reason}")
    typer.echo(
        f"mode: fn {mode.natural_frequency_hz:.2f} Hz, k {mode.stiffness_n_per_m / 1e6:.3f} MN/m, zeta {mode.damping_ratio:.3f}"
    )
    if lead["design"] == "lqr":
        typer.echo(f"stable with the {delay_ms:g} ms delay: W below (R = {r:g})")
    elif lead["design"] == "delay-aware-lqr":
        n_hist = len(aware.gains) - 2
        typer.echo(f"stable with the {delay_ms:g} ms delay: delay-aware LQR (R = 1), u = -K [x, v, "
                   f"u_k-1 .. u_k-{n_hist}], K = [{aware.gains[0]:.4g} m/m, {aware.gains[1]:.4g} s, "
                   + ", ".join(f"{g:.3g}" for g in aware.gains[2:])
                   + f"] (spectral radius {aware.spectral_radius:.3f})")  # fmt: skip
    else:
        typer.echo(f"NO state feedback here is stable with the {delay_ms:g} ms delay: use feedforward "
                   "or repetitive control (robovib control design --controller adaptive+force "
                   "or feedforward+robust)")  # fmt: skip
    if not tuned_stable and lead["design"] != "lqr":
        typer.echo("the thesis' 2-gain form below is unstable with the delay at every R tried")
    typer.echo(f"W = [w1 {d.gains[0]:.4g} m/m, w2 {d.gains[1]:.4g} s] (R = {r:g}; a path-correction "
               f"command per m and per m/s of tool-tip motion); with {delay_ms:g} ms delay: "
               f"{'stable' if da.stable else 'UNSTABLE'} (spectral radius {da.spectral_radius:.3f}, largest stable delay {max_delay_ms:g} ms)")  # fmt: skip
    if not da.stable:
        typer.echo(
            f"best-damped R with the delay: {r_tuned:.3g} -> W = [{tuned.gains[0]:.4g} m/m, "
            f"{tuned.gains[1]:.4g} s] ({'stable' if tuned_stable else 'UNSTABLE'} with the delay)"
        )
    if margins.gain_margins.size:
        typer.echo(
            f"gain margin with the delay: {margins.gain_margins[0]:.3g} at {margins.phase_crossovers_hz[0]:.2f} Hz"
        )
    typer.echo(f"delay-aware LQR (R = 1): spectral radius {aware.spectral_radius:.3f}")
    if outside:
        typer.echo(
            f"warning: {', '.join(outside)} outside the calibrated workspace: the mode is a GP "
            "extrapolation"
        )


@app.command("schedule")
def schedule(
    path_file: Annotated[
        Path | None,
        typer.Option(
            "--path-file",
            help="CSV of modes along a path: s_m, fn_hz, stiffness_n_per_m, damping_ratio. Default: virtual-robot EMA along the chapter-4 path.",
        ),
    ] = None,
    direction: Annotated[
        str,
        typer.Option(
            help="Direction whose mode is controlled (x, y, z): of the virtual-robot path model, or of the pose model with --start/--end."
        ),
    ] = "x",
    start: Annotated[
        str | None,
        typer.Option(
            help="Line start pose in the model's input units, comma-separated (e.g. 2400,0,45 for x_mm,y_mm,rz_deg); with --end, gains from the pose model along the line."
        ),
    ] = None,
    end: Annotated[str | None, typer.Option(help="Line end pose (as --start).")] = None,
    points: Annotated[
        int | None,
        typer.Option(help="Design points along the --start/--end line (>= 5; default 20)."),
    ] = None,
    model_path: ModelOpt = None,
    plot: Annotated[
        Path | None, typer.Option(help="PNG of w1, w2 vs path distance (thesis Fig. 23).")
    ] = None,
    seed: SeedOpt = 0,
    json_out: JsonFlag = False,
) -> None:
    """Gains along a path (R tuned for the 32 ms delay), with the Eq. 28-29 polynomial fits."""
    from ..control.schedule import schedule_gains

    check_output(plot, [p for p in (path_file, model_path) if p is not None])
    warnings_seen: list[str] = []
    if (start is None) != (end is None):
        fail("give both --start and --end (a line through the pose model), or neither")
    if start is not None and path_file is not None:
        fail("give either --path-file or --start/--end, not both")
    if start is not None:
        points = 20 if points is None else points
        if points < 5:
            fail(f"--points must be at least 5 (design points along the line), got {points}")
        _schedule_line(start, end, points, direction, model_path, seed, plot, json_out)
        return
    if model_path is not None or points is not None:
        fail("--model and --points need --start and --end (the line to schedule along)")
    if path_file is not None:
        from ..io import read_path_modes_csv

        s, modes = read_path_modes_csv(path_file)
    else:
        from ..sim import virtual_path_modes

        s, modes = virtual_path_modes(direction=direction, rng=seed)
    with about_file(path_file):  # "too few path points" names the file
        sched = schedule_gains(s, modes, warn=warnings_seen.append)

    def draw() -> None:
        if plot is not None:
            use_agg()
            save_figure(sched.plot(), plot)

    doc = {"s_m": sched.s_m, "w1": sched.w1, "w2": sched.w2, "r": sched.r, "stable_with_delay": sched.stable_with_delay,
           "w1_poly_high_to_low": sched.w1_poly, "w2_poly_high_to_low": sched.w2_poly, "warnings": warnings_seen}  # fmt: skip
    if json_out:
        emit_json(doc)
        draw()
        return
    for si, w1, w2, rr, ok in zip(sched.s_m, sched.w1, sched.w2, sched.r, sched.stable_with_delay, strict=True):  # fmt: skip
        typer.echo(f"s = {si:6.3f} m   w1 = {w1:10.3e} m/m   w2 = {w2:10.3e} s   R = {rr:8.3g}   "
                   f"stable with 32 ms delay: {'yes' if ok else 'NO'}")  # fmt: skip
    for w in warnings_seen:
        typer.echo(f"warning: {w}")
    if plot is not None:
        draw()
        typer.echo(f"wrote {plot}")


def _pose(text: str, option: str) -> list[float]:
    try:
        values = [float(v) for v in text.split(",")]
    except ValueError:
        fail(f"{option} must be comma-separated numbers, got {text!r}")
    return values


def _schedule_line(start, end, points, direction, model_path, seed, plot, json_out) -> None:
    from ..control.schedule import schedule_along_line

    model = workspace_model(model_path, seed, require_inputs=None)  # a line in any inputs
    warnings_seen: list[str] = []
    result = schedule_along_line(model, _pose(start, "--start"), _pose(end, "--end"), direction,
                                 points, warn=warnings_seen.append)  # fmt: skip
    sched = result.schedule
    if result.mode_choice:
        warnings_seen.append(result.mode_choice)
    outside = [int(i) for i in np.flatnonzero(result.extrapolating)]
    if outside:
        warnings_seen.append(f"{len(outside)} of {points} poses lie outside the model's training data: their modes are GP extrapolations")  # fmt: skip
    doc = {"input_names": list(result.input_names), "poses": result.poses, "s_m": sched.s_m,
           "mode": [m.to_dict() for m in result.modes], "w1": sched.w1, "w2": sched.w2,
           "r": sched.r, "stable_with_delay": sched.stable_with_delay,
           "extrapolating": result.extrapolating, "w1_poly_high_to_low": sched.w1_poly,
           "w2_poly_high_to_low": sched.w2_poly, "warnings": warnings_seen}  # fmt: skip
    if json_out:
        units = ", ".join(result.input_names)
        emit_json(doc, units={"poses": f"model input units ({units}), one row per point"})
    else:
        for si, pose, m, w1, w2, ok, ex in zip(sched.s_m, result.poses, result.modes, sched.w1, sched.w2, sched.stable_with_delay, result.extrapolating, strict=True):  # fmt: skip
            flag = "  (extrapolation)" if ex else ""
            typer.echo(f"s = {si:6.3f} m  pose {', '.join(f'{v:g}' for v in pose)}  fn {m.natural_frequency_hz:6.2f} Hz  w1 = {w1:10.3e} m/m  w2 = {w2:10.3e} s  stable with 32 ms delay: {'yes' if ok else 'NO'}{flag}")  # fmt: skip
        for w in warnings_seen:
            typer.echo(f"warning: {w}")
    if plot is not None:
        use_agg()
        save_figure(sched.plot(), plot)
        if not json_out:
            typer.echo(f"wrote {plot}")


@app.command("table9")
def table9(json_out: JsonFlag = False) -> None:
    """Gains from the thesis' Table 8 inputs under each plant formulation, beside Table 9."""
    from ..studies.table9 import table_9_comparison

    rows = table_9_comparison().to_dict()["rows"]
    if json_out:
        emit_json({"rows": rows})
        return
    t = Table(
        title="LQR gains from Table 8 predictions (T = 4 ms, Q = diag(1, 0.001), R = 0.001) vs Table 9"
    )
    for col in ("formulation", "input", "pos", "dir", "w1", "thesis w1", "w2", "thesis w2"):
        t.add_column(col, justify="right")
    for r in rows:
        t.add_row(
            r["formulation"], r["input"], str(r["position"]), r["direction"], f"{r['w1']:.4g}",
            f"{r['thesis_w1']:.3g}", f"{r['w2']:.4g}", f"{r['thesis_w2']:.3g}",
        )  # fmt: skip
    con = console()
    con.print(t)
    con.print("w1 in m/m and w2 in s for displacement input, N/m and N*s/m for force input. No "
              "formulation reproduces the printed Table 9 gains (force or displacement input, SI or "
              "mm, T = 4 or 1 ms were all tried; see docs/data.md): compare trends, not values.")  # fmt: skip


@app.command("simulate")
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

    from ..studies.control_closed_loop import simulate_control

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


@app.command("design")
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
    from ..control.path_design import ControlPath
    from ..control.runtime import design_controller, write_controller_file
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
            vertices = [_pose(start, "--start"), _pose(end, "--end")]
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
                             if k.endswith(("radius", "ratio"))}}  # fmt: skip
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
    if summary["extrapolating_points"]:
        typer.echo(f"warning: {summary['extrapolating_points']} design points lie outside the "
                   "model's training data (GP extrapolation)")  # fmt: skip


@app.command("replay")
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
    from ..control.runtime import load_controller, replay
    from ..io import read_milling_record_csv

    check_output(output, [controller_file, record], force)
    try:
        runtime = load_controller(controller_file)
        result = replay(runtime, read_milling_record_csv(record), spindle_rpm=rpm, teeth=teeth,
                        record_made=record_made)  # fmt: skip
    except ValueError as exc:
        fail(str(exc))
    if output is not None:
        from ..io.safe_write import atomic_output

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
