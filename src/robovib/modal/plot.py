"""Figures of FRFs and fitted modes (matplotlib imported on use)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

from ..frf.core import FRF
from ..frf.plot import FRFCurve, FRFView, plot_frf
from .parameters import ModalParameters

if TYPE_CHECKING:
    from .fits import FRFFits

__all__ = ["plot_frf_fit", "plot_frf_fits"]


def plot_frf_fit(
    frf: FRF,
    fitted: Sequence[ModalParameters] = (),
    residual: complex = 0j,
    title: str | None = None,
    *,
    flags: Sequence[str] = (),
    view: FRFView = "bode",
    ax=None,
    residual_curvature: float = 0.0,
):
    """A compliance FRF with the fitted modes' curve: magnitude, unwrapped phase, Re, Im, coherence.

    Parameters
    ----------
    frf : FRF
        Measured compliance FRF [m/N] (the fit band).
    fitted : sequence of ModalParameters
        Fitted modes; their summed compliance (+ ``residual``) is drawn dashed.
    residual : complex
        Constant residual compliance [m/N] of the fit.
    title : str, optional
        Figure title.
    flags : sequence of str
        Reasons the fit should not be trusted (:attr:`robovib.modal.ModalFit.flags`): shown in
        red on the figure, title prefixed "FLAGGED FIT".
    view : {"bode", "real-imag", "both"}
        Panels (see :func:`robovib.frf.plot_frf`); ``modal fit --plot`` draws ``"both"``.
    ax : sequence of matplotlib.axes.Axes, optional
        Axes to draw into (see :func:`robovib.frf.plot_frf`); a new figure when omitted.
    residual_curvature : float
        Coefficient [m/N] of the fit's ``(f / fn)^2`` residual term
        (:attr:`robovib.modal.ModalFit.residual_curvature`, fn of the first fitted mode).

    Returns
    -------
    matplotlib.figure.Figure
        The figure (saving is the caller's: ``robovib.io.save_figure``).
    """
    f = frf.frequency_hz
    overlays = []
    if fitted:
        r2 = (f / fitted[0].natural_frequency_hz) ** 2
        model = sum(m.compliance(f) for m in fitted) + residual + residual_curvature * r2
        overlays.append(FRFCurve("fit" if not flags else "fit (flagged)", f, model))
    if flags:
        title = f"FLAGGED FIT - {title}" if title else "FLAGGED FIT"
    fig = plot_frf(frf, ax, view=view, overlays=overlays, title=title)
    if flags:
        fig.axes[0].title.set_color("C3")
        fig.text(0.01, 0.005, "\n".join(f"flag: {r}" for r in flags), color="C3", fontsize=7,
                 va="bottom", ha="left", wrap=True)  # fmt: skip
        fig.subplots_adjust(bottom=min(0.35, 0.06 + 0.03 * len(flags)))
    return fig


def plot_frf_fits(fits: FRFFits, title: str | None = None, *, ax=None):
    """An FRF in its fit band with the fitted curve (``modal fit --plot``).

    The multi-mode fit's band and modes when there is one, else the dominant mode with its
    residual compliance; every flag of either fit shown in red.

    Parameters
    ----------
    fits : FRFFits
        The fits of one FRF (:func:`robovib.modal.fits.fit_frfs`).
    title : str, optional
        Figure title.
    ax : sequence of matplotlib.axes.Axes, optional
        Axes to draw into (see :func:`plot_frf_fit`); a new figure when omitted.

    Returns
    -------
    matplotlib.figure.Figure
        Magnitude/unwrapped phase, Re/Im and coherence panels (``view="both"``).
    """
    dom, multi = fits.dominant, fits.modes
    if multi is None:
        shown, fitted = fits.frf.band(*dom.band_hz), (dom.parameters,)
        residual, curvature = dom.residual_compliance, dom.residual_curvature
    else:
        shown, fitted, residual, curvature = fits.frf.band(*multi.band_hz), multi.modes, 0j, 0.0
    return plot_frf_fit(
        shown,
        fitted,
        residual=residual,
        title=title,
        flags=fits.flags,
        view="both",
        ax=ax,
        residual_curvature=curvature,
    )
