"""``robovib modal``: modal parameters from FRFs."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from ._common import (
    ForceOpt,
    JsonFlag,
    KeepFlaggedFitsOpt,
    Table,
    check_output,
    console,
    emit_json,
    escape,
    fail,
    new_app,
    save_figure,
    use_agg,
)

app = new_app("Modal parameters from FRFs.")


@app.command("fit")
def fit(
    frf_file: Annotated[Path, typer.Argument(help="FRF file (.h5 or .uff).")],
    band: Annotated[
        tuple[float, float] | None,
        typer.Option(help="Fit band LO HI [Hz]; default: around the dominant peak."),
    ] = None,
    modes: Annotated[
        bool, typer.Option("--modes", help="Also identify all modes in the band (LSCF + LSFD).")
    ] = False,
    max_order: Annotated[int, typer.Option(help="Highest LSCF model order for --modes.")] = 30,
    plot: Annotated[
        Path | None,
        typer.Option(help="PNG of magnitude, phase and coherence with the fitted curve."),
    ] = None,
    keep_flagged: KeepFlaggedFitsOpt = False,
    force: ForceOpt = False,
    json_out: JsonFlag = False,
) -> None:
    """Dominant-mode fit (fn, k, c, zeta with standard errors) of every FRF in a file.

    A fit the library flags (parameter at a bound, large residual, inverted sign) is shown
    with its reasons, and the command then exits with an error unless ``--keep-flagged``.
    """
    from ..io import read_frfs
    from ..modal import fit_frfs

    check_output(plot, [frf_file], force)
    frfs = read_frfs(frf_file)
    try:
        results = fit_frfs(frfs, band, all_modes=modes, max_order=max_order)
    except ValueError as exc:  # a fit that fails: "FILE, FRF i: ..."
        fail(f"{frf_file}, {exc}")
    docs = [r.to_dict(i) for i, r in enumerate(results)]
    flagged = [(i, r.flags) for i, r in enumerate(results) if r.flagged]
    if json_out:
        emit_json({"file": str(frf_file), "frfs": docs, "n_flagged": len(flagged)})
        if plot is not None:
            _plot(frf_file, results, plot, force)
        _flagged_exit(flagged, keep_flagged)
        return
    con = console()
    t = Table(title=f"Dominant mode of each FRF in {frf_file.name}")
    for col in (
        "FRF",
        "dir",
        "fn [Hz]",
        "k [MN/m]",
        "c [kN·s/m]",
        "zeta [%]",
        "band [Hz]",
        "flags",
    ):
        t.add_column(escape(col), justify="right")
    for i, r in enumerate(results):
        frf, dom = r.frf, r.dominant
        p, sd = dom.parameters, dom.std
        t.add_row(
            str(i), frf.direction or "-",
            f"{p.natural_frequency_hz:.3f} ± {sd['natural_frequency_hz']:.3f}",
            f"{p.stiffness_n_per_m / 1e6:.4f} ± {sd['stiffness_n_per_m'] / 1e6:.4f}",
            f"{p.damping_ns_per_m / 1e3:.3f} ± {sd['damping_ns_per_m'] / 1e3:.3f}",
            f"{100 * p.damping_ratio:.2f} ± {100 * sd['damping_ratio']:.2f}",
            f"{dom.band_hz[0]:.1f}-{dom.band_hz[1]:.1f}",
            "[red]" + escape("; ".join(dom.flags)) + "[/]" if dom.flags else "-",
        )  # fmt: skip
    con.print(t)
    for i, multi in enumerate(r.modes for r in results):
        if multi is None:
            continue
        t = Table(
            title=f"FRF {i}: modes in {multi.band_hz[0]:.1f}-{multi.band_hz[1]:.1f} Hz (LSCF + LSFD)"
        )
        for col in ("mode", "fn [Hz]", "k [MN/m]", "zeta [%]"):
            t.add_column(escape(col), justify="right")
        for j, m in enumerate(multi.modes):
            t.add_row(
                str(j + 1),
                f"{m.natural_frequency_hz:.3f}",
                f"{m.stiffness_n_per_m / 1e6:.4f}",
                f"{100 * m.damping_ratio:.2f}",
            )
        con.print(t)
    if plot is not None:
        _plot(frf_file, results, plot, force)
        con.print(f"wrote {plot}")
    _flagged_exit(flagged, keep_flagged)


def _flagged_exit(flagged, keep_flagged: bool) -> None:
    """Fits that say they are wrong make the command fail, unless the user keeps them."""
    if not flagged:
        return
    detail = "; ".join(f"FRF {i}: {reasons[0]}" for i, reasons in flagged[:3])
    more = f" (+{len(flagged) - 3} more)" if len(flagged) > 3 else ""
    if keep_flagged:
        typer.echo(f"warning: {len(flagged)} flagged fit(s) kept: {detail}{more}", err=True)
        return
    fail(f"{len(flagged)} fit(s) flagged: {detail}{more}; see the flags, or pass --keep-flagged")


def _plot(frf_file: Path, results, plot: Path, force: bool) -> None:
    """The first FRF with its fit, drawn after the results are printed."""
    from ..modal.plot import plot_frf_fits

    use_agg()
    fig = plot_frf_fits(results[0], title=f"{frf_file.name}, FRF 0")
    save_figure(fig, plot, inputs=[frf_file], force=force)
