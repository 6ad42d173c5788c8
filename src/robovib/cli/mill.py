"""``robovib mill``: milling vibration and chatter stability at a pose (thesis §3.5)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import numpy as np
import typer

from ._common import (
    JsonFlag,
    SeedOpt,
    Table,
    console,
    emit_json,
    escape,
    material,
    new_app,
    save_figure,
    use_agg,
)

app = new_app("Milling vibration and chatter stability at a pose (thesis §3.5).")
XOpt = Annotated[float, typer.Option("--x", help="Tool-tip X [mm].")]
YOpt = Annotated[float, typer.Option("--y", help="Tool-tip Y [mm].")]
RzOpt = Annotated[float, typer.Option("--rz", help="Rotation about the tool axis [deg].")]
RpmOpt = Annotated[float, typer.Option(help="Spindle speed [rpm].")]
FzOpt = Annotated[float, typer.Option("--fz", help="Feed per tooth [mm].")]
ApOpt = Annotated[float, typer.Option("--ap", help="Axial depth of cut [mm].")]
AeOpt = Annotated[
    float,
    typer.Option("--ae", help="Radial depth of cut [mm] (25.4 = slotting with the 25.4 mm tool)."),
]
MaterialOpt = Annotated[
    str, typer.Option("--material", help="Cutting-coefficient preset: al7075 or acetal.")
]
FeedOpt = Annotated[str, typer.Option(help="Feed direction in the base frame: x or y.")]


@app.command("predict")
def predict(
    x: XOpt,
    y: YOpt,
    rz: RzOpt,
    rpm: RpmOpt = 1750.0,
    fz: FzOpt = 0.058,
    ap: ApOpt = 3.0,
    ae: AeOpt = 25.4,
    material_name: MaterialOpt = "al7075",
    feed: FeedOpt = "x",
    forces: Annotated[
        Path | None,
        typer.Option(
            help="Measured forces CSV (time_s, force_x_n, force_y_n, force_z_n), any rate."
        ),
    ] = None,
    samples: Annotated[
        int, typer.Option(help="Monte-Carlo draws of the GP prediction for the band.")
    ] = 50,
    seed: SeedOpt = 0,
    json_out: JsonFlag = False,
) -> None:
    """Mean deflection and peak-to-valley per revolution at a pose, with 95 % bands."""
    from ..gp.study import fit_chapter3_model
    from ..io import read_force_csv
    from ..milling import CuttingConditions
    from ..milling.prediction import resample_force
    from ..milling.workflow import predict_at_pose

    cond = CuttingConditions(rpm, fz / 1e3, ap / 1e3, ae / 1e3)
    f = resample_force(*read_force_csv(forces), 1000.0) if forces is not None else None
    res = predict_at_pose(
        fit_chapter3_model(rng=seed), x, y, rz, cond, coefficients=material(material_name),
        forces_n=f, feed_direction=feed, n_samples=samples, rng=seed,
    )  # fmt: skip
    rows = [
        {"direction": r.direction, "mean_deflection_mm": 1e3 * r.mean_deflection_m,
         "mean_deflection_band_mm": [1e3 * v for v in r.mean_deflection_band_m],
         "peak_to_valley_mm": 1e3 * r.peak_to_valley_m,
         "peak_to_valley_band_mm": [1e3 * v for v in r.peak_to_valley_band_m],
         "mode": r.mode.to_dict()}
        for r in res
    ]  # fmt: skip
    if json_out:
        emit_json({"pose_mm_deg": [x, y, 325.0, 0, 0, rz], "spindle_rpm": rpm, "predictions": rows})
        return
    con = console()
    t = Table(
        title=f"Milling vibration at X={x:g}, Y={y:g} mm, Rz={rz:g}° ({rpm:g} rpm, fz {fz} mm, ap {ap} mm, ae {ae} mm)"
    )
    for col in ("dir", "mode fn [Hz]", "mean deflection [mm]", "95 % band", "P-V / rev [mm]",
                "95 % band"):  # fmt: skip
        t.add_column(escape(col), justify="right")
    for r in rows:
        t.add_row(
            r["direction"].upper(), f"{r['mode']['natural_frequency_hz']:.2f}", f"{r['mean_deflection_mm']:.4f}",
            escape(f"[{r['mean_deflection_band_mm'][0]:.4f}, {r['mean_deflection_band_mm'][1]:.4f}]"),
            f"{r['peak_to_valley_mm']:.4f}", escape(f"[{r['peak_to_valley_band_mm'][0]:.4f}, {r['peak_to_valley_band_mm'][1]:.4f}]"),
        )  # fmt: skip
    con.print(t)


@app.command("lobes")
def lobes(
    x: XOpt,
    y: YOpt,
    rz: RzOpt,
    ae: AeOpt = 6.0,
    material_name: MaterialOpt = "al7075",
    feed: FeedOpt = "x",
    rpm_min: Annotated[float, typer.Option(help="Lowest speed of the plot [rpm].")] = 100.0,
    rpm_max: Annotated[float, typer.Option(help="Highest speed of the plot [rpm].")] = 3000.0,
    plot: Annotated[Path | None, typer.Option(help="PNG of the lobes.")] = None,
    seed: SeedOpt = 0,
    json_out: JsonFlag = False,
) -> None:
    """Stability lobes (zero-order method) from the pose's predicted X/Y modes."""
    from ..gp.study import fit_chapter3_model
    from ..milling import CuttingConditions, MillingTool
    from ..milling.stability import stability_lobes
    from ..milling.workflow import pose_modes

    modes, _, _ = pose_modes(fit_chapter3_model(rng=seed), x, y, rz)
    cond = CuttingConditions(1000.0, 1e-4, 1e-3, ae / 1e3)
    feed_dir, normal = ("x", "y") if feed == "x" else ("y", "x")
    result = stability_lobes(
        [modes[feed_dir]], [modes[normal]], MillingTool(), cond, material(material_name),
        n_lobes=40,
    )  # fmt: skip
    speeds = np.linspace(rpm_min, rpm_max, 200)
    crit = result.critical_depth(speeds)
    doc = {
        "minimum_critical_depth_mm": 1e3 * result.minimum_depth_m,
        "spindle_rpm": speeds,
        "critical_depth_mm": 1e3 * crit,
    }
    if json_out:
        emit_json(doc)
    else:
        typer.echo(
            f"minimum critical axial depth (all speeds): {doc['minimum_critical_depth_mm']:.3f} mm"
        )
        best = int(np.argmax(crit))
        typer.echo(
            f"most stable speed in {rpm_min:g}-{rpm_max:g} rpm: {speeds[best]:.0f} rpm ({1e3 * crit[best]:.2f} mm)"
        )
    if plot is not None:
        use_agg()
        result.plot(path=plot, rpm_range=(rpm_min, rpm_max))
        if not json_out:
            typer.echo(f"wrote {plot}")


@app.command("map")
def lobe_map(
    rz: Annotated[float, typer.Option("--rz", help="Rotation about the tool axis [deg].")] = 0.0,
    rpm: RpmOpt = 1750.0,
    ae: AeOpt = 6.0,
    material_name: MaterialOpt = "al7075",
    feed: FeedOpt = "x",
    nx: Annotated[int, typer.Option(help="Grid points in X.")] = 13,
    ny: Annotated[int, typer.Option(help="Grid points in Y.")] = 10,
    plot: Annotated[Path | None, typer.Option(help="PNG heat map over X-Y.")] = None,
    seed: SeedOpt = 0,
    json_out: JsonFlag = False,
) -> None:
    """Critical axial depth at a spindle speed over the workspace: where to mill."""
    from rich.progress import Progress

    from ..gp.study import fit_chapter3_model
    from ..milling import CuttingConditions, MillingTool
    from ..milling.workflow import best_pose, plot_lobe_map, workspace_lobe_map

    xs, ys = np.linspace(2100, 2700, nx), np.linspace(-300, 600, ny)
    model = fit_chapter3_model(rng=seed)
    cond = CuttingConditions(rpm, 1e-4, 1e-3, ae / 1e3)
    with Progress(transient=True, disable=json_out) as bar:
        task = bar.add_task("lobes over the workspace", total=nx * ny)
        grid = workspace_lobe_map(
            model, rz, MillingTool(), cond, material(material_name), x_mm=xs, y_mm=ys,
            feed_direction=feed, progress=lambda done, total: bar.update(task, completed=done),
        )  # fmt: skip
    best = best_pose(xs, ys, grid)
    doc = {
        "x_mm": xs,
        "y_mm": ys,
        "critical_depth_mm": grid * 1e3,
        "best_pose_mm": best["best_pose_mm"],
        "best_depth_mm": best["best_depth_mm"],
    }
    if json_out:
        emit_json(doc)
    else:
        bx, by = best["best_pose_mm"]
        typer.echo(
            f"deepest stable cut at X={bx:.0f}, Y={by:.0f} mm: {best['best_depth_mm']:.2f} mm; "
            f"shallowest: {best['shallowest_depth_mm']:.2f} mm"
        )
    if plot is not None:
        use_agg()
        title = f"critical depth at {rpm:g} rpm, Rz = {rz:g}°, ae = {ae:g} mm"
        save_figure(plot_lobe_map(xs, ys, grid, title=title), plot)
        if not json_out:
            typer.echo(f"wrote {plot}")
