"""Shared pieces of the command line: options, JSON/table output, figures and error handling."""

from __future__ import annotations

import json
import math
import os
import sys
import tempfile
from pathlib import Path
from typing import Annotated, Any

import click
import numpy as np
import typer
from rich.console import Console
from rich.markup import escape
from rich.table import Table
from typer.core import TyperGroup

__all__ = [
    "JsonFlag",
    "KernelOpt",
    "ModeSwitchOpt",
    "OutOpt",
    "SeedOpt",
    "Table",
    "check_kernel",
    "console",
    "emit_json",
    "escape",
    "fail",
    "materials",
    "new_app",
    "save_figure",
    "use_agg",
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
SeedOpt = Annotated[int, typer.Option(help="Seed of fold shuffles and optimiser restarts.")]
ModeSwitchOpt = Annotated[
    bool,
    typer.Option(
        "--mode-switch/--no-mode-switch",
        help="Classify the ~63 Hz X-mode switch at full extension (default) or smooth over it with one GP (thesis).",
    ),
]
OutOpt = Annotated[Path, typer.Option("-o", "--output", help="File to write.")]

#: Library errors reported as one line ``error: ...`` with exit code 1.
EXPECTED_ERRORS = (ValueError, OSError, RuntimeError, KeyError, ImportError)
_STATE = {"debug": False}


def new_app(help: str, **kwargs) -> typer.Typer:
    """A Typer app with markup off, so bracketed units like ``[mm]`` stay in the help."""
    return typer.Typer(help=help, rich_markup_mode=None, no_args_is_help=True, **kwargs)


class ErrorHandlingGroup(TyperGroup):
    """Root group: library errors become one line on stderr and exit code 1."""

    def invoke(self, ctx: click.Context) -> Any:
        try:
            return super().invoke(ctx)
        except (click.exceptions.ClickException, click.exceptions.Exit, click.exceptions.Abort):
            raise
        except EXPECTED_ERRORS as exc:
            if _STATE["debug"]:
                raise
            msg = str(exc.args[0]) if isinstance(exc, KeyError) and exc.args else str(exc)
            typer.echo(f"error: {msg or type(exc).__name__}", err=True)
            raise typer.Exit(code=1) from None
        except Exception as exc:
            if _STATE["debug"]:
                raise
            typer.echo(
                f"error: unexpected {type(exc).__name__}: {exc} (run with --debug for the traceback)",
                err=True,
            )
            raise typer.Exit(code=1) from None


def set_debug(value: bool) -> None:
    _STATE["debug"] = bool(value)


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


def _plain(obj: Any) -> Any:
    """JSON-ready copy: arrays to lists, NumPy scalars to Python, NaN/inf to None."""
    if isinstance(obj, dict):
        return {str(k): _plain(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_plain(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return _plain(obj.tolist())
    if isinstance(obj, np.generic):
        return _plain(obj.item())
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    if isinstance(obj, Path):
        return str(obj)
    if isinstance(obj, complex):
        raise TypeError("complex values are not JSON serialisable; split them first")
    return obj


def emit_json(doc: dict) -> None:
    """Print ``doc`` as one JSON document (strict: NaN and inf become null)."""
    typer.echo(json.dumps(_plain(doc), indent=2, allow_nan=False))


def materials() -> dict:
    from ..milling import ACETAL, ALUMINIUM_7075

    return {"al7075": ALUMINIUM_7075, "acetal": ACETAL}


def material(name: str):
    mats = materials()
    if name not in mats:
        fail(f"unknown material {name!r}; use one of {', '.join(mats)}")
    return mats[name]


def use_agg() -> None:
    """Pick matplotlib's file-only backend (the CLI never opens windows)."""
    import matplotlib

    matplotlib.use("Agg")


def save_figure(fig, path: Path, dpi: int = 120) -> None:
    """Save a figure atomically (temporary file in the target folder, then rename) and close it."""
    import matplotlib.pyplot as plt

    path = Path(path)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=path.suffix)
    os.close(fd)
    try:
        fig.savefig(tmp, dpi=dpi, format=path.suffix.lstrip(".") or "png")
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    finally:
        plt.close(fig)
