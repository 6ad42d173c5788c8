"""Shared pieces of the command line: options, JSON/table output, figures, one-line failures."""

from __future__ import annotations

import contextlib
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Annotated

import typer
from rich.console import Console
from rich.markup import escape

from ._table import Table

__all__ = [
    "ForceOpt",
    "JsonFlag",
    "KeepFlaggedFitsOpt",
    "KernelOpt",
    "ModeSwitchOpt",
    "ModelOpt",
    "OutOpt",
    "SeedOpt",
    "Table",
    "about_file",
    "check_kernel",
    "check_output",
    "console",
    "emit_json",
    "escape",
    "fail",
    "materials",
    "new_app",
    "save_figure",
    "use_agg",
    "workspace_model",
]

JsonFlag = Annotated[
    bool, typer.Option("--json", help="Print one JSON document instead of tables.")
]
KernelOpt = Annotated[
    str,
    typer.Option(
        help="GP kernel: 'ard' (one length scale per input) or 'isotropic' (thesis Eq. 7)."
    ),
]
SeedOpt = Annotated[
    int, typer.Option(help="Random seed (simulated noise, fold shuffles, optimiser restarts).")
]
ModeSwitchOpt = Annotated[
    bool,
    typer.Option(
        "--mode-switch/--no-mode-switch",
        help="Classify the ~63 Hz X-mode switch at full extension (default) or smooth over it with one GP (thesis).",
    ),
]
OutOpt = Annotated[Path, typer.Option("-o", "--output", help="File to write.")]
ForceOpt = Annotated[
    bool,
    typer.Option(
        "--force", help="Allow the output to replace one of the input files (the input is lost)."
    ),
]
KeepFlaggedFitsOpt = Annotated[
    bool,
    typer.Option(
        "--keep-flagged",
        help="Exit 0 even when a fit is flagged (at a bound, large residual, inverted sign).",
    ),
]
ModelOpt = Annotated[
    Path | None,
    typer.Option(
        "--model",
        help="Your pose model (.h5 from 'robovib model fit' of modes.csv: every mode, or of "
        "modal.csv: dominant mode; inputs x_mm,y_mm,rz_deg); default: the thesis' chapter-3 "
        "model.",
    ),
]
LevelCheckOpt = Annotated[
    bool,
    typer.Option(
        help="Refuse implausible peak force / response / compliance levels (unit mix-ups such "
        "as a response in g labelled m/s^2; ranges in robovib.frf.plausibility).",
    ),
]
ComplianceRangeOpt = Annotated[
    tuple[float, float] | None,
    typer.Option(
        "--compliance-range",
        metavar="LOW HIGH",
        help="Plausible peak compliance LOW HIGH [m/N] of the FRF's resonance, two numbers "
        "separated by a space "
        "(default 6e-7 1e-3: an industrial robot; lower LOW for a stiffer structure).",
    ),
]


def plausible_ranges(level_check: bool, compliance_range: tuple[float, float] | None):
    """The :class:`robovib.frf.PlausibleRanges` of ``--level-check`` and
    ``--compliance-range`` (None: no level check); the class checks the range."""
    from ..frf import PlausibleRanges

    if not level_check:
        return None
    if compliance_range is None:
        return PlausibleRanges()
    return PlausibleRanges(peak_compliance_m_per_n=tuple(map(float, compliance_range)))


def workspace_model(path: Path | None, seed: int = 0, require_inputs=("x_mm", "y_mm", "rz_deg")):
    """``--model`` / ``--seed``: :func:`robovib.gp.chapter3_model.workspace_predictor`."""
    from ..gp.chapter3_model import workspace_predictor

    return workspace_predictor(path, seed=seed, require_inputs=require_inputs)


def new_app(help: str, **kwargs) -> typer.Typer:
    """A Typer app with markup off, so bracketed units like ``[mm]`` stay in the help."""
    return typer.Typer(help=help, rich_markup_mode=None, no_args_is_help=True, **kwargs)


def fail(message: str) -> None:
    """Stop with ``error: message`` on stderr and exit code 1."""
    typer.echo(f"error: {message}", err=True)
    raise typer.Exit(code=1)


def check_kernel(kernel: str) -> str:
    if kernel not in ("ard", "isotropic"):
        raise typer.BadParameter(f"unknown kernel {kernel!r}; use 'ard' or 'isotropic'")
    return kernel


def console() -> Console:
    """Rich console on stdout at the terminal's width."""
    return Console(file=sys.stdout)


def emit_json(
    doc: dict, *, units: dict[str, str] | None = None, settings: dict | None = None
) -> None:
    """Print ``doc`` as one self-describing JSON document (strict: NaN and inf become null,
    the reason listed under ``null_reasons``; see :func:`robovib.io.json_dumps`).

    Added to ``doc``: ``robovib_version``, ``command`` (argv as run), ``settings`` (every option
    and argument, defaults included), ``settings_units`` (setting -> unit), ``input_files`` (path
    and SHA-256 of each input file) and ``units`` (unit of every key of ``doc`` whose name has
    no unit suffix: from :data:`robovib.files.json_units.KEY_UNITS` and ``units``). ``settings``
    replaces echoed options by the values actually used (e.g. a default another option overrode).
    """
    from ..files.json_units import self_describing_document
    from ..files.provenance import run_provenance
    from ..io import json_dumps

    out = self_describing_document(doc, run_provenance(settings=settings), units=units)
    typer.echo(json_dumps(out, indent=2))


@contextlib.contextmanager
def about_file(path: Path | None) -> Iterator[None]:
    """Errors of the work on one input file name it: ``FILE: message`` (unless they do)."""
    from ..files.safe_write import OutputPathError

    try:
        yield
    except OutputPathError:  # about an output, not this input
        raise
    except ValueError as exc:
        msg = str(exc)
        if path is None or str(path) in msg or Path(path).name in msg:
            raise
        raise ValueError(f"{path}: {msg}") from exc


def check_output(path: Path | None, inputs=(), force: bool = False) -> None:
    """Refuse an output before any work: missing/read-only folder, or one of the inputs."""
    if path is not None:
        from ..io import check_output_path

        check_output_path(path, inputs=inputs, force=force)


def materials() -> dict:
    from ..milling import ACETAL, ALUMINIUM_7075

    return {"al7075": ALUMINIUM_7075, "acetal": ACETAL}


def material(name: str):
    mats = materials()
    if name not in mats:
        fail(f"unknown material {name!r}; use one of {', '.join(mats)}")
    return mats[name]


def use_agg() -> None:
    """Pick matplotlib's file-only backend (the CLI never opens windows).

    Raises
    ------
    ImportError
        matplotlib is not installed (one line: how to install the extra).
    """
    try:
        import matplotlib
    except ImportError:
        raise ImportError(
            "--plot needs matplotlib: pip install 'robovib[plot]' (the results above are complete)"
        ) from None

    matplotlib.use("Agg")


def save_figure(fig, path: Path, dpi: int = 120, inputs=(), force: bool = False) -> None:
    """Save a figure atomically (:func:`robovib.io.save_figure`) and close it."""
    import matplotlib.pyplot as plt

    from ..io import save_figure as _save

    try:
        _save(fig, path, dpi=dpi, inputs=inputs, force=force)
    finally:
        plt.close(fig)


def print_table(title: str, columns, rows) -> None:
    """One rich table: ``columns`` (headers, units in brackets are escaped) and rows of strings."""
    t = Table(title=escape(title))
    for col in columns:
        t.add_column(escape(col), justify="right")
    for row in rows:
        t.add_row(*(escape(str(v)) for v in row))
    console().print(t)
