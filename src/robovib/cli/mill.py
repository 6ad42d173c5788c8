"""``robovib mill``: milling vibration and chatter stability at a pose (thesis §3.5)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from ..files.units import from_si, to_si
from . import _mill_options as opt
from ._common import (
    JsonFlag,
    ModelOpt,
    SeedOpt,
    about_file,
    check_output,
    console,
    emit_json,
    material,
    new_app,
    print_table,
    save_figure,
    use_agg,
    workspace_model,
)

app = new_app("Milling vibration and chatter stability at a pose (thesis §3.5).")


@app.command("predict")
def predict(
    x: opt.XOpt,
    y: opt.YOpt,
    rz: opt.RzOpt,
    rpm: opt.RpmOpt = 1750.0,
    fz: opt.FzOpt = 0.058,
    ap: opt.ApOpt = 3.0,
    ae: opt.AeOpt = 25.4,
    material_name: opt.MaterialOpt = "al7075",
    feed: opt.FeedOpt = "x",
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
    model_path: ModelOpt = None,
    json_out: JsonFlag = False,
) -> None:
    """Mean deflection and peak-to-valley per revolution at a pose, with 95 % bands."""
    from ..milling import CuttingConditions
    from ..milling.at_pose import predict_at_pose

    cond = CuttingConditions(rpm, to_si(fz, "mm"), to_si(ap, "mm"), to_si(ae, "mm"))
    f = None
    if forces is not None:  # the CSV reader only when a force file is given
        from ..io import read_force_csv
        from ..milling.prediction import resample_force

        with about_file(forces):  # "not uniformly sampled" names the file
            f = resample_force(*read_force_csv(forces), 1000.0)
    pose_model = workspace_model(model_path, seed)
    res = predict_at_pose(
        pose_model, x, y, rz, cond, coefficients=material(material_name),
        forces_n=f, feed_direction=feed, n_samples=samples, rng=seed,
    )  # fmt: skip
    checks = _predict_checks(pose_model, (x, y, rz), cond, material(material_name), feed,
                             samples, res)  # fmt: skip
    rows = [
        {"direction": r.direction, "mean_deflection_mm": from_si(r.mean_deflection_m, "mm"),
         "mean_deflection_band_mm": [from_si(v, "mm") for v in r.mean_deflection_band_m],
         "peak_to_valley_mm": from_si(r.peak_to_valley_m, "mm"),
         "peak_to_valley_band_mm": [from_si(v, "mm") for v in r.peak_to_valley_band_m],
         "mode": r.mode.to_dict(), "modes": [m.to_dict() for m in r.modes or (r.mode,)]}
        for r in res
    ]  # fmt: skip
    outside = list(res[0].extrapolation)
    if json_out:
        emit_json({"pose_mm_deg": [x, y, 325.0, 0, 0, rz], "spindle_rpm": rpm,
                   "extrapolation": outside, "predictions": rows, **checks})  # fmt: skip
        return
    band = "[{:.4f}, {:.4f}]".format
    print_table(
        f"Milling vibration at X={x:g}, Y={y:g} mm, Rz={rz:g}° ({rpm:g} rpm, fz {fz} mm, ap {ap} mm, ae {ae} mm)",
        ("dir", "mode(s) fn [Hz]", "mean deflection [mm]", "95 % band", "P-V / rev [mm]", "95 % band"),
        [(r["direction"].upper(), ", ".join(f"{m['natural_frequency_hz']:.2f}" for m in r["modes"]), f"{r['mean_deflection_mm']:.4f}",
          band(*r["mean_deflection_band_mm"]), f"{r['peak_to_valley_mm']:.4f}", band(*r["peak_to_valley_band_mm"]))
         for r in rows],
    )  # fmt: skip
    if outside:
        console().print(
            f"[yellow]warning:[/] {', '.join(outside)} outside the calibrated workspace: extrapolation"
        )
    _print_predict_checks(checks, ap, rpm)


def _lobes_checks(model, samples: int) -> dict:
    """Calibration of a pose model's bands and too few samples for P(stable)'s 5-95 %."""
    from ..milling.cut_checks import quantile_sample_warning

    if model is None:
        return {}
    from ..gp.calibration import calibration_status

    bands = calibration_status(model)
    warns = [] if bands["calibrated"] else [f"bands {bands['bands']}"]
    few = quantile_sample_warning(samples, 0.05, "--samples")
    return {**bands, "warnings": [*warns, *([few] if few else [])]}


def _predict_checks(model, pose, cond, coefficients, feed, samples, res) -> dict:
    """What ``mill predict`` says beside its figures: chatter, implausible inputs, bands."""
    from ..gp.calibration import calibration_status
    from ..milling.cut_checks import (
        cut_stability,
        implausible_cut_warnings,
        quantile_sample_warning,
    )
    from ..milling.forces import MillingTool

    stab = cut_stability(model, pose, cond, coefficients, feed_direction=feed)
    biggest = max(max(abs(r.mean_deflection_m), abs(r.peak_to_valley_m)) for r in res)
    warns = implausible_cut_warnings(MillingTool(), cond, deflection_m=biggest)
    few = quantile_sample_warning(samples, 0.025, "--samples")
    bands = calibration_status(model)
    if not bands["calibrated"]:
        warns.append(f"bands {bands['bands']}")
    return {"stability": stab.to_dict(), **bands, "warnings": [*warns, *([few] if few else [])]}


def _print_predict_checks(checks: dict, ap_mm: float, rpm: float) -> None:
    con = console()
    st = checks["stability"]
    crit = st["critical_depth_m"]
    limit = "no limit found" if crit is None else f"limit {from_si(crit, 'mm'):.3f} mm"
    if st["chatter_predicted"]:
        con.print(
            f"[red]CHATTER predicted:[/] ap {ap_mm:g} mm is beyond the stability {limit} at "
            f"{rpm:g} rpm ({st['method'].upper()}, as mill lobes): the peak-to-valley above is "
            "the forced vibration of a stable cut, which this cut is not"
        )
    else:
        con.print(f"stable: ap {ap_mm:g} mm below the stability {limit} at {rpm:g} rpm "
                  f"({st['method'].upper()})")  # fmt: skip
    for w in checks["warnings"]:
        con.print(f"[yellow]warning:[/] {w}")


@app.command("lobes")
def lobes(
    x: Annotated[float | None, typer.Option("--x", help="Tool-tip X [mm] (pose model).")] = None,
    y: Annotated[float | None, typer.Option("--y", help="Tool-tip Y [mm].")] = None,
    rz: opt.OptionalRzOpt = None,
    method: opt.MethodOpt = "sdm",
    mode: opt.ModeSpecOpt = None,
    frf: opt.FrfFileOpt = None,
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
    rpm_range: opt.RpmRangeOpt = "100:3000:200",
    cuts: opt.CutsOpt = None,
    operating_point: opt.OperatingPointOpt = None,
    samples: opt.LobeSamplesOpt = 0,
    time_domain_margin: opt.TimeDomainMarginOpt = False,
    label_noise: opt.LabelNoiseOpt = 0.05,
    local_factor: opt.LocalFactorOpt = "0.55,1.3",
    common_factor: opt.CommonFactorOpt = "0.9,1.1",
    steps: opt.StepsOpt = 40,
    plot: Annotated[Path | None, typer.Option(help="PNG of the stability chart.")] = None,
    seed: SeedOpt = 0,
    model_path: ModelOpt = None,
    json_out: JsonFlag = False,
) -> None:
    """Stability lobes (envelope) from explicit modes, a measured FRF or the pose model's modes."""
    from ..milling.chart import lobes_chart, plot_lobes_chart
    from ._parsers import parse_mode_specs, parse_operating_point, parse_rpm_range

    check_output(plot, [model_path, frf, cuts])
    split, common = opt.factor_split(local_factor, common_factor) if cuts else (None, (0.9, 1.1))
    tool, cond, coef = opt.cutting(material(material_name), kt, kn, diameter, teeth, helix, ae,
                                radial_immersion, milling)  # fmt: skip
    modes_x, modes_y = parse_mode_specs(mode or [])
    model, pose, pose_label = None, None, None
    if not (modes_x or modes_y) and frf is None:
        if x is None or y is None or rz is None:
            raise ValueError("give --x --y --rz (pose model), --mode ... or --frf FILE")
        model, pose = workspace_model(model_path, seed), (x, y, rz)
        pose_label = f"X {x:g} mm, Y {y:g} mm, Rz {rz:g}°, feed {feed}"
    from rich.console import Console
    from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn

    err_console = Console(stderr=True)
    bar = Progress(TextColumn("{task.description}"), BarColumn(), TextColumn("{task.completed}/{task.total}"),
                   TimeRemainingColumn(), console=err_console, transient=True,
                   disable=samples == 0 or not err_console.is_terminal)  # fmt: skip
    task = bar.add_task("P(stable): sampled envelopes", total=max(samples, 1))
    from ..io import read_frfs
    from ..io.cuts import read_cuts_csv

    speeds = parse_rpm_range(rpm_range)
    op = None if operating_point is None else parse_operating_point(operating_point)
    frfs = None if frf is None else read_frfs(frf)  # .h5/.hdf5, .uff/.unv or .csv
    measured_cuts = None if cuts is None else read_cuts_csv(cuts)
    with bar:
        chart = lobes_chart(
        tool=tool, conditions=cond, coefficients=coef, spindle_rpm=speeds, method=method,
        modes_x=modes_x, modes_y=modes_y, frfs=frfs, frf_label=None if frf is None else str(frf),
        cuts=measured_cuts,
        operating_point=op,
        pose_label=pose_label, material_label=material_name if kt is None and kn is None else
        f"Kt {coef.ktc:.3g}, Kn {coef.krc:.3g} N/m²", pose_model=model, pose=pose,
        feed_direction=feed, n_samples=samples, rng=seed, steps_per_period=steps,
        time_domain_margin=time_domain_margin, label_noise=label_noise,
        local_factor=split, common_factor=common,
        progress=lambda done, total: bar.update(task, completed=done, total=total),
        )  # fmt: skip
    if plot is not None:
        use_agg()
        save_figure(plot_lobes_chart(chart), plot)
    doc = chart.to_dict()
    from ..milling.at_pose import pose_extrapolation

    outside = list(pose_extrapolation(model, pose)) if model is not None else []
    checks = _lobes_checks(model, samples)
    overridden = [n for n, v in (("Kt", kt), ("Kn", kn)) if v is not None]
    used_material = (material_name if not overridden else None if len(overridden) == 2
                     else f"{material_name} ({overridden[0]} given)")  # fmt: skip
    if json_out:
        emit_json({"pose_mm_deg": pose, "material": used_material,
                   "extrapolation": outside, **doc, **checks},
                  settings={"ae": float(f"{from_si(cond.radial_depth_m, 'mm'):.12g}"),
                            "material_name": used_material})  # fmt: skip
        return
    env = chart.envelope
    typer.echo(f"{chart.title.splitlines()[0]}")
    for note in chart.notes:
        typer.echo(f"note: {note}")
    if outside:
        typer.echo(
            f"warning: {', '.join(outside)} outside the calibrated workspace: the modes are a GP "
            "extrapolation"
        )
    for w in checks.get("warnings", ()):
        typer.echo(f"warning: {w}")
    if doc["minimum_depth_m"] is not None:
        typer.echo(
            f"depth stable at every speed ({method.upper()}): {from_si(doc['minimum_depth_m'], 'mm'):.3f} mm"
        )
    if doc["most_stable_rpm"] is not None:
        typer.echo(
            f"most stable speed: {doc['most_stable_rpm']:.0f} rpm ({from_si(doc['most_stable_depth_m'], 'mm'):.2f} mm)"
        )
    else:
        typer.echo("no interior maximum of the envelope in the speed range: widen --rpm-range")
    n_flip = chart.n_flip_limited
    if n_flip:
        typer.echo(f"{n_flip} of {env.kind.size} speeds limited by flip (period-doubling) lobes")
    if "test_cuts" in doc:
        opt.echo_cut_update(doc["test_cuts"], "at this pose")
    if chart.operating_point is not None:
        state = {True: "stable", False: "CHATTER", None: "outside the speed range"}[
            chart.operating_point_stable
        ]
        p_op = chart.operating_point_p_stable
        typer.echo(
            f"operating point {chart.operating_point[0]:.0f} rpm, {from_si(chart.operating_point[1], 'mm'):.2f} mm: {state}"
            + (
                ""
                if p_op is None
                else f", P(stable) = {p_op:.2f} ({chart.probability.settings['n_samples']} samples)"
            )
            + (
                f"; {doc['operating_point']['p_stable_before_cuts']:.2f} before the test cuts"
                if "p_stable_before_cuts" in doc.get("operating_point", {})
                else ""
            )
        )
    if plot is not None:
        typer.echo(f"wrote {plot}")


# the workspace map, chatter detection and path planning live in their own modules
from .mill_map import register as _register_map  # noqa: E402
from .mill_plan import register as _register_plan  # noqa: E402

_register_map(app)
_register_plan(app)
