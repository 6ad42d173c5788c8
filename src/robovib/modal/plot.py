"""Figures of FRFs and fitted modes (matplotlib imported on use)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from ..frf.core import FRF
from ..frf.plot import FRFCurve, FRFView, plot_frf
from .parameters import ModalParameters

__all__ = ["plot_frf_fit"]


def plot_frf_fit(
    frf: FRF,
    fitted: Sequence[ModalParameters] = (),
    path: str | Path | None = None,
    residual: complex = 0j,
    title: str | None = None,
    *,
    flags: Sequence[str] = (),
    view: FRFView = "both",
    ax=None,
):
    """A compliance FRF with the fitted modes' curve: magnitude, unwrapped phase, Re, Im, coherence.

    Parameters
    ----------
    frf
        Measured compliance FRF [m/N] (the fit band).
    fitted
        Fitted modes; their summed compliance (+ ``residual``) is drawn dashed.
    path
        If given, the figure is written there (atomically) and closed.
    residual
        Constant residual compliance [m/N] of the fit.
    title
        Figure title.
    flags
        Reasons the fit should not be trusted (:attr:`robovib.modal.ModalFit.flags`): shown in
        red on the figure, title prefixed "FLAGGED FIT".
    view
        ``"bode"``, ``"real-imag"`` or ``"both"`` (see :func:`robovib.frf.plot_frf`).
    ax
        Axes to draw into (see :func:`robovib.frf.plot_frf`).

    Returns
    -------
    matplotlib.figure.Figure
    """
    f = frf.frequency_hz
    overlays = []
    if fitted:
        model = sum(m.compliance(f) for m in fitted) + residual
        overlays.append(FRFCurve("fit" if not flags else "fit (flagged)", f, model))
    if flags:
        title = f"FLAGGED FIT - {title}" if title else "FLAGGED FIT"
    fig = plot_frf(frf, ax, view=view, overlays=overlays, title=title)
    if flags:
        fig.axes[0].title.set_color("C3")
        fig.text(0.01, 0.005, "\n".join(f"flag: {r}" for r in flags), color="C3", fontsize=7,
                 va="bottom", ha="left", wrap=True)  # fmt: skip
        fig.subplots_adjust(bottom=min(0.35, 0.06 + 0.03 * len(flags)))
    if path is not None:
        import matplotlib.pyplot as plt

        from ..io.safe_write import save_figure

        save_figure(fig, path)
        plt.close(fig)
    return fig
