"""``robovib mill detect`` and ``robovib mill plan`` (issue 39), registered on the ``mill`` group."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from . import _mill_options as opt
from ._common import JsonFlag, emit_json


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
        float,
        typer.Option(help="Share of the window's vibration power the line must carry."),
    ] = 0.5,
    min_line_feed: Annotated[
        float,
        typer.Option(
            help="Displacement records: and the RMS of the line (marks the surface), as a "
            "fraction of --fz."
        ),
    ] = 0.05,
    json_out: JsonFlag = False,
) -> None:
    """Label a milling record stable or chatter window by window; the chatter frequency."""
    from ..io.units import to_si
    from ..milling.detection import detect_chatter, read_detection_record

    signal, fs, cols = read_detection_record(record, channel)
    displacement = all(c.startswith("displacement_") for c in cols)
    min_rms = None
    if displacement:
        from ..io.units import si_factor

        # the columns' unit -> m, then the line's RMS against the feed per tooth [m]
        units = {c.split("_")[-1] for c in cols}
        if len(units) != 1:
            raise ValueError(f"{record}: displacement columns in several units: {cols}")
        signal = signal * si_factor(units.pop(), "displacement")[1]
        min_rms = min_line_feed * to_si(fz, "mm")
    res = detect_chatter(
        signal, fs, rpm, teeth, window_s=window, false_alarm_rate=false_alarm,
        min_line_fraction=min_line_fraction, min_line_rms=min_rms,
    )  # fmt: skip
    doc = {"record": str(record), "columns": cols, "sample_rate_hz": fs, **res.to_dict()}
    if json_out:
        emit_json(doc)
        return
    n_ch = int(res.chatter.sum())
    typer.echo(
        f"{record}: {res.result.upper()} ({n_ch} of {res.chatter.size} windows chatter; "
        f"{', '.join(cols)}, {fs:g} Hz, tooth passing {res.tooth_passing_hz:.2f} Hz, "
        f"false-alarm rate {false_alarm:g} per window)"
    )
    for w in doc["windows"]:
        typer.echo(
            f"  {w['start_s']:7.2f}-{w['end_s']:7.2f} s  {'chatter' if w['chatter'] else 'stable ':7s}"
            f"  line {w['chatter_hz']:7.2f} Hz  peak/floor {w['peak_to_floor']:9.1f}"
            f" (threshold {res.threshold:.1f})  share {w['line_fraction']:.2f}"
        )
    if res.chatter_frequency_hz is not None:
        typer.echo(f"chatter frequency: {res.chatter_frequency_hz:.2f} Hz")


def register(app: typer.Typer) -> None:
    """Add the commands of this module to the ``mill`` group.

    Parameters
    ----------
    app : typer.Typer
        The ``robovib mill`` group.
    """
    app.command("detect")(detect)
