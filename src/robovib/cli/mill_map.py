"""``robovib mill map``: chatter limits and P(stable) over the workspace (Dask), registered on
the ``mill`` group by :mod:`robovib.cli.mill`."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import numpy as np
import typer

from ..files.units import from_si, to_si
from . import _mill_options as opt
from ._common import (
    JsonFlag,
    ModelOpt,
    SeedOpt,
    check_output,
    emit_json,
    fail,
    material,
    save_figure,
    use_agg,
    workspace_model,
)


def lobe_map(
    rz: Annotated[float, typer.Option("--rz", help="Rotation about the tool axis [deg].")] = 0.0,
    rpm: opt.RpmOpt = 1750.0,
    rpm_range: Annotated[
        str | None,
        typer.Option("--rpm-range", help="Speeds MIN:MAX:N [rpm] (default: --rpm only)."),
    ] = None,
    method: Annotated[str, typer.Option("--method", help="zoa (fast) or sdm.")] = "zoa",
    teeth: opt.TeethOpt = 2,
    diameter: opt.DiameterOpt = 25.4,
    helix: opt.HelixOpt = 30.0,
    ae: opt.AeOpt = 6.0,
    radial_immersion: opt.RadialOpt = None,
    milling: opt.MillingOpt = "down",
    material_name: opt.MaterialOpt = "al7075",
    kt: opt.KtOpt = None,
    kn: opt.KnOpt = None,
    feed: opt.FeedOpt = "x",
    nx: Annotated[int, typer.Option(help="Grid points in X.")] = 13,
    ny: Annotated[int, typer.Option(help="Grid points in Y.")] = 10,
    scheduler: Annotated[
        str | None,
        typer.Option(
            help="Dask scheduler: sync, threads, processes or tcp://host:port (a cluster)."
        ),
    ] = None,
    workers: Annotated[
        int | None, typer.Option(help="Local Dask workers (default: all cores).")
    ] = None,
    chunk: Annotated[int, typer.Option(help="Poses per Dask task.")] = 4,
    steps: opt.StepsOpt = 40,
    samples: Annotated[
        int,
        typer.Option(
            help="Monte-Carlo samples of the pose model per pose (every modelled mode): the "
            "5/50/95 % critical depth and the best spot stable with 95 % (0: mean modes only)."
        ),
    ] = 0,
    depth: Annotated[
        float | None,
        typer.Option(
            help="With --samples: map the probability of a stable cut at this depth [mm]."
        ),
    ] = None,
    cuts: Annotated[
        Path | None,
        typer.Option(
            "--cuts",
            help="With --samples: test cuts CSV x_mm,y_mm,rz_deg,spindle_rpm,depth_mm,result "
            "update the 5/50/95 % depths and P(stable) (a posterior over the sampled structures).",
        ),
    ] = None,
    label_noise: opt.LabelNoiseOpt = 0.05,
    local_factor: opt.LocalFactorOpt = "0.55,1.3",
    common_factor: opt.CommonFactorOpt = "0.9,1.1",
    output: Annotated[
        Path | None, typer.Option("-o", "--output", help="NetCDF (.nc) of the map.")
    ] = None,
    plot: Annotated[Path | None, typer.Option(help="PNG map over X-Y at --rpm.")] = None,
    seed: SeedOpt = 0,
    model_path: ModelOpt = None,
    json_out: JsonFlag = False,
) -> None:
    """Critical axial depth over the workspace × spindle speeds (Dask): where and how fast to mill.

    With --model the grid spans the model's measured X-Y range and every modelled mode is used;
    --samples adds the uncertainty (5/50/95 % critical depth, P(stable) at --depth)."""
    from rich.progress import Progress

    from ..milling.maps import (
        WORKSPACE_X_MM,
        WORKSPACE_Y_MM,
        best_pose,
        map_speeds,
        plot_lobe_map,
        save_lobe_map,
        workspace_lobe_map,
    )
    from ._parsers import parse_rpm_range

    check_output(plot, [model_path, cuts])
    measured_cuts = None
    if cuts is not None:
        check_output(output, [model_path, cuts])
        from ..io.cuts import read_cuts_csv

        split, common = opt.factor_split(local_factor, common_factor)
        if samples < 2:
            fail("--cuts updates the sampled forecast: give --samples N (N >= 2)")
        measured_cuts = read_cuts_csv(cuts)
        if measured_cuts.pose_mm_deg is None:
            fail(f"{cuts}: a map's test cuts need their poses: add columns x_mm, y_mm, rz_deg")
    for name, n in (("--nx", nx), ("--ny", ny)):
        if n < 2:
            fail(f"{name} must be at least 2 grid points, got {n}")
    tool, cond, coef = opt.cutting(material(material_name), kt, kn, diameter, teeth, helix, ae,
                                radial_immersion, milling)  # fmt: skip
    speeds = map_speeds(rpm, None if rpm_range is None else parse_rpm_range(rpm_range))
    model = workspace_model(model_path, seed)
    box = (WORKSPACE_X_MM, WORKSPACE_Y_MM)
    if model_path is not None:  # your model: the grid spans the poses it was measured at
        box = (model.input_range()["x_mm"], model.input_range()["y_mm"])
    xs, ys = np.linspace(*box[0], nx), np.linspace(*box[1], ny)
    with Progress(transient=True, disable=json_out) as bar:
        task = bar.add_task(f"{method.upper()} lobes over the workspace", total=None)
        ds = workspace_lobe_map(
            model, xs, ys, [rz], speeds, tool, cond, coef, method=method, feed_direction=feed,
            scheduler=scheduler, n_workers=workers, poses_per_chunk=chunk,
            **({"steps_per_period": steps} if method == "sdm" else {}),
            progress=lambda done, total: bar.update(task, completed=done, total=total),
            n_samples=0 if cuts else samples, rng=seed,
            depth_m=None if depth is None or cuts else to_si(depth, "mm"),
        )  # fmt: skip
    if measured_cuts is not None:  # the weighted structures replace the per-pose samples
        from ..milling.cut_forecast import add_cut_forecast

        ds, _ = add_cut_forecast(
            ds, model, measured_cuts, tool, cond, coef, n_samples=samples, rng=seed,
            depth_m=None if depth is None else to_si(depth, "mm"), label_noise=label_noise,
            local_factor=split, common_factor=common,
        )  # fmt: skip
    if output is not None:
        save_lobe_map(ds, output)
    if plot is not None:
        use_agg()
        save_figure(plot_lobe_map(ds, spindle_rpm=rpm), plot)
    best = best_pose(ds, rpm, rz)
    doc = {
        "method": method,
        "rz_deg": rz,
        **(
            {"modes_feed": ds.attrs["feed_modes"], "modes_normal": ds.attrs["normal_modes"]}
            if model_path is not None
            else {}
        ),
        "spindle_rpm": rpm,
        "x_mm": xs,
        "y_mm": ys,
        **best,
        "netcdf": None if output is None else str(output),
        "settings": ds.attrs["settings"],
        "robovib_version": ds.attrs["robovib_version"],
    }
    if "test_cuts" in ds.attrs:
        import json

        doc["test_cuts"] = json.loads(ds.attrs["test_cuts"])
    if json_out:
        emit_json(doc)
        return
    typer.echo(
        f"deepest stable cut at {rpm:g} rpm: X={best['best_pose_mm'][0]:.0f}, "
        f"Y={best['best_pose_mm'][1]:.0f} mm: {from_si(best['best_depth_m'], 'mm'):.2f} mm; "
        f"shallowest: {from_si(best['shallowest_depth_m'], 'mm'):.2f} mm ({method.upper()})"
    )
    if samples:
        lo, hi = (from_si(v, "mm") for v in best["best_sure_depth_band_m"])
        if "test_cuts" in doc:
            opt.echo_cut_update(doc["test_cuts"], "over the map")
        typer.echo(
            f"deepest cut stable with 95 % ({samples} samples of the model): "
            f"X={best['best_sure_pose_mm'][0]:.0f}, Y={best['best_sure_pose_mm'][1]:.0f} mm: "
            f"{lo:.2f} mm (90 % band of the limit there {lo:.2f}-{hi:.2f} mm)"
        )
        if depth is not None:
            p = np.asarray(best["p_stable"])
            typer.echo(f"P(stable) at {depth:g} mm: {np.nanmin(p):.2f}-{np.nanmax(p):.2f} over "
                       f"the map; >= 0.95 at {int(np.sum(p >= 0.95))} of {p.size} poses")  # fmt: skip
    if model_path is not None:
        n_out = int(ds["extrapolating"].sel(rz_deg=rz).sum())
        n_none = int(np.isnan(ds["feed_fn_hz"].sel(rz_deg=rz).values).sum())
        typer.echo(f"grid: the model's measured range X {box[0][0]:g}-{box[0][1]:g} mm, "
                   f"Y {box[1][0]:g}-{box[1][1]:g} mm; modes {ds.attrs['feed_modes']} (feed), "
                   f"{ds.attrs['normal_modes']} (normal); {n_out} of {nx * ny} poses outside "
                   "the measured poses (extrapolation, crossed on the plot; the best spots are "
                   "chosen inside)"
                   + (f"; no physical mode predicted at {n_none}" if n_none else ""))  # fmt: skip
    for path in (output, plot):
        if path is not None:
            typer.echo(f"wrote {path}")


def register(app: typer.Typer) -> None:
    """Add ``map`` to the ``mill`` group.

    Parameters
    ----------
    app : typer.Typer
        The ``robovib mill`` group.
    """
    app.command("map")(lobe_map)
