"""Options shared by the ``robovib hybrid`` commands (units in every help text)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

#: How ``hybrid predict`` takes each pose value (for the library's error messages).
POSE_OPTIONS = {
    "s_m": "--path-s [m]",
    "x_mm": "--x [mm]",
    "y_mm": "--y [mm]",
    "rz_deg": "--rz [deg]",
}

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
    list[str] | None,
    typer.Option(
        help="Broadband force content of the OMA cut (x spread of the periodic force); "
        "several (repeat, or 0.05,0.15,0.5,1,2) give the background table."
    ),
]


def print_background_table(tab: list[dict]) -> None:
    """Render :func:`robovib.studies.hybrid.background_table` rows."""
    from ._common import print_table

    cols = ("rmse_change_mean_pct", "rmse_change_worst_pct", "peak_error_ema_pct",
            "peak_error_robust_pct", "peak_change_worst_pts")  # fmt: skip
    print_table("Robust vs EMA alone at the validation pose, vs the true FRF: RMSE change % "
                "(mean, worst seed), peak |H| error % (EMA, robust: mean), worst peak change (pts), "
                "seeds where the whole direction was held back",
                ("background", "dir", "RMSE mean", "RMSE worst", "peak EMA", "peak rob.",
                 "peak worst", "held back"),
                [(f"{r['background']:g}", r["direction"].upper(), *(f"{r[c]:+.1f}" for c in cols),
                  f"{100 * r.get('held_back_fraction', 0.0):.0f} %")
                 for r in tab])  # fmt: skip
