"""Figures of a campaign (matplotlib imported on use; no backend chosen here)."""

from __future__ import annotations

import numpy as np

__all__ = ["plot_next_poses"]


def _axis_label(name: str) -> str:
    """``"x_mm"`` -> ``"x [mm]"``: an input name with its unit suffix as an axis label."""
    stem, _, unit = name.rpartition("_")
    return f"{stem} [{unit}]" if stem and unit else name


def plot_next_poses(result, ax=None):
    """Candidates by their summed normalised predictive variance, training poses and the chosen
    next poses (numbered in pick order).

    The one figure of :func:`robovib.campaign.next_poses`, for every pose model: with one input
    (a path coordinate) the variance along it, the training poses as vertical lines; with two
    or more, the candidates coloured by the variance over the first two inputs.

    Parameters
    ----------
    result
        :class:`robovib.campaign.NextPoses` from :func:`robovib.campaign.next_poses` (or
        :meth:`robovib.hybrid.FRFPoseModel.next_poses`); it carries the candidates, their
        variance and the training poses.
    ax
        Matplotlib axes to draw into (None: a new figure).

    Returns
    -------
    matplotlib.figure.Figure
    """
    try:
        import matplotlib.pyplot as plt
    except ImportError:
        raise ImportError("plots need matplotlib: pip install 'robovib[plot]'") from None
    names = list(result.input_names)
    C, var = np.asarray(result.candidates, float), np.asarray(result.candidate_variance, float)
    X, P = np.asarray(result.training_poses, float), np.asarray(result.poses, float)
    if ax is None:
        fig, ax = plt.subplots(figsize=(6.5, 5) if len(names) > 1 else (7, 3.5))
    else:
        fig = ax.figure
    label = "summed normalised predictive variance [-]"
    if len(names) == 1:
        order = np.argsort(C[:, 0])
        ax.plot(C[order, 0], var[order], color="C0", label="candidates")
        for i, x in enumerate(X[:, 0]):
            ax.axvline(x, color="k", lw=1, label="measured poses" if i == 0 else None)
        for i, p in enumerate(P[:, 0]):
            ax.axvline(p, color="C3", ls="--", lw=1, label="next poses" if i == 0 else None)
            ax.annotate(str(i + 1), (p, var.max()), xytext=(3, -10), textcoords="offset points",
                        color="C3")  # fmt: skip
        ax.set_ylabel(label)
    else:
        sc = ax.scatter(C[:, 0], C[:, 1], c=var, s=18, cmap="viridis", label="candidates")
        fig.colorbar(sc, ax=ax, label=label)
        ax.scatter(X[:, 0], X[:, 1], marker="o", facecolors="none", edgecolors="k", s=30,
                   label="measured poses")  # fmt: skip
        ax.scatter(P[:, 0], P[:, 1], marker="*", c="red", s=160, label="next poses")
        for i, p in enumerate(P, start=1):
            ax.annotate(str(i), (p[0], p[1]), xytext=(4, 4), textcoords="offset points",
                        color="red")  # fmt: skip
        ax.set_ylabel(_axis_label(names[1]))
    ax.set_xlabel(_axis_label(names[0]))
    ax.set_title("Where to hammer next (integrated variance reduction)")
    ax.legend(loc="best", fontsize=8)
    fig.tight_layout()
    return fig
