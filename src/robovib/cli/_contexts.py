"""The running command's click context, through click's public ``context_class`` (no Typer
private globals): :func:`track_contexts` makes every command of the app create
:class:`TrackedContext` contexts, and :func:`current_context` returns the innermost entered."""

from __future__ import annotations

from typing import Any

import typer


class TrackedContext(typer.Context):
    """Typer's public context class, keeping a stack of the contexts entered, so that
    :func:`~robovib.cli._root_group.run_info` finds the running command's parameters without
    Typer's private globals."""

    def __enter__(self):
        CONTEXTS.append(self)
        return super().__enter__()

    def __exit__(self, *exc_info):
        if CONTEXTS and CONTEXTS[-1] is self:
            CONTEXTS.pop()
        return super().__exit__(*exc_info)


CONTEXTS: list[typer.Context] = []


def track_contexts(command: Any) -> None:
    """Every command under ``command`` makes :class:`TrackedContext` contexts (click's public
    ``context_class`` attribute)."""
    stack = [command]
    while stack:
        cmd = stack.pop()
        cmd.context_class = TrackedContext
        stack.extend(getattr(cmd, "commands", {}).values())


def current_context():
    """The innermost context entered (the running command's), or None."""
    return CONTEXTS[-1] if CONTEXTS else None
