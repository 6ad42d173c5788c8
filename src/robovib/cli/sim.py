"""``robovib sim``: the virtual robot (synthetic hammer tests, milling passes, offset-mass runs)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from ..files.units import from_si, to_si
from ._common import (
    JsonFlag,
    OutOpt,
    SeedOpt,
    emit_json,
    fail,
    material,
    new_app,
)
from ._control_options import DisturbanceOpt, parse_disturbances

app = new_app("The virtual robot: synthetic hammer tests, milling passes and offset-mass runs.")
#: The virtual robot's workspace pose (:mod:`robovib.sim`): metres and degrees.
_WORKSPACE_M = ("x_m", "y_m", "rz_deg")

PathFromOpt = Annotated[
    float | None,
    typer.Option(
        "--path-s-from",
        help="Run along the chapter-4 path instead: start distance [m] (0 = retracted, 1.235 = extended).",
    ),
]
PathToOpt = Annotated[
    float | None, typer.Option("--path-s-to", help="End distance along the chapter-4 path [m].")
]
RobotSeedOpt = Annotated[
    int | None,
    typer.Option(
        "--robot-seed",
        min=0,
        help="Simulate a robot robovib has never seen: the member of the virtual-robot family "
        "drawn from this seed (robovib.sim.family; default: the thesis robot).",
    ),
]


def _robot(robot_seed: int | None):
    """The thesis robot, or the family's robot drawn from ``robot_seed``."""
    from ..sim import VirtualRobot

    try:
        return VirtualRobot.variant(robot_seed)
    except ValueError as exc:
        fail(str(exc))


@app.command("hammer")
def hammer(
    output: OutOpt,
    x: Annotated[
        float, typer.Option("--x", help="Tool-tip X [mm] (workspace 2100-2700).")
    ] = 2400.0,
    y: Annotated[float, typer.Option("--y", help="Tool-tip Y [mm] (workspace -300-600).")] = 0.0,
    rz: Annotated[
        float, typer.Option("--rz", help="Rotation about the tool axis [deg] (0-180).")
    ] = 45.0,
    direction: Annotated[str, typer.Option(help="Hit and response direction x, y or z.")] = "x",
    hits: Annotated[int, typer.Option(help="Number of hits.")] = 5,
    sample_rate_hz: Annotated[
        float, typer.Option(help="Accelerometer/hammer sample rate [Hz].")
    ] = 17066.0,
    duration_s: Annotated[float, typer.Option(help="Record length per hit [s].")] = 4.0,
    snr_db: Annotated[float, typer.Option(help="Response signal-to-noise ratio [dB].")] = 40.0,
    path_s: Annotated[
        float | None,
        typer.Option(
            "--path-s",
            help="Test on the chapter-4 path instead: distance from its start [m] (0-1.235).",
        ),
    ] = None,
    seed: SeedOpt = 0,
    robot_seed: RobotSeedOpt = None,
    json_out: JsonFlag = False,
) -> None:
    """Impact-hammer test of the virtual robot at a workspace pose (or a path point), UFF 58 or CSV."""
    from ..gp.pose_units import pose_in_units
    from ..io import write_recording
    from ..sim import simulate_hammer_test

    if path_s is None:  # the virtual robot takes metres: units named, no conversion by hand
        where = tuple(map(float, pose_in_units(_WORKSPACE_M, {"x_mm": x, "y_mm": y, "rz_deg": rz})))
        domain = "workspace"
    else:
        where, domain = path_s, "path"
    rec = simulate_hammer_test(
        _robot(robot_seed), where, direction, domain=domain, n_hits=hits,
        sample_rate_hz=sample_rate_hz, duration_s=duration_s, snr_db=snr_db, rng=seed,
    )  # fmt: skip
    write_recording(output, rec)
    doc = {"output": str(output), "pose_mm_deg": [x, y, 325.0, 0.0, 0.0, rz], "direction": direction,
           "hits": rec.n_hits, "sample_rate_hz": rec.sample_rate_hz, "samples_per_hit": int(rec.forces.shape[1])}  # fmt: skip
    if json_out:
        emit_json(doc)
    else:
        typer.echo(
            f"wrote {output}: {rec.n_hits} hits, {rec.forces.shape[1]} samples at {rec.sample_rate_hz:g} Hz, direction {direction}"
        )


@app.command("mill")
def mill(
    output: OutOpt,
    x0: Annotated[float, typer.Option(help="Start X [mm].")] = 2100.0,
    y0: Annotated[float, typer.Option(help="Start Y [mm].")] = 0.0,
    x1: Annotated[float, typer.Option(help="End X [mm].")] = 2700.0,
    y1: Annotated[float, typer.Option(help="End Y [mm].")] = 0.0,
    rz: Annotated[float, typer.Option("--rz", help="Rotation about the tool axis [deg].")] = 0.0,
    rpm: Annotated[float, typer.Option(help="Spindle speed [rpm].")] = 1750.0,
    fz_mm: Annotated[float, typer.Option("--fz", help="Feed per tooth [mm].")] = 0.058,
    ap_mm: Annotated[float, typer.Option("--ap", help="Axial depth of cut [mm].")] = 3.0,
    ae_mm: Annotated[
        float, typer.Option("--ae", help="Radial depth of cut [mm] (25.4 = slotting).")
    ] = 25.4,
    material_name: Annotated[
        str, typer.Option("--material", help="Cutting-coefficient preset: al7075 or acetal.")
    ] = "al7075",
    path_s_from: PathFromOpt = None,
    path_s_to: PathToOpt = None,
    background: Annotated[
        float, typer.Option(help="Broadband force content (x spread of the periodic force).")
    ] = 0.15,
    disturbance: DisturbanceOpt = None,
    seed: SeedOpt = 0,
    robot_seed: RobotSeedOpt = None,
    json_out: JsonFlag = False,
) -> None:
    """Milling pass on the virtual robot (thesis §3.5: 25.4 mm 2-flute 30° helix tool); CSV out.

    ``--disturbance`` makes the cut real (open loop: the actuator gain and delay errors only
    matter under control, ``robovib control simulate milling``).
    """
    from ..milling import CuttingConditions, MillingTool
    from ..sim import LinearMove, simulate_milling

    coefficients = material(material_name)
    dist = parse_disturbances(disturbance)
    if (path_s_from is None) != (path_s_to is None):
        raise typer.BadParameter("give both --path-s-from and --path-s-to [m], or neither")
    cond = CuttingConditions(rpm, to_si(fz_mm, "mm"), to_si(ap_mm, "mm"), to_si(ae_mm, "mm"))
    if path_s_from is None:
        from ..gp.pose_units import pose_in_units

        start, end = (
            tuple(map(float, pose_in_units(_WORKSPACE_M, {"x_mm": a, "y_mm": b, "rz_deg": rz})))
            for a, b in ((x0, y0), (x1, y1))
        )
        move = LinearMove("workspace", start, end)
    else:
        move = LinearMove("path", (path_s_from,), (path_s_to,))
    run = simulate_milling(
        _robot(robot_seed), move, MillingTool(), cond, coefficients,
        background_noise_rel=background, disturbances=dist if dist.active() else None, rng=seed,
    )  # fmt: skip
    run.to_csv(output)
    doc = {
        "output": str(output), "samples": int(run.time_s.size), "duration_s": float(run.time_s[-1]),
        "mean_force_n": run.force_n.mean(axis=0), "mean_deflection_mm": from_si(run.true_displacement_m.mean(axis=0), "mm"),
        **run.meta,
    }  # fmt: skip
    if json_out:
        emit_json(doc)
    else:
        typer.echo(
            f"wrote {output}: {run.time_s.size} samples over {run.time_s[-1]:.1f} s; mean deflection "
            f"X/Y/Z = {', '.join(f'{v:.3f}' for v in doc['mean_deflection_mm'])} mm"
        )


@app.command("offset-mass")
def offset_mass(
    output: OutOpt,
    rpm: Annotated[
        float, typer.Option(help="Spindle speed [rpm] (thesis: 480, 960, 1440).")
    ] = 480.0,
    path_s_from: Annotated[
        float,
        typer.Option(
            "--path-s-from",
            help="Start on the chapter-4 path [m] (0 = retracted, 1.235 = extended).",
        ),
    ] = 1.235,
    path_s_to: Annotated[
        float, typer.Option("--path-s-to", help="End on the chapter-4 path [m].")
    ] = 0.335,
    speed_mm_s: Annotated[
        float, typer.Option("--speed", help="Robot speed along the path [mm/s].")
    ] = 84.0,
    seed: SeedOpt = 0,
    robot_seed: RobotSeedOpt = None,
    json_out: JsonFlag = False,
) -> None:
    """Rotating offset-mass run (1 kg at 50.8 mm, thesis §4.3.3) along the chapter-4 path; CSV out."""
    from ..sim import LinearMove, simulate_offset_mass

    run = simulate_offset_mass(
        _robot(robot_seed),
        LinearMove("path", (path_s_from,), (path_s_to,)),
        rpm,
        speed_m_per_s=to_si(speed_mm_s, "mm/s"),
        rng=seed,
    )
    run.to_csv(output)
    amp = from_si(run.peak_vibration_m, "mm")
    doc = {"output": str(output), "samples": int(run.time_s.size), "peak_vibration_mm": amp}
    if json_out:
        emit_json(doc)
    else:
        typer.echo(
            f"wrote {output}: {run.time_s.size} samples; peak vibration X/Y = {amp[0]:.3f}/{amp[1]:.3f} mm"
        )


@app.command("campaign")
def campaign(
    poses: Annotated[Path, typer.Option("--poses", help="CSV of poses: x_mm, y_mm, rz_deg.")],
    output: Annotated[Path, typer.Option("-o", "--output", help="Folder for the campaign.")],
    hits: Annotated[int, typer.Option(min=1, help="Hits per recording.")] = 3,
    duration_s: Annotated[float, typer.Option(help="Seconds per hit.")] = 2.0,
    sample_rate_hz: Annotated[float, typer.Option(help="Sample rate [Hz].")] = 1280.0,
    truth: Annotated[int, typer.Option(min=0, help="Unseen poses in truth.csv.")] = 20,
    scatter: Annotated[
        str | None,
        typer.Option(
            help="Test-to-test scatter 'fn,k,zeta' as relative stds, e.g. 0.01,0.04,0.04."
        ),
    ] = None,
    seed: SeedOpt = 0,
    robot_seed: RobotSeedOpt = None,
    json_out: JsonFlag = False,
) -> None:
    """A virtual hammer campaign: recordings in mixed layouts, manifest and truth at unseen poses."""
    from ..sim import simulate_campaign

    rel = None
    if scatter is not None:
        try:
            rel = tuple(float(v) for v in scatter.split(","))
        except ValueError:
            fail(f"--scatter must be three numbers 'fn,k,zeta', got {scatter!r}")
    res = simulate_campaign(poses, output, rng=seed, n_hits=hits, duration_s=duration_s,
                            sample_rate_hz=sample_rate_hz, n_truth=truth,
                            scatter=rel, robot=_robot(robot_seed))  # fmt: skip
    doc = {
        "manifest": str(res.manifest),
        "truth": str(res.truth),
        "recordings": len(res.recordings),
    }
    if json_out:
        emit_json(doc)
    else:
        typer.echo(f"wrote {res.manifest} ({len(res.recordings)} recordings) and {res.truth}")
