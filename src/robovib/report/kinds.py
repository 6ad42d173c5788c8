"""Report builders for each kind of result robovib produces."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from .html import Report, ReportSection

__all__ = ["chapter3_report", "plot_cv_rmse_ratio", "result_report"]


def result_report(
    title: str,
    result: Any,
    *,
    figures: Sequence[tuple[str, Any]] = (),
    paragraphs: Sequence[str] = (),
    notes: Sequence[str] = (),
    settings: Mapping[str, Any] | None = None,
    provenance: Mapping[str, Any] | None = None,
) -> Report:
    """A one-section report of any result that has ``to_frame()`` (and optionally ``settings``).

    Parameters
    ----------
    title
        Page title.
    result
        A frozen result object with ``to_frame() -> DataFrame``.
    figures
        ``(caption, Figure)`` pairs drawn from the result.
    paragraphs, notes
        Plain text shown above the table; notes are highlighted.
    settings, provenance
        Shown at the end of the page; ``settings`` defaults to ``result.settings`` when present.
    """
    if not hasattr(result, "to_frame"):
        raise TypeError(f"{type(result).__name__} has no to_frame(); cannot tabulate it")
    if settings is None:
        settings = getattr(result, "settings", {}) or {}
    section = ReportSection(
        title="Results",
        paragraphs=tuple(paragraphs),
        notes=tuple(notes),
        tables=(("Results", result.to_frame()),),
        figures=tuple(figures),
    )
    return Report(title, (section,), settings=dict(settings), provenance=dict(provenance or {}))


def plot_cv_rmse_ratio(study, ax=None):
    """Bar chart of cross-validated RMSE relative to the thesis' Table 2 GPR RMSE per output.

    Parameters
    ----------
    study
        A chapter-3 study result (fields ``outputs``, ``thesis_gpr_rmse``, ``gpr_plain_rmse``,
        ``gpr_grouped_rmse``, ``mlr_cv_rmse``).
    ax
        Axes to draw into; a new figure when None.

    Returns
    -------
    matplotlib.figure.Figure
    """
    import matplotlib.pyplot as plt

    if ax is None:
        fig, ax = plt.subplots(figsize=(8.0, 3.6))
    else:
        fig = ax.figure
    thesis = np.asarray(study.thesis_gpr_rmse, dtype=float)
    series = {
        "GPR plain CV": study.gpr_plain_rmse,
        "GPR grouped CV (unseen poses)": study.gpr_grouped_rmse,
        "MLR CV": study.mlr_cv_rmse,
    }
    positions = np.arange(len(study.outputs))
    width = 0.8 / len(series)
    for i, (label, values) in enumerate(series.items()):
        ax.bar(positions + (i - 1) * width, np.asarray(values) / thesis, width, label=label)
    ax.axhline(1.0, color="k", lw=0.8, ls="--", label="thesis GPR (Table 2)")
    ax.set_xticks(positions, list(study.outputs), rotation=30, ha="right", fontsize=8)
    ax.set_ylabel("RMSE / thesis GPR RMSE [-]")
    ax.set_xlabel("output")
    ax.set_yscale("log")
    ax.legend(fontsize=8)
    fig.tight_layout()
    return fig


def chapter3_report(study, provenance: Mapping[str, Any] | None = None) -> Report:
    """The chapter-3 study (GPR vs thesis Table 2, MLR, external validation) as a report."""
    frame = study.to_frame()
    thesis_cols = [c for c in frame.columns if c.startswith("thesis_")]
    ours = frame.drop(columns=thesis_cols)
    overview = ReportSection(
        title="Modal-parameter GPR over the workspace (thesis chapter 3)",
        paragraphs=(
            "Gaussian-process models of the dominant-mode natural frequency, stiffness and damping "
            "in X, Y and Z over the pose (X, Y, Rz), trained on Table A1 and validated by 5-fold "
            "cross-validation and on the external poses of Table A2.",
            "Plain CV keeps replicates of a test pose in the training folds (the thesis' protocol); "
            "grouped CV holds out whole poses and measures prediction at an unseen pose.",
        ),
        tables=(
            ("Thesis Table 2 (targets to compare with)", frame[thesis_cols]),
            ("This run: CV, MLR baseline and external validation (thesis units)", ours),
        ),
        figures=(("Cross-validated RMSE relative to the thesis", plot_cv_rmse_ratio(study)),),
    )
    return Report(
        "robovib — chapter-3 study",
        (overview,),
        settings=dict(study.settings),
        provenance=dict(provenance or {}),
    )
