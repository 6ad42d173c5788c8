"""The root command group: library errors as one line, ``--debug``, and what ran (for provenance)."""

from __future__ import annotations

import sys
from typing import Any

import click
import typer
from typer.core import TyperGroup

from ._coerce import install_light_coercion
from ._contexts import current_context as _current_context
from ._contexts import track_contexts as _track_contexts

__all__ = ["EXPECTED_ERRORS", "ErrorHandlingGroup", "run_info", "set_debug"]

#: Library errors reported as one line ``error: ...`` with exit code 1.
EXPECTED_ERRORS = (ValueError, OSError, RuntimeError, KeyError, ImportError)
_STATE: dict[str, Any] = {"debug": False, "argv": []}


def _click_passthrough() -> tuple[type, ...]:
    """Click's own exceptions (usage errors, --help exits), also those of the click copy that
    recent Typer vendors: they derive from Typer's public ``TyperException``, ``Exit`` and
    ``Abort``. Click reports them itself, never as "unexpected"."""
    return (
        click.exceptions.ClickException, click.exceptions.Exit, click.exceptions.Abort,
        typer.Exit, typer.Abort, getattr(typer, "TyperException", click.ClickException),
    )  # fmt: skip


#: Exceptions that keep their own meaning (usage errors, exits) - never turned into "error: ...".
_PASSTHROUGH = _click_passthrough()


class ErrorHandlingGroup(TyperGroup):
    """Root group: library errors become one line on stderr and exit code 1."""

    def main(self, args=None, prog_name=None, *a, **kw):
        _STATE["argv"] = [str(v) for v in (sys.argv[1:] if args is None else args)]
        install_light_coercion(self)  # plain values without Pydantic (see _coerce)
        _track_contexts(self)
        return super().main(args, prog_name, *a, **kw)

    def invoke(self, ctx: click.Context) -> Any:
        from ..files.provenance import forget_files_read, set_run_info_provider
        from ..files.safe_read import recording_inputs

        set_run_info_provider(run_info)
        try:
            with recording_inputs():  # no output may replace a file the command read
                return super().invoke(ctx)
        except _PASSTHROUGH:  # typer.Exit is a RuntimeError in recent Typer: --help exits 0
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
        finally:
            forget_files_read()  # the run is over: later library calls record their own


def set_debug(value: bool) -> None:
    _STATE["debug"] = bool(value)


def run_info() -> dict:
    """Command (argv as run), settings and their units, and input files of the running command.

    Settings are every parameter of the command (options and arguments) after parsing, defaults
    included (:func:`robovib.files.provenance.command_settings`).
    """
    from ..files.provenance import command_settings

    ctx = _current_context()
    params = [] if ctx is None else [
        (p.name, ctx.params[p.name], getattr(p, "help", None)) for p in ctx.command.params
        if p.name != "json_out" and p.name in ctx.params
    ]  # fmt: skip
    return {"command": ["robovib", *_STATE["argv"]], **command_settings(params)}
