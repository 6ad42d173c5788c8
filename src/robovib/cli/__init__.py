"""Command-line interface of robovib: one module per command group, shared parts in ``_common``.

Commands are thin: they parse options, call one library function and render its result.
"""

from __future__ import annotations

from typing import Annotated

import typer

from . import (
    campaign,
    control,
    demo,
    examples,
    frf,
    gpr,
    hybrid,
    mill,
    modal,
    model,
    report,
    robot,
    sim,
)
from ._root_group import ErrorHandlingGroup, set_debug

__all__ = ["app", "main"]

app = typer.Typer(
    help="robovib: pose-dependent dynamics of machining robots.",
    no_args_is_help=True,
    add_completion=False,
    rich_markup_mode=None,
    cls=ErrorHandlingGroup,
)


def _version(value: bool) -> None:
    if value:
        from .. import __version__

        typer.echo(f"robovib {__version__}")
        raise typer.Exit()


@app.callback()
def _root(
    version: Annotated[
        bool,
        typer.Option(
            "--version", callback=_version, is_eager=True, help="Print robovib's version and exit."
        ),
    ] = False,
    debug: Annotated[
        bool, typer.Option("--debug", help="Show the full traceback of errors.")
    ] = False,
) -> None:
    """robovib: pose-dependent dynamics of machining robots."""
    set_debug(debug)


app.command("demo")(demo.demo)
app.command("examples")(examples.examples)
app.add_typer(gpr.app, name="gpr")
app.add_typer(frf.app, name="frf")
app.add_typer(modal.app, name="modal")
app.add_typer(sim.app, name="sim")
app.add_typer(robot.app, name="robot")
app.add_typer(mill.app, name="mill")
app.add_typer(control.app, name="control")
app.add_typer(hybrid.app, name="hybrid")
app.add_typer(campaign.app, name="campaign")
app.add_typer(model.app, name="model")
app.add_typer(report.app, name="report")


def main() -> None:
    from ._malloc import keep_freed_heap

    keep_freed_heap()  # glibc: no page-fault churn from the charts' numpy temporaries
    app()


if __name__ == "__main__":
    main()
