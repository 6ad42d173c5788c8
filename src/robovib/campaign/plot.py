"""Figures of a campaign (matplotlib imported on use; no backend chosen here)."""

from __future__ import annotations

import numpy as np

__all__ = ["plot_next_poses"]


def plot_next_poses(result, model, candidates, ax=None):
    """Candidates coloured by their summed normalised predictive variance, training poses and
    the chosen next poses (numbered in pick order), over the first two model inputs.

    Parameters
    ----------
    result
        :class:`robovib.campaign.NextPoses` from :func:`robovib.campaign.next_poses`.
    model
        The fitted pose model.
    candidates
        The candidate set given to ``next_poses`` ((m, n_inputs) or DataFrame).
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
    names = list(model.input_names)
    if hasattr(candidates, "columns"):
        candidates = candidates[names].to_numpy(float)
    C = np.atleast_2d(np.asarray(candidates, float))
    mean, std = model.predict(C, return_std=True)
    scale = np.nanmax(np.abs(mean), axis=0)
    var = np.nansum((std / np.where(scale > 0, scale, 1.0)) ** 2, axis=1)
    if ax is None:
        fig, ax = plt.subplots(figsize=(6.5, 5))
    else:
        fig = ax.figure
    j = 1 if len(names) > 1 else 0
    sc = ax.scatter(C[:, 0], C[:, j], c=var, s=18, cmap="viridis", label="candidates")
    fig.colorbar(sc, ax=ax, label="summed relative predictive variance [-]")
    X = model.X_train_
    ax.scatter(X[:, 0], X[:, j], marker="o", facecolors="none", edgecolors="k", s=30,
               label="measured poses")  # fmt: skip
    P = result.poses
    ax.scatter(P[:, 0], P[:, j], marker="*", c="red", s=160, label="next poses")
    for i, p in enumerate(P, start=1):
        ax.annotate(str(i), (p[0], p[j]), xytext=(4, 4), textcoords="offset points", color="red")
    ax.set_xlabel(names[0])
    ax.set_ylabel(names[j])
    ax.set_title("Where to hammer next (integrated variance reduction)")
    ax.legend(loc="best", fontsize=8)
    return fig
