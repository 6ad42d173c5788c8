"""The chapter-5 study repeated over OMA estimator settings (issue 17 item 2)."""

from __future__ import annotations

from dataclasses import dataclass

from .study import hybrid_study

__all__ = [
    "OMASettingsResult",
    "oma_settings_study",
]


@dataclass(frozen=True)
class OMASettingsResult:
    """RMSE (robust update, vs truth) and bin count per OMA estimator setting.

    Attributes
    ----------
    rows
        One dict per setting.
    """

    rows: tuple[dict, ...]

    def to_frame(self):
        import pandas as pd

        return pd.DataFrame(list(self.rows))

    def to_dict(self) -> dict:
        return {"rows": [dict(r) for r in self.rows]}


def oma_settings_study(
    settings=None, *, seeds=(0,), directions=("x", "y", "z"), **kwargs
) -> OMASettingsResult:
    """The study repeated over OMA estimator settings (issue 17 item 2).

    Parameters
    ----------
    settings
        Iterable of dicts with keys among ``nperseg, noverlap, window, segment_length_m,
        f_range_hz``. Default: nperseg 256/512/1024 (3.9/1.95/0.98 Hz) with 50 mm segments,
        Hann and boxcar, nperseg 1024/2048/4096 with 100/200/200 mm segments, and 1024 over
        2-130 Hz (131 bins, the thesis' count).
    seeds, directions, **kwargs
        Passed to :func:`hybrid_study`.

    Returns
    -------
    OMASettingsResult
        Rows: the settings, ``direction, n_bins, flagged_fraction, rmse_ema_um_per_n,
        rmse_robust_um_per_n, change_pct`` (means over seeds).
    """
    if settings is None:
        settings = [
            {"nperseg": 256},
            {"nperseg": 512},
            {"nperseg": 512, "window": "boxcar"},
            {"nperseg": 1024},
            {"nperseg": 1024, "noverlap": 768},
            {"nperseg": 1024, "window": "boxcar"},
            {"nperseg": 1024, "segment_length_m": 0.1},
            {"nperseg": 2048, "segment_length_m": 0.2},
            {"nperseg": 1024, "f_range_hz": (2.0, 130.0)},
            {"nperseg": 4096, "segment_length_m": 0.2},
        ]
    rows = []
    for st in settings:
        res = hybrid_study(seeds=seeds, directions=directions, models=("ema", "robust"),
                           **{**kwargs, **st})  # fmt: skip
        summ = res.summary().set_index(["direction", "model"])
        df = res.to_frame()
        for d in directions:
            sub = df[(df.direction == d) & (df.model == "robust")]
            rows.append({
                "nperseg": st.get("nperseg", 1024), "noverlap": st.get("noverlap"),
                "window": st.get("window", "hann"),
                "segment_length_m": st.get("segment_length_m", 0.05),
                "f_max_hz": float(st.get("f_range_hz", kwargs.get("f_range_hz", (2.0, 40.0)))[1]),
                "direction": d,
                "n_bins": int(sub.n_bins.iloc[0]), "n_oma_segments": int(sub.n_oma_segments.iloc[0]),
                "flagged_fraction": float(sub.flagged_fraction.mean()),
                "rmse_ema_um_per_n": float(summ.loc[(d, "ema"), "rmse_vs_truth_um_per_n"]),
                "rmse_robust_um_per_n": float(summ.loc[(d, "robust"), "rmse_vs_truth_um_per_n"]),
                "change_pct": float(summ.loc[(d, "robust"), "change_pct"]),
            })  # fmt: skip
    return OMASettingsResult(tuple(rows))
