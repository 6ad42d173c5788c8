"""``robovib mill detect``: chatter in a milling record, window by window (issue 39),
registered on the ``mill`` group by :mod:`robovib.cli.mill_plan`."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import numpy as np
import typer

from . import _mill_options as opt
from ._common import ForceOpt, JsonFlag, check_output, emit_json


def detect(
    record: Annotated[Path, typer.Argument(help="Milling record CSV (time_s + channels).")],
    rpm: opt.RpmOpt = 1750.0,
    teeth: opt.TeethOpt = 2,
    fz: opt.FzOpt = 0.058,
    channel: Annotated[
        str | None,
        typer.Option(
            help="Column or quantity (displacement, acceleration, velocity, force); default: "
            "displacement, else acceleration, velocity, force."
        ),
    ] = None,
    window: Annotated[float, typer.Option("--window", help="Window length [s].")] = 2.0,
    false_alarm: Annotated[
        float,
        typer.Option("--false-alarm", help="Per-window false-alarm rate of a line on noise."),
    ] = 1e-3,
    min_line_fraction: Annotated[
        float | None,
        typer.Option(
            help="Share of the window's vibration power the line must carry (default: 0.2 for "
            "displacement records, with --min-line-feed; 0.5 otherwise)."
        ),
    ] = None,
    min_line_feed: Annotated[
        float,
        typer.Option(
            help="Displacement records: and the RMS of the line (marks the surface), as a "
            "fraction of --fz."
        ),
    ] = 0.07,
    force_check: Annotated[
        bool,
        typer.Option(
            "--force-check/--no-force-check",
            help="When the record has force columns: a line is chatter only if the force has "
            "it too (a forced resonance of a mode driven by the broadband force is not).",
        ),
    ] = True,
    cuts_out: Annotated[
        Path | None,
        typer.Option(
            "--cuts-out",
            help="Write the record as one labelled test cut (x_mm,y_mm,rz_deg,spindle_rpm,"
            "depth_mm,result) for --cuts; needs --pose and --depth.",
        ),
    ] = None,
    pose: Annotated[
        str | None, typer.Option(help="Pose of the cut X,Y,RZ [mm, mm, deg] (for --cuts-out).")
    ] = None,
    depth: Annotated[
        float | None, typer.Option(help="Axial depth of the cut [mm] (for --cuts-out).")
    ] = None,
    force: ForceOpt = False,
    json_out: JsonFlag = False,
) -> None:
    """Label a milling record stable or chatter window by window; the chatter frequency."""
    from ..files.units import to_si
    from ..milling.detection import detect_chatter, read_detection_record

    cut_pose = None
    if cuts_out is not None:
        if pose is None or depth is None:
            raise ValueError("--cuts-out needs the cut's --pose X,Y,RZ and --depth [mm]")
        cut_pose = [float(v) for v in pose.split(",")] if pose.count(",") == 2 else None
        if cut_pose is None or not all(np.isfinite(cut_pose)):
            raise ValueError(f"--pose must be X,Y,RZ (three numbers), got {pose!r}")
        if not (np.isfinite(depth) and depth > 0):
            raise ValueError(f"--depth must be a positive depth [mm], got {depth!r}")
        check_output(cuts_out, [record], force)
    signal, fs, cols = read_detection_record(record, channel)
    displacement = all(c.startswith("displacement_") for c in cols)
    min_rms = None
    if displacement:
        from ..files.units import si_factor

        # the columns' unit -> m, then the line's RMS against the feed per tooth [m]
        units = {c.split("_")[-1] for c in cols}
        if len(units) != 1:
            raise ValueError(f"{record}: displacement columns in several units: {cols}")
        signal = signal * si_factor(units.pop(), "displacement")[1]
        min_rms = min_line_feed * to_si(fz, "mm")
    if min_line_fraction is None:
        min_line_fraction = 0.2 if displacement else 0.5
    force_signal, force_cols = None, []
    if force_check and not all(c.startswith("force_") for c in cols):
        try:
            force_signal, _, force_cols = read_detection_record(record, "force")
        except ValueError:  # no (non-constant) force column: the check cannot be made
            force_signal, force_cols = None, []
    res = detect_chatter(
        signal, fs, rpm, teeth, window_s=window, false_alarm_rate=false_alarm,
        min_line_fraction=min_line_fraction, min_line_rms=min_rms, force=force_signal,
    )  # fmt: skip
    doc = {"record": str(record), "columns": cols, "force_columns": force_cols,
           "sample_rate_hz": fs, **res.to_dict()}  # fmt: skip
    if cuts_out is not None:
        from ..files.safe_write import atomic_output

        row = [*cut_pose, rpm, depth]
        with atomic_output(cuts_out, inputs=[record], force=force) as tmp:
            tmp.write_text("x_mm,y_mm,rz_deg,spindle_rpm,depth_mm,result\n"
                           + ",".join(f"{v:.10g}" for v in row) + f",{res.result}\n")  # fmt: skip
        doc["cuts_out"] = str(cuts_out)
    if json_out:
        record_unit = "the record's unit (N, m/s^2 or m, as its columns)"
        emit_json(doc, units={
            "channels": "column names", "false_alarm_rate": "1 (per window)",
            "line_rms": record_unit, "min_line_rms": record_unit, "off_harmonic_bins": "count",
            "peak_to_floor": "1 (spectral power over the noise floor)",
            "threshold_peak_to_floor": "1 (spectral power over the noise floor)",
            "force_line_to_floor": "1 (the force's power at the line over its floor)",
            "force_threshold": "1 (the force's power at the line over its floor)"})  # fmt: skip
        return
    n_ch = int(res.chatter.sum())
    typer.echo(
        f"{record}: {res.result.upper()} ({n_ch} of {res.chatter.size} windows chatter; "
        f"{', '.join(cols)}, {fs:g} Hz, tooth passing {res.tooth_passing_hz:.2f} Hz, "
        f"false-alarm rate {false_alarm:g} per window)"
    )
    if force_cols:
        typer.echo(
            f"force check ({', '.join(force_cols)}): a line is chatter only if the force has it "
            f"(force/floor > {res.settings['force_threshold']:.1f})"
        )
    for w in doc["windows"]:
        typer.echo(
            f"  {w['start_s']:7.2f}-{w['end_s']:7.2f} s  {'chatter' if w['chatter'] else 'stable ':7s}"
            f"  line {w['chatter_hz']:7.2f} Hz  peak/floor {w['peak_to_floor']:9.1f}"
            f" (threshold {res.threshold:.1f})  share {w['line_fraction']:.2f}"
            + (
                ""
                if w["force_line_to_floor"] is None
                else f"  force/floor {w['force_line_to_floor']:.1f}"
            )
        )
    if res.chatter_frequency_hz is not None:
        typer.echo(f"chatter frequency: {res.chatter_frequency_hz:.2f} Hz")
    if cuts_out is not None:
        typer.echo(f"wrote {cuts_out}: one {res.result} cut (for --cuts)")
