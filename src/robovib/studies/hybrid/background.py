"""The chapter-5 study over background force levels (issue 17 item 3)."""

from __future__ import annotations

import numpy as np

from .study import HybridStudyResult, hybrid_study

__all__ = [
    "background_study",
    "background_table",
]


def background_study(backgrounds, seeds=(0,), **kwargs) -> HybridStudyResult:
    """The study (EMA alone and the default robust update) at several background levels.

    Parameters
    ----------
    backgrounds
        Broadband force content levels of the cut (``background_noise_rel``), e.g.
        ``(0.05, 0.15, 0.5, 1, 2)``; each must be > 0.
    seeds
        Simulator seeds, each run at every background.
    **kwargs
        Passed to :func:`hybrid_study` (not ``models`` / ``background_noise_rel``).

    Returns
    -------
    HybridStudyResult
        Rows as :func:`hybrid_study`'s with a ``background`` key; scored against the
        simulator's true FRF (``rmse_vs_truth_um_per_n``, ``peak_error_vs_truth_pct``).

    Raises
    ------
    ValueError
        No background, or one that is not finite and > 0.
    """
    bgs = [float(b) for b in backgrounds]
    if not bgs or not all(np.isfinite(b) and b > 0 for b in bgs):
        raise ValueError(f"backgrounds must be finite and > 0, got {list(backgrounds)}")
    rows, settings = [], {}
    for b in bgs:
        res = hybrid_study(seeds=seeds, background_noise_rel=b, models=("ema", "robust"), **kwargs)
        rows += [{**r, "background": b} for r in res.rows]
        settings = dict(res.settings)
    settings["backgrounds"] = bgs
    return HybridStudyResult(tuple(rows), settings)


def background_table(result: HybridStudyResult) -> list[dict]:
    """Per background and direction: robust vs EMA alone, against the true FRF.

    Parameters
    ----------
    result
        From :func:`background_study`.

    Returns
    -------
    list of dict
        ``background, direction, rmse_change_mean_pct, rmse_change_worst_pct`` (relative
        change of the RMSE vs truth, per seed), ``peak_error_ema_pct, peak_error_robust_pct``
        (mean over seeds) and ``peak_change_worst_pts`` (worst seed, robust minus EMA, in
        percentage points of the dominant-peak |H| error), ``held_back_fraction`` (of the
        seeds where the evidence test held the whole direction back: EMA alone).
    """
    import pandas as pd

    df = pd.DataFrame(list(result.rows))
    key = ["background", "seed", "direction"]
    e = df[df.model == "ema"].set_index(key)
    r = df[df.model == "robust"].set_index(key)
    t = pd.DataFrame({
        "d_rmse": 100 * (r.rmse_vs_truth_um_per_n / e.rmse_vs_truth_um_per_n - 1),
        "pk_e": e.peak_error_vs_truth_pct, "pk_r": r.peak_error_vs_truth_pct,
        "held": r.held_back_all.astype(float),
    })  # fmt: skip
    t["d_pk"] = t.pk_r - t.pk_e
    g = t.groupby(level=["background", "direction"]).agg(
        rmse_change_mean_pct=("d_rmse", "mean"), rmse_change_worst_pct=("d_rmse", "max"),
        peak_error_ema_pct=("pk_e", "mean"), peak_error_robust_pct=("pk_r", "mean"),
        peak_change_worst_pts=("d_pk", "max"), held_back_fraction=("held", "mean"),
    )  # fmt: skip
    return [{k: (float(v) if k != "direction" else v) for k, v in row.items()}
            for row in g.reset_index().to_dict(orient="records")]  # fmt: skip
