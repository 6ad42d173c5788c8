"""Reports of the studies: run a study, hand its result to :mod:`robovib.report`.

The report layer only reads results; this module composes a study with its report (the
``robovib report chapter3`` and ``robovib report control`` commands).
"""

from __future__ import annotations

import numpy as np

from ..report import Report, chapter3_report, control_report
from ..report.kinds import report_provenance

__all__ = ["chapter3_study_report", "control_study_report"]


def chapter3_study_report(
    *, kernel: str = "ard", n_splits: int = 5, mode_switch: bool = True, rng: int = 0
) -> Report:
    """Run the chapter-3 study (:func:`robovib.studies.chapter3.chapter3_study`) and report it.

    Parameters
    ----------
    kernel : {"ard", "isotropic"}
        The GP length scales (not the covariance family): one per input (ARD) or one shared.
    n_splits : int
        Cross-validation folds, 2-20.
    mode_switch : bool
        Classify the ~63 Hz X-mode switch (default) or smooth over it (thesis).
    rng : int
        Seed.

    Returns
    -------
    Report
        The study's page (:func:`robovib.report.chapter3_report`).

    Raises
    ------
    ValueError
        Unknown kernel, ``n_splits`` out of range.
    """
    from .chapter3 import chapter3_study

    if kernel not in ("ard", "isotropic"):
        raise ValueError(f"unknown kernel {kernel!r}; use 'ard' or 'isotropic'")
    if int(n_splits) != n_splits or not 2 <= n_splits <= 20:
        raise ValueError(
            f"n_splits must be an integer in [2, 20] (cross-validation folds), got {n_splits}"
        )
    study = chapter3_study(kernel=kernel, n_splits=n_splits, mode_switch=mode_switch, rng=rng)
    return chapter3_report(study, report_provenance(None))


def control_study_report(
    path_file=None, *, direction: str = "x", rng: int = 0, line=None
) -> Report:
    """Schedule from a path-modes CSV (or the virtual robot's EMA) + Table 9, as a report.

    Parameters
    ----------
    path_file : path, optional
        CSV of modes along a path (``s_m, fn_hz, stiffness_n_per_m, damping_ratio``); default:
        the virtual robot's EMA along the chapter-4 path.
    direction : {"x", "y", "z"}
        Direction of the virtual-robot path model.
    rng : int
        Seed of the virtual EMA.
    line : (model, start, end, n_points), optional
        Instead: gains along a straight line through a pose model of either kind
        (:func:`robovib.control.schedule.schedule_along_line`; a multi-mode model's mode is
        picked by its compliance peak, and the page says so).

    Returns
    -------
    Report
        The page (:func:`robovib.report.control_report`), schedule warnings as notes.
    """
    from ..control.schedule import schedule_gains
    from .table9 import table_9_comparison

    warnings: list[str] = []
    source = str(path_file) if path_file else "virtual-robot EMA along the chapter-4 path"
    if line is not None:
        from ..control.schedule import schedule_along_line

        model, start, end, n_points = line
        res = schedule_along_line(model, start, end, direction, n_points, warn=warnings.append)
        sched = res.schedule
        warnings += [res.mode_choice] if res.mode_choice else []
        if np.any(res.extrapolating):
            warnings.append(f"{int(np.sum(res.extrapolating))} of {n_points} poses lie outside "
                            "the model's training data: their modes are GP extrapolations")  # fmt: skip
        source = (f"pose model ({model.kind}), line {', '.join(f'{v:g}' for v in start)} -> "
                  f"{', '.join(f'{v:g}' for v in end)} ({', '.join(model.input_names)})")  # fmt: skip
    else:
        if path_file is not None:
            from ..io import read_path_modes_csv

            s, modes = read_path_modes_csv(path_file)
        else:
            from ..sim import virtual_path_modes

            s, modes = virtual_path_modes(direction=direction, rng=rng)
        sched = schedule_gains(s, modes, warn=warnings.append)
    settings = {"path_file": source,
                "direction": direction, "period_ms": 4.0, "delay_ms": 32.0, "q": "diag(1, 0.001)"}  # fmt: skip
    rep = control_report(sched, list(table_9_comparison().rows), settings,
                         provenance=report_provenance(None, inputs=[path_file] if path_file else []))  # fmt: skip
    if warnings:
        first = rep.sections[0]
        from dataclasses import replace

        rep = replace(
            rep, sections=(replace(first, notes=(*first.notes, *warnings)), *rep.sections[1:])
        )
    return rep
