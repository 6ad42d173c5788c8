"""``robovib mill plan`` (and, from :mod:`robovib.cli.mill_detect`, ``mill detect``) (issue 39),
registered on the ``mill`` group."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import numpy as np
import typer

from . import _mill_options as opt
from ._common import (
    JsonFlag,
    ModelOpt,
    SeedOpt,
    check_output,
    emit_json,
    material,
    save_figure,
    use_agg,
    workspace_model,
)


def _pair(spec: str, what: str) -> tuple[float, float]:
    try:
        a, b = (float(v) for v in spec.replace(",", ":").split(":"))
    except ValueError as exc:
        raise ValueError(f"{what} must be A:B (two numbers), got {spec!r}") from exc
    return a, b


def plan(
    path_csv: Annotated[
        Path | None, typer.Option("--path", help="Tool path CSV: x_mm, y_mm (base frame).")
    ] = None,
    start: Annotated[
        str | None, typer.Option(help="Start X,Y [mm] of a straight path (with --end).")
    ] = None,
    end: Annotated[str | None, typer.Option(help="End X,Y [mm] of a straight path.")] = None,
    segments: Annotated[int, typer.Option(help="Segments of a --start/--end path.")] = 50,
    teeth: opt.TeethOpt = 2,
    diameter: opt.DiameterOpt = 25.4,
    helix: opt.HelixOpt = 30.0,
    ae: opt.AeOpt = 6.0,
    milling: opt.MillingOpt = "down",
    material_name: opt.MaterialOpt = "al7075",
    fz: opt.FzOpt = 0.058,
    feed: opt.FeedOpt = "x",
    rz_range: Annotated[str, typer.Option(help="Allowed Rz MIN:MAX [deg].")] = "0:180",
    rz_step: Annotated[float, typer.Option(help="Rz grid step [deg].")] = 20.0,
    rpm_range: Annotated[
        str, typer.Option("--rpm-range", help="Allowed speeds MIN:MAX:N [rpm].")
    ] = "1000:3500:12",
    p_stable: Annotated[
        float, typer.Option("--p-stable", help="Required probability of a stable cut.")
    ] = 0.95,
    ap: Annotated[
        float | None,
        typer.Option("--ap", help="Axial depth wanted [mm] (default: as deep as allowed)."),
    ] = None,
    max_depth: Annotated[float, typer.Option(help="Deepest cut the tool allows [mm].")] = 20.0,
    depth_rule: Annotated[
        str,
        typer.Option(
            help="With no --ap: 'segment' (each segment as deep as allowed) or 'path' (one "
            "depth for the whole path); the fixed comparison follows the same rule."
        ),
    ] = "segment",
    max_rz_rate: Annotated[
        float, typer.Option(help="Largest Rz change per mm of path [deg/mm].")
    ] = 1.0,
    samples: Annotated[
        int, typer.Option(help="Sampled structures of the pose model (the forecast).")
    ] = 48,
    cuts: Annotated[
        Path | None,
        typer.Option(
            "--cuts",
            help="Test cuts CSV x_mm,y_mm,rz_deg,spindle_rpm,depth_mm,result: update the "
            "forecast (Bayesian posterior over the structures).",
        ),
    ] = None,
    label_noise: Annotated[
        float, typer.Option(help="Probability that a test cut's label is wrong.")
    ] = 0.05,
    local_factor: Annotated[
        str,
        typer.Option(
            help="With --cuts: LO,HI of the local factor on the limit, drawn afresh at every cut "
            "and segment (the time-domain / linear limit ratio), the cuts learning only a common "
            "factor (--common-factor); 'none': one common factor over the structures' whole "
            "range (the earlier behaviour)."
        ),
    ] = "0.55,1.3",
    common_factor: Annotated[
        str,
        typer.Option(help="With --cuts: LO,HI of the common factor the cuts learn."),
    ] = "0.9,1.1",
    suggest_cuts: Annotated[
        Path | None,
        typer.Option(
            help="Write the most informative test cuts of this plan (CSV, result column to fill)."
        ),
    ] = None,
    n_suggest: Annotated[int, typer.Option(help="Test cuts suggested.")] = 5,
    check_sdm: Annotated[
        bool, typer.Option(help="Check each segment with the SDM limit of the mean modes.")
    ] = False,
    output: Annotated[
        Path | None, typer.Option("-o", "--output", help="Plan CSV (one row per segment).")
    ] = None,
    plot: Annotated[
        Path | None, typer.Option(help="PNG: path coloured by depth, Rz, speed.")
    ] = None,
    report_html: Annotated[
        Path | None, typer.Option("--report", help="HTML report of the plan.")
    ] = None,
    seed: SeedOpt = 0,
    model_path: ModelOpt = None,
    json_out: JsonFlag = False,
) -> None:
    """Plan Rz and spindle speed along a tool path at a required P(stable); optional test cuts."""

    from ..files.units import to_si
    from ..milling.planning import plan_path, read_path_csv
    from ..milling.structures import sample_structures
    from ._parsers import parse_rpm_range

    outs = [p for p in (output, plot, report_html, suggest_cuts) if p is not None]
    for out in outs:
        check_output(out, [model_path, path_csv, cuts])
    if len(set(outs)) != len(outs):
        raise ValueError("the output files must differ")
    if path_csv is not None:
        if start is not None or end is not None:
            raise ValueError("give --path or --start/--end, not both")
        points, n_seg = read_path_csv(path_csv), None
    elif start is not None and end is not None:
        points, n_seg = np.array([_pair(start, "--start"), _pair(end, "--end")]), segments
    else:
        raise ValueError("give a tool path: --path FILE, or --start X,Y --end X,Y")
    tool, cond, coef = opt.cutting(material(material_name), None, None, diameter, teeth, helix,
                                   ae, None, milling)  # fmt: skip
    from dataclasses import replace

    cond = replace(cond, feed_per_tooth_m=to_si(fz, "mm"))
    speeds = parse_rpm_range(rpm_range)
    model = workspace_model(model_path, seed)
    structures = sample_structures(model, samples, rng=seed)
    update = measured_cuts = None
    if cuts is not None:
        from ..io.cuts import read_cuts_csv
        from ..milling.cut_posterior import update_with_cuts

        split, common = opt.factor_split(local_factor, common_factor)
        measured_cuts = read_cuts_csv(cuts)
        update = update_with_cuts(structures, measured_cuts, tool, cond, coef,
                                  feed_direction=feed, label_noise=label_noise,
                                  local_factor=split, common_factor=common)  # fmt: skip
        structures = update.structures
    res = plan_path(
        structures, points, tool, cond, coef, n_segments=n_seg, feed_direction=feed,
        rz_range_deg=_pair(rz_range, "--rz-range"), rz_step_deg=rz_step,
        rpm_range=(float(speeds.min()), float(speeds.max())), n_speeds=speeds.size,
        p_required=p_stable, depth_m=None if ap is None else to_si(ap, "mm"),
        max_depth_m=to_si(max_depth, "mm"), max_rz_rate_deg_per_mm=max_rz_rate,
        depth_rule=depth_rule,
        check_sdm=check_sdm, cuts=measured_cuts, label_noise=label_noise,
    )  # fmt: skip
    suggested = None
    if suggest_cuts is not None:
        suggested = _suggest(res, structures, n_suggest, suggest_cuts, [model_path, path_csv, cuts])
    if output is not None:
        res.write_csv(output, inputs=[p for p in (model_path, path_csv, cuts) if p])
    if plot is not None:
        use_agg()
        from ..milling.planning import plot_path_plan

        save_figure(plot_path_plan(res), plot)
    if report_html is not None:
        use_agg()
        from ..report import write_report
        from ..report.plan import plan_report

        write_report(plan_report(res, update), report_html,
                     inputs=[p for p in (model_path, path_csv, cuts) if p])  # fmt: skip
    doc = res.to_dict()
    if update is not None:
        doc["test_cuts"] = update.to_dict()
    if suggested is not None:
        doc["suggested_cuts"] = suggested
    if json_out:
        emit_json(doc)
        return
    fixed = res.fixed
    typer.echo(
        f"plan: {res.rz_deg.size} segments, mean MRR {doc['mean_mrr_mm3_per_s']:.1f} mm³/s at "
        f"P(stable) >= {p_stable:g} ({res.feasible.sum()} of {res.feasible.size} segments meet it); "
        f"best fixed Rz {fixed['rz_deg']:g}° / {fixed['spindle_rpm']:g} rpm: "
        f"{fixed['mean_mrr_mm3_per_s']:.1f} mm³/s (x{doc['gain_over_fixed']:.2f}); "
        f"{res.settings['seconds']:.1f} s"
    )
    if update is not None:
        u = doc["test_cuts"]
        typer.echo(
            f"test cuts: {u['n_cuts']} (label noise {u['label_noise']:g}): effective sample size "
            f"{u['effective_sample_size_prior']:.0f} -> {u['effective_sample_size']:.1f}, "
            f"information {u['information_nats']:.2f} nats, median limit at the cuts "
            f"{100 * u['median_limit_shift_rel']:+.0f} %"
        )
    rows = res.rows()
    step = max(len(rows) // 10, 1)
    typer.echo("segment  X [mm]  Y [mm]  Rz [deg]  speed [rpm]  depth [mm]  P(stable)  MRR [mm³/s]")
    for r in rows[::step]:
        typer.echo(
            f"{r['segment']:7d} {r['x_mm']:7.0f} {r['y_mm']:7.0f} {r['rz_deg']:9.0f} "
            f"{r['spindle_rpm']:12.0f} {r['depth_mm']:11.2f} {r['p_stable']:10.3f} "
            f"{r['mrr_mm3_per_s']:12.1f}"
        )
    for p in (output, plot, report_html, suggest_cuts):
        if p is not None:
            typer.echo(f"wrote {p}")


def _suggest(res, structures, n, path, inputs) -> list[dict]:
    """The most informative test cuts among the plan's segments, Rz and speeds, as a cuts CSV."""
    from ..files.safe_write import atomic_output
    from ..milling.cut_posterior import choose_test_cuts

    poses, rpm, lim = res.test_cut_candidates()
    idx, depth = choose_test_cuts(lim, structures.weights, n, local_factor=structures.local_factor)
    rows = [
        {"x_mm": float(poses[i, 0]), "y_mm": float(poses[i, 1]), "rz_deg": float(poses[i, 2]),
         "spindle_rpm": float(rpm[i]), "depth_mm": float(d * 1e3), "result": ""}
        for i, d in zip(idx, depth, strict=True)
    ]  # fmt: skip
    text = "x_mm,y_mm,rz_deg,spindle_rpm,depth_mm,result\n" + "".join(
        f"{r['x_mm']:.6g},{r['y_mm']:.6g},{r['rz_deg']:.6g},{r['spindle_rpm']:.6g},"
        f"{r['depth_mm']:.4g},\n"
        for r in rows
    )
    with atomic_output(path, inputs=[p for p in inputs if p]) as tmp:
        tmp.write_text(text)
    return rows


def register(app: typer.Typer) -> None:
    """Add the commands of this module to the ``mill`` group.

    Parameters
    ----------
    app : typer.Typer
        The ``robovib mill`` group.
    """
    from .mill_detect import detect

    app.command("detect")(detect)
    app.command("plan")(plan)
