"""``robovib frf``: FRFs from impact-hammer recordings (thesis §3.2.1)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import numpy as np
import typer

from ._common import (
    ComplianceRangeOpt,
    ForceOpt,
    JsonFlag,
    LevelCheckOpt,
    Table,
    about_file,
    check_output,
    console,
    emit_json,
    escape,
    fail,
    new_app,
    plausible_ranges,
)

app = new_app("FRFs from impact-hammer recordings (thesis §3.2.1).")


@app.command("compute")
def compute(
    recording: Annotated[
        Path, typer.Argument(help="Hammer recording: .csv or .uff/.unv (dataset 58 time records).")
    ],
    output: Annotated[
        Path,
        typer.Option(
            "-o",
            "--output",
            help="FRF file to write: .h5, .uff or .csv (frequency_hz, real/imag in m_per_n).",
        ),
    ],
    direction: Annotated[
        str | None, typer.Option(help="Excitation/response direction x, y or z (robot base frame).")
    ] = None,
    estimator: Annotated[
        str, typer.Option(help="H1 (noise on the response) or H2 (noise on the force).")
    ] = "H1",
    pretrigger_ms: Annotated[
        float, typer.Option(help="Pre-trigger kept before each hit [ms].")
    ] = 10.0,
    force_window_ms: Annotated[
        float, typer.Option(help="Force window after the trigger [ms]; 0 = none.")
    ] = 10.0,
    exp_window_tau_ms: Annotated[
        float,
        typer.Option(help="Exponential window time constant [ms] on both channels; 0 = none."),
    ] = 0.0,
    f_max_hz: Annotated[
        float, typer.Option("--fmax", help="Highest frequency kept [Hz] (<= Nyquist).")
    ] = 200.0,
    f_min_hz: Annotated[
        float,
        typer.Option(
            "--fmin",
            help="Lowest frequency kept [Hz] (compliance = accelerance / -w^2 blows up at 0).",
        ),
    ] = 2.0,
    keep_flagged: Annotated[
        bool, typer.Option(help="Keep hits flagged for double hits or overload (default: reject).")
    ] = False,
    path_s: Annotated[
        float | None,
        typer.Option(
            "--path-s",
            help="Pose as distance along a tool path [m], stored with the FRF (hybrid model).",
        ),
    ] = None,
    x_mm: Annotated[
        float | None, typer.Option("--x", help="Workspace pose X [mm], stored with the FRF.")
    ] = None,
    y_mm: Annotated[float | None, typer.Option("--y", help="Workspace pose Y [mm].")] = None,
    rz_deg: Annotated[
        float | None,
        typer.Option("--rz", help="Workspace pose: rotation about the tool axis [deg]."),
    ] = None,
    force_sensitivity: Annotated[
        float | None, typer.Option(help="Hammer sensitivity [mV/N] for a force channel in V or mV.")
    ] = None,
    response_sensitivity: Annotated[
        float | None,
        typer.Option(
            help="Response sensor sensitivity [mV per --response-unit] for a channel in V or mV."
        ),
    ] = None,
    response_unit: Annotated[
        str, typer.Option(help="Unit of the response sensitivity (g, m/s^2, m/s, m).")
    ] = "g",
    level_check: LevelCheckOpt = True,
    compliance_range: ComplianceRangeOpt = None,
    force: ForceOpt = False,
    json_out: JsonFlag = False,
) -> None:
    """Averaged compliance FRF of a hammer recording, with per-hit quality control."""
    from dataclasses import replace

    from ..frf import BandTooShortError, check_lines_in_band, impact_compliance_frf
    from ..io import Sensitivity, from_si, read_recording, to_si, write_frfs

    if direction is not None and direction not in ("x", "y", "z"):
        fail(f"unknown direction {direction!r}; use x, y or z")
    check_output(output, [recording], force)
    plausible = plausible_ranges(level_check, compliance_range)
    with about_file(recording):  # "no impact recorded" names the recording
        rec = read_recording(
            recording, direction,
            Sensitivity(force_sensitivity, "N") if force_sensitivity else None,
            Sensitivity(response_sensitivity, response_unit) if response_sensitivity else None,
        )  # fmt: skip
    with about_file(recording):  # "no impact recorded" etc. name the recording
        result = impact_compliance_frf(  # the campaign's pipeline (campaign.process_row)
            rec.forces, rec.responses, rec.sample_rate_hz, f_min_hz=f_min_hz,
            response_quantity=rec.response_quantity, estimator=estimator,
            pretrigger_s=to_si(pretrigger_ms, "ms"),
            force_window_s=None if force_window_ms == 0 else to_si(force_window_ms, "ms"),  # < 0: error
            exp_window_tau_s=None if exp_window_tau_ms == 0 else to_si(exp_window_tau_ms, "ms"),
            reject=not keep_flagged, f_max_hz=f_max_hz, direction=rec.direction, pose=rec.pose,
            plausible=plausible,
        )  # fmt: skip
    frf = result.frf
    try:
        check_lines_in_band(frf, (f_min_hz, f_max_hz), hit_samples=rec.forces.shape[1],
                            sample_rate_hz=rec.sample_rate_hz, min_lines=5)  # fmt: skip
    except BandTooShortError as exc:  # the band is the one --fmin and --fmax set
        fail(
            f"{exc.n_lines} FRF lines between --fmin and --fmax at df = {exc.df_hz:.3g} Hz "
            f"(hits of {exc.hit_duration_s:.3g} s): too short for the band"
        )
    if path_s is not None:
        frf = replace(frf, meta={**frf.meta, "path_s_m": float(path_s)})
    given = [v is not None for v in (x_mm, y_mm, rz_deg)]
    if any(given) and not all(given):
        fail("give all of --x [mm], --y [mm] and --rz [deg] for a workspace pose")
    if all(given):
        from ..gp.pose_units import pose_in_units

        x, y, rz = pose_in_units(
            ("x_m", "y_m", "rz_deg"), {"x_mm": x_mm, "y_mm": y_mm, "rz_deg": rz_deg}
        )
        nan = float("nan")
        frf = replace(frf, pose=(float(x), float(y), nan, nan, nan, float(rz)))
    write_frfs(output, [frf], inputs=[recording], force=force)
    hits = [
        {
            "hit": h.index,
            "accepted": h.accepted,
            "peak_force_n": h.peak_force_n,
            "pulse_width_ms": from_si(h.pulse_width_s, "ms"),
            "reasons": list(h.reasons),
        }
        for h in result.hits
    ]
    summary = {
        "recording": str(recording),
        "output": str(output),
        "sample_rate_hz": rec.sample_rate_hz,
        "response_quantity": rec.response_quantity,
        "direction": frf.direction,
        "n_hits": rec.n_hits,
        "n_averaged": frf.n_averages,
        "frequency_range_hz": [float(frf.frequency_hz[0]), float(frf.frequency_hz[-1])],
        "df_hz": frf.df_hz,
        "mean_coherence": float(np.mean(frf.coherence)),
        "hits": hits,
        "reader": rec.report.to_dict() if rec.report is not None else None,
    }
    if json_out:
        emit_json(summary)
        return
    con = console()
    t = Table(
        title=f"Hits of {recording.name} ({rec.sample_rate_hz:g} Hz, {rec.response_quantity})"
    )
    for col in ("hit", "accepted", "peak force [N]", "pulse [ms]", "flags"):
        t.add_column(escape(col), justify="right")
    for h in hits:
        t.add_row(
            str(h["hit"]),
            "yes" if h["accepted"] else "[red]no[/]",
            f"{h['peak_force_n']:.1f}",
            f"{h['pulse_width_ms']:.2f}",
            escape("; ".join(h["reasons"])),
        )
    con.print(t)
    if rec.report is not None:
        rep = rec.report
        con.print(
            f"read {rep.records_read} records ({rep.layout}): {rep.hits_formed} hits formed, "
            f"{len(rep.hits_rejected)} rejected"
            + "".join(f"\n  rejected {escape(h)}: {escape(r)}" for h, r in rep.hits_rejected)
            + "".join(f"\n  note: {escape(n)}" for n in rep.notes)
        )
    con.print(
        f"wrote {output}: compliance FRF, {frf.frequency_hz[0]:g}-{frf.frequency_hz[-1]:g} Hz, "
        f"df = {frf.df_hz:.3g} Hz, {frf.n_averages} hits averaged, mean coherence {summary['mean_coherence']:.3f}"
    )
