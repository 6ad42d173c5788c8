"""Figures of FRFs and fitted modes (matplotlib imported on use)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..frf.core import FRF
from .parameters import ModalParameters

__all__ = ["plot_frf_fit"]


def plot_frf_fit(
    frf: FRF,
    fitted: Sequence[ModalParameters] = (),
    residual: complex = 0j,
    title: str | None = None,
    ax=None,
):
    """Magnitude, phase and coherence of a compliance FRF with the fitted modes' curve.

    Parameters
    ----------
    frf : FRF
        Measured compliance FRF [m/N] (the fit band).
    fitted : sequence of ModalParameters
        Fitted modes; their summed compliance (+ ``residual``) is drawn dashed.
    residual : complex
        Constant residual compliance [m/N] of the fit.
    title : str, optional
        Axes title.
    ax : sequence of matplotlib.axes.Axes, optional
        2 axes (magnitude, phase), 3 with coherence; a new figure when omitted.

    Returns
    -------
    matplotlib.figure.Figure
        The figure (saving is the caller's: ``robovib.io.save_figure``).
    """
    try:
        import matplotlib.pyplot as plt
    except ImportError:
        raise ImportError("plots need matplotlib: pip install 'robovib[plot]'") from None

    n_rows = 3 if frf.coherence is not None else 2
    if ax is None:
        fig, axes = plt.subplots(n_rows, 1, sharex=True, figsize=(7, 2.2 * n_rows + 0.6))
    else:
        axes = list(ax)
        if len(axes) != n_rows:
            raise ValueError(f"ax must be {n_rows} Axes (magnitude, phase[, coherence])")
        fig = axes[0].figure
    f = frf.frequency_hz
    label = "predicted" if frf.source == "model" else f"measured ({frf.source} {frf.estimator})"
    axes[0].semilogy(f, np.abs(frf.values), color="C0", label=label)
    axes[1].plot(f, np.degrees(np.angle(frf.values)), color="C0")
    if fitted:
        model = sum(m.compliance(f) for m in fitted) + residual
        axes[0].semilogy(f, np.abs(model), "--", color="C3", label="fit")
        axes[1].plot(f, np.degrees(np.angle(model)), "--", color="C3")
    axes[0].set_ylabel("|H| [m/N]")
    axes[1].set_ylabel("phase [deg]")
    axes[0].legend(loc="best", fontsize=8)
    if frf.coherence is not None:
        axes[2].plot(f, frf.coherence, color="C2")
        axes[2].set_ylim(0, 1.05)
        axes[2].set_ylabel("coherence")
    axes[-1].set_xlabel("frequency [Hz]")
    if title:
        axes[0].set_title(title)
    fig.tight_layout()
    return fig
