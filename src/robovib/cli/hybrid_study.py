"""``robovib hybrid study``: the chapter-5 study on the virtual robot (Table 12 / 13 analogues).
Registered on the ``hybrid`` group by :mod:`robovib.cli.hybrid`."""

from __future__ import annotations

from typing import Annotated

import typer

from . import _hybrid_options as hopt
from ._common import JsonFlag, emit_json, print_table

__all__ = ["study"]


def study(
    background: hopt.BackgroundOpt = None,
    seeds: Annotated[str, typer.Option(help="Simulator seeds: a range 0-4 or a list 0,1,2.")] = "0",
    nperseg: hopt.NpersegOpt = 1024,
    noverlap: hopt.NoverlapOpt = None,
    window: hopt.WindowOpt = "hann",
    segment_m: hopt.SegmentOpt = 0.05,
    validation_s: Annotated[float, typer.Option("--validation-s", help="Validation s [m].")] = 0.91,
    fmax: Annotated[float, typer.Option(help="Highest frequency [Hz].")] = 40.0,
    json_out: JsonFlag = False,
) -> None:
    """EMA at 3 poses, OMA from a 600 mm cut, validation: Table 12 / 13 analogues over seeds."""
    from ..studies import hybrid as hs

    kw = {"seeds": hs.parse_seeds(seeds), "nperseg": nperseg, "noverlap": noverlap, "window": window,
          "segment_length_m": segment_m, "validation_s_m": validation_s, "f_range_hz": (2.0, fmax)}  # fmt: skip
    bgs = hs.parse_backgrounds(background or ["1"])
    if len(bgs) > 1:
        res = hs.background_study(bgs, **kw)
        tab = hs.background_table(res)
        if json_out:
            emit_json({**res.to_dict(), "summary": tab})
            return
        hopt.print_background_table(tab)
        return
    res = hs.hybrid_study(background_noise_rel=bgs[0], **kw)
    if json_out:
        emit_json(res.to_dict())
        return
    summ = res.summary()
    print_table("FRF RMSE at the validation pose vs truth (um/N), change vs EMA (mean / worst seed), "
                "peak error vs hammer FRF, optimiser iterations per GP of the fit/update "
                "('kept': EMA hyperparameters reused, no optimiser run) - Table 12/13 analogues",
                ("dir", "model", "RMSE", "change", "worst", "peak err", "rejected", "iter/GP"),
                [(r["direction"].upper(), r["model"], f"{r['rmse_vs_truth_um_per_n']:.3f}",
                  f"{r['change_pct']:+.0f} %", f"{r['worst_change_pct']:+.0f} %",
                  f"{r['peak_error_pct']:.1f} %", f"{100 * r['rejected_fraction']:.0f} %",
                  f"{r['iterations_mean']:.1f}" if r["iterations_mean"] > 0 else "kept")
                 for r in summ.to_dict(orient="records")])  # fmt: skip
    typer.echo("default (robust) update: X and Z RMSE improve >= 20 % on average and no "
               f"direction is worse than EMA alone by > 5 %: {'yes' if res.rule_met() else 'no'}")  # fmt: skip
