"""``robovib campaign``: your own robot's hammer campaign -> FRFs -> modal table."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from ._common import (
    ComplianceRangeOpt,
    JsonFlag,
    LevelCheckOpt,
    Table,
    console,
    emit_json,
    escape,
    new_app,
    plausible_ranges,
)

app = new_app(
    "Your own robot: process a hammer campaign (manifest CSV) into FRFs and a modal table."
)


@app.command("process")
def process(
    manifest: Annotated[
        Path,
        typer.Argument(help="Campaign manifest CSV: file,direction,x_mm,y_mm,z_mm,rz_deg[,...]."),
    ],
    output: Annotated[
        Path, typer.Option("-o", "--output", help="Folder for frfs.h5, modal.csv, campaign.json.")
    ],
    skip_bad: Annotated[
        bool,
        typer.Option("--skip-bad", help="Report and skip failing rows (default: write nothing)."),
    ] = False,
    workers: Annotated[
        int | None, typer.Option("--workers", min=1, help="Processes (default: all CPU cores).")
    ] = None,
    f_min_hz: Annotated[float, typer.Option("--fmin", help="Lowest frequency kept [Hz].")] = 5.0,
    f_max_hz: Annotated[float, typer.Option("--fmax", help="Highest frequency kept [Hz].")] = 200.0,
    level_check: LevelCheckOpt = True,
    compliance_range: ComplianceRangeOpt = None,
    modes_band: Annotated[
        str | None,
        typer.Option(
            "--modes-band",
            help="LO,HI [Hz]: also fit every mode in this band and "
            "track it across poses into modes.csv (default: dominant only).",
        ),
    ] = None,
    json_out: JsonFlag = False,
) -> None:
    """Every recording of the manifest -> averaged FRF (hit QC) -> dominant mode, in parallel."""
    from dataclasses import replace

    from rich.progress import Progress

    from ..campaign import ProcessingSettings, process_campaign

    band = None
    if modes_band is not None:
        try:
            band = tuple(float(v) for v in modes_band.split(","))
        except ValueError:
            band = ()
        if len(band) != 2:
            raise typer.BadParameter(f"--modes-band wants LO,HI in Hz, got {modes_band!r}")
    settings = ProcessingSettings(f_min_hz=f_min_hz, f_max_hz=f_max_hz, modes_band_hz=band)
    settings = replace(settings, plausible=plausible_ranges(level_check, compliance_range))
    with Progress(disable=json_out, transient=True) as bar:
        task = bar.add_task("processing recordings", total=None)

        def progress(done: int, total: int) -> None:
            bar.update(task, completed=done, total=total)

        res = process_campaign(manifest, output, skip_bad=skip_bad, n_workers=workers,
                               progress=progress, settings=settings)  # fmt: skip
    table = res.table
    if json_out:
        emit_json({
            "manifest": str(manifest), "output_dir": str(output),
            "files": [str(output / n) for n in ("frfs.h5", "modal.csv", "campaign.json")]
            + ([str(output / "modes.csv")] if band else []),
            "n_rows": len(table), "n_frfs": res.n_frfs,
            "skipped": [{"line": line, "reason": why} for line, why in res.skipped],
            "rows": table.to_dict(orient="records"), "reader_reports": list(res.reports),
            "accounting": res.accounting,
        })  # fmt: skip
        return
    con = console()
    t = Table(title=f"Campaign {manifest.name}: dominant mode per recording (std errors in --json)")
    for col in (
        "line",
        "file",
        "dir",
        "fn [Hz]",
        "k [MN/m]",
        "zeta [%]",
        "hits",
        "rej.",
        "coh.",
        "flags",
    ):
        t.add_column(escape(col), justify="right")
    for r in table.to_dict(orient="records"):
        flags = r["flags"] if isinstance(r["flags"], str) else ""
        t.add_row(
            str(r["row"]), escape(Path(r["file"]).name), r["direction"], f"{r['fn_hz']:.2f}",
            f"{r['stiffness_n_per_m'] / 1e6:.3f}", f"{100 * r['damping_ratio']:.2f}",
            str(r["n_hits_used"]), str(r["n_hits_rejected"]), f"{r['mean_coherence']:.3f}",
            escape(flags),
        )  # fmt: skip
    con.print(t)
    for line, why in res.skipped:
        con.print(f"[yellow]skipped line {line}:[/] {escape(why)}")
    con.print(escape(res.accounting.get("summary", "")))
    modes = ""
    if band and (output / "modes.csv").is_file():  # --modes-band: every mode, tracked
        modes = ", modes.csv (every mode in the band, with mode ids)"
    con.print(
        f"wrote {output}/frfs.h5 ({res.n_frfs} FRFs), modal.csv ({len(table)} rows), campaign.json"
        + modes
    )
