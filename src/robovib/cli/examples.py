"""``robovib examples``: the example recordings shipped for each workflow."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from ._common import JsonFlag, emit_json


def examples(
    to: Annotated[
        Path | None, typer.Option("--to", help="Copy all examples into this folder.")
    ] = None,
    json_out: JsonFlag = False,
) -> None:
    """List the example files (hammer UFF/CSV, FRF CSV, milling record, cuts, campaign manifest);
    --to DIR copies them there."""
    from ..datasets import EXAMPLES, copy_examples, example_path

    paths = copy_examples(to) if to is not None else [example_path(n) for n in EXAMPLES]
    doc = {"examples": [{"file": str(p), "description": EXAMPLES[p.name]} for p in paths]}
    if json_out:
        emit_json(doc)
        return
    for p in paths:
        typer.echo(f"{p}  - {EXAMPLES[p.name]}")
