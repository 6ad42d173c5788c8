"""Figures of a pose model's band calibration (matplotlib imported on use)."""

from __future__ import annotations

import numpy as np

__all__ = ["plot_calibration"]


def plot_calibration(calibration, n_bins: int = 10):
    """Reliability of the bands: PIT histogram per output and coverage at 50/90/95 %.

    Parameters
    ----------
    calibration
        :class:`robovib.gp.BandCalibration` (``PoseModalModel.calibration_``).
    n_bins
        Bins of the PIT histograms (a calibrated model gives a flat histogram at 1).

    Returns
    -------
    matplotlib.figure.Figure
        One panel per output (PIT density of the held-out measurements, the ideal 1 dashed)
        and a last panel with the coverage of every output against the ideal.

    Raises
    ------
    ValueError
        The calibration holds no PIT values.
    """
    import matplotlib.pyplot as plt

    if calibration.pit is None:
        raise ValueError("this calibration holds no PIT values")
    names = calibration.output_names
    n = len(names)
    cols = 3
    rows = int(np.ceil((n + 1) / cols))
    fig, axes = plt.subplots(rows, cols, figsize=(3.2 * cols, 2.4 * rows), squeeze=False)
    edges = np.linspace(0.0, 1.0, n_bins + 1)
    for j, name in enumerate(names):
        ax = axes.flat[j]
        pit = calibration.pit[:, j]
        pit = pit[np.isfinite(pit)]
        ax.hist(pit, bins=edges, density=True, color="tab:blue", alpha=0.75)
        ax.axhline(1.0, color="k", ls="--", lw=1)
        ax.set_title(f"{name} ({calibration.covariance[j]})", fontsize=8)
        ax.set_xlim(0, 1)
        ax.set_xlabel("PIT", fontsize=8)
        ax.tick_params(labelsize=7)
    ax = axes.flat[n]
    levels = np.asarray(calibration.levels)
    for j in range(n):
        ax.plot(100 * levels, 100 * calibration.coverage[j], "o-", ms=3, lw=0.8, alpha=0.7)
    ax.plot([40, 100], [40, 100], "k--", lw=1, label="ideal")
    ax.set_xlabel("nominal level [%]", fontsize=8)
    ax.set_ylabel("held-out coverage [%]", fontsize=8)
    ax.set_title("coverage, grouped CV", fontsize=8)
    ax.legend(fontsize=7, loc="upper left")
    ax.tick_params(labelsize=7)
    for ax in axes.flat[n + 1 :]:
        ax.set_visible(False)
    fig.tight_layout()
    return fig
