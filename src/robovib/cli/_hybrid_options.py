"""Options shared by the ``robovib hybrid`` commands (units in every help text)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

RecordArg = Annotated[
    Path,
    typer.Argument(
        help="Synchronised CSV: time_s, force_{x,y,z}_n, displacement_{x,y,z}_m, path_s_m "
        "(e.g. from `robovib sim mill`/`sim offset-mass`)."
    ),
]
SegmentOpt = Annotated[
    float, typer.Option("--segment", help="Path length per OMA FRF [m] (path coordinates in m).")
]
NpersegOpt = Annotated[int, typer.Option(help="OMA Welch window [samples].")]
NoverlapOpt = Annotated[
    int | None, typer.Option(help="OMA Welch overlap [samples] (default half a window).")
]
WindowOpt = Annotated[str, typer.Option(help="OMA window (SciPy name: hann, boxcar, ...).")]
UpdateModeOpt = Annotated[
    str,
    typer.Option(
        help="robust (bias check and rejection, OMA noise by marginal likelihood), posterior, "
        "or warm (re-optimise from the current hyperparameters)."
    ),
]
BackgroundOpt = Annotated[
    float,
    typer.Option(help="Broadband force content of the OMA cut (x spread of the periodic force)."),
]
