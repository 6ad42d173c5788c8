"""FRF figures: magnitude / unwrapped phase (Bode) and real / imaginary parts.

matplotlib is imported inside the functions (optional extra ``robovib[plot]``).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np

from .core import FRF

__all__ = ["FRFCurve", "plot_frf", "unwrapped_phase_deg"]

FRFView = Literal["bode", "real-imag", "both"]
#: Display unit and scale of each FRF quantity (SI values are multiplied by the scale).
_DISPLAY = {
    "compliance": ("µm/N", 1e6),
    "mobility": ("mm/s/N", 1e3),
    "accelerance": ("m/s²/N", 1.0),
}


@dataclass(frozen=True)
class FRFCurve:
    """An extra curve on an FRF figure (a fit, a prediction, a measurement to compare with).

    Attributes
    ----------
    label
        Legend entry.
    frequency_hz
        (n,) frequencies [Hz].
    values
        (n,) complex FRF in SI units of the figure's quantity (m/N for compliance).
    std
        (n,) standard deviation of the magnitude (and of each of Re, Im) [SI], drawn as a
        ±2σ band; or None.
    style
        Matplotlib line style; ``""`` draws only the band.
    color
        Matplotlib colour (default: the next in the cycle).
    """

    label: str
    frequency_hz: np.ndarray
    values: np.ndarray
    std: np.ndarray | None = None
    style: str = "--"
    color: str | None = None


def unwrapped_phase_deg(values) -> np.ndarray:
    """Phase of a complex FRF [deg], unwrapped along frequency (no ±180° jumps).

    The first bin lies in (-180, 180]; later bins continue it smoothly (``numpy.unwrap``).

    Parameters
    ----------
    values
        (n,) complex FRF.

    Returns
    -------
    numpy.ndarray
        (n,) phase [deg].
    """
    return np.degrees(np.unwrap(np.angle(np.asarray(values, complex))))


def _axes(ax, n: int):
    import matplotlib.pyplot as plt

    if ax is None:
        fig, axes = plt.subplots(n, 1, sharex=True, figsize=(7, 1.9 * n + 0.9))
        return fig, list(np.atleast_1d(axes))
    axes = list(np.atleast_1d(ax))
    if len(axes) < n:
        raise ValueError(f"this FRF view needs {n} axes, got {len(axes)}")
    return axes[0].figure, axes[:n]


def plot_frf(
    frf: FRF | Sequence[FRF],
    ax=None,
    *,
    view: FRFView = "bode",
    overlays: Sequence[FRFCurve] = (),
    coherence: bool = True,
    title: str | None = None,
    labels: Sequence[str] | None = None,
):
    """Plot FRFs as magnitude and unwrapped phase, or as real and imaginary parts.

    Parameters
    ----------
    frf
        One FRF or several of the same quantity (SI values; shown in µm/N for compliance).
    ax
        Axes to draw into: 2 for ``"bode"`` / ``"real-imag"`` (+1 for coherence), 4 for
        ``"both"`` (+1); a new figure when None.
    view
        ``"bode"``: |H| (log scale) and unwrapped phase [deg]; ``"real-imag"``: Re H and Im H
        against frequency; ``"both"``: all four panels.
    overlays
        Extra curves (fits, predictions with a ±2σ band).
    coherence
        Add a coherence panel when the (first) FRF has one.
    title
        Figure title.
    labels
        Legend entries of the FRFs (default: source and estimator); bins flagged in
        ``frf.meta["flagged"]`` (OMA harmonics) are marked with grey crosses.

    Returns
    -------
    matplotlib.figure.Figure

    Raises
    ------
    ValueError
        Unknown view, no FRF, FRFs of different quantities, or too few axes.
    ImportError
        matplotlib is not installed.
    """
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        raise ImportError("plots need matplotlib: pip install 'robovib[plot]'") from None
    if view not in ("bode", "real-imag", "both"):
        raise ValueError(f"unknown FRF view {view!r}; use 'bode', 'real-imag' or 'both'")
    frfs = [frf] if isinstance(frf, FRF) else list(frf)
    if not frfs:
        raise ValueError("no FRF to plot")
    quantity = frfs[0].quantity
    if any(f.quantity != quantity for f in frfs):
        raise ValueError(
            "FRFs of different quantities (compliance/mobility/accelerance) in one plot"
        )
    unit, scale = _DISPLAY[quantity]
    panels = {"bode": ["mag", "phase"], "real-imag": ["re", "im"],
              "both": ["mag", "phase", "re", "im"]}[view]  # fmt: skip
    if coherence and frfs[0].coherence is not None:
        panels.append("coh")
    fig, axes = _axes(ax, len(panels))
    axd = dict(zip(panels, axes, strict=True))
    labels = list(labels) if labels is not None else [
        "predicted" if f.source == "model" else f"measured ({f.source} {f.estimator})" for f in frfs
    ]  # fmt: skip

    def draw(f, v, label, style, color, std=None):
        v = np.asarray(v, complex) * scale
        if not style:  # band only
            style, v_line = "-", np.full(v.shape, np.nan + 0j)
        else:
            v_line = v
        if "mag" in axd:
            axd["mag"].semilogy(f, np.abs(v_line), style, color=color, label=label)
            if std is not None:
                s = 2 * np.asarray(std) * scale
                lo = np.maximum(np.abs(v) - s, np.abs(v) * 1e-3)
                axd["mag"].fill_between(f, lo, np.abs(v) + s, color=color, alpha=0.2)
            axd["phase"].plot(f, unwrapped_phase_deg(v_line), style, color=color)
        if "re" in axd:
            axd["re"].plot(
                f, v_line.real, style, color=color, label=None if "mag" in axd else label
            )
            axd["im"].plot(f, v_line.imag, style, color=color)
            if std is not None:
                s = 2 * np.asarray(std) * scale
                axd["re"].fill_between(f, v.real - s, v.real + s, color=color, alpha=0.2)
                axd["im"].fill_between(f, v.imag - s, v.imag + s, color=color, alpha=0.2)

    for i, (f, label) in enumerate(zip(frfs, labels, strict=True)):
        draw(f.frequency_hz, f.values, label, "-", f"C{i % 10}")
        flagged = np.asarray(f.meta.get("flagged", np.zeros(0)), bool)
        if flagged.shape == f.frequency_hz.shape and flagged.any():
            v = f.values[flagged] * scale
            fx = f.frequency_hz[flagged]
            for key, y in (("mag", np.abs(v)), ("re", v.real), ("im", v.imag)):
                if key in axd:
                    axd[key].plot(
                        fx, y, "x", color="0.5", label="flagged bins" if key == panels[0] else None
                    )
    for j, c in enumerate(overlays):
        draw(c.frequency_hz, c.values, c.label, c.style,
             c.color or f"C{(len(frfs) + j + 2) % 10}", c.std)  # fmt: skip
    if "mag" in axd:
        axd["mag"].set_ylabel(f"|H| [{unit}]")
        axd["phase"].set_ylabel("phase [deg]")
    if "re" in axd:
        axd["re"].set_ylabel(f"Re H [{unit}]")
        axd["im"].set_ylabel(f"Im H [{unit}]")
        for key in ("re", "im"):
            axd[key].axhline(0.0, color="0.7", lw=0.6)
    if "coh" in axd:
        axd["coh"].plot(frfs[0].frequency_hz, frfs[0].coherence, color="C2")
        axd["coh"].set_ylim(0, 1.05)
        axd["coh"].set_ylabel("coherence [-]")
    axes[0].legend(loc="best", fontsize=8)
    axes[-1].set_xlabel("frequency [Hz]")
    if title:
        axes[0].set_title(title)
    fig.tight_layout()
    return fig
