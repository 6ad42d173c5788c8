"""Report builders for each kind of result robovib produces."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from .html import Report, ReportSection

__all__ = [
    "chapter3_report",
    "control_report",
    "lobes_report",
    "lobes_study_report",
    "model_report",
    "plot_cv_rmse_ratio",
    "report_provenance",
    "result_report",
]


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

    Returns
    -------
    Report
        One section: the paragraphs, the result's table and the figures.
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
    # Outside the axes: inside, the legend covered bars.
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0)
    fig.tight_layout()
    return fig


def report_provenance(provenance=None, inputs=()) -> dict:
    """The given provenance, or the run's (command, input SHA-256) from :mod:`robovib.io`.

    Parameters
    ----------
    provenance : mapping, optional
        Provenance to use as it is.
    inputs : sequence of path
        Input files whose SHA-256 the run's provenance lists (when ``provenance`` is None).

    Returns
    -------
    dict
        ``command`` and ``input_files``, or a copy of ``provenance``.
    """
    if provenance is not None:
        return dict(provenance)
    from ..files.provenance import run_provenance

    prov = run_provenance(inputs=inputs)
    return {
        "command": " ".join(prov["command"]),
        "input_files": [f"{i['path']} (sha256 {i['sha256']})" for i in prov["input_files"]],
    }


def chapter3_report(study, provenance: Mapping[str, Any] | None = None) -> Report:
    """The chapter-3 study (GPR vs thesis Table 2, MLR, external validation) as a report.

    Parameters
    ----------
    study : object
        A :class:`robovib.studies.chapter3.Chapter3Study` (``to_frame()``, ``settings``).
    provenance : mapping, optional
        Provenance shown at the end (default: this run's command and inputs).

    Returns
    -------
    Report
        Thesis Table 2 beside this run's figures, and the RMSE-ratio figure.
    """
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


# ----------------------------------------------------------------------------- pose models
def _load_model(path):
    """A saved pose model (:class:`robovib.gp.PoseModalModel`: the chapter-3 model, a campaign's
    or a user's) or a hybrid FRF model, by the file's format tag."""
    from ..files.h5format import FRF_POSE_MODEL_FORMAT, POSE_MODEL_FORMAT, file_format
    from ..files.safe_read import MAX_BINARY_BYTES, check_input_file

    fmt, _ = file_format(check_input_file(path, "model file", MAX_BINARY_BYTES))
    if fmt == FRF_POSE_MODEL_FORMAT:
        from ..hybrid import FRFPoseModel

        return FRFPoseModel.load(path)
    if fmt == POSE_MODEL_FORMAT:
        from ..gp.loader import load_pose_model

        return load_pose_model(path)
    raise ValueError(
        f"{path}: format {fmt!r} is not a robovib pose model ({POSE_MODEL_FORMAT}) or hybrid "
        f"FRF model ({FRF_POSE_MODEL_FORMAT})"
    )


def _file_provenance(path) -> dict:
    from ..files.provenance import read_provenance

    try:
        prov = read_provenance(path)
    except KeyError:
        return {"model file provenance": "none stored (written before robovib stored it)"}
    return {
        "model written by": " ".join(prov["command"]),
        "model robovib_version": prov["robovib_version"],
        "model settings": prov["settings"],
        "model inputs": [f"{i['path']} (sha256 {i['sha256']})" for i in prov["input_files"]],
    }


def plot_pose_model_slice(model, ax=None, n: int = 60):
    """Predicted natural frequency per direction along the first input (others at mid-range).

    Parameters
    ----------
    model
        A fitted pose model (``PoseModalModel`` interface: ``input_names``, ``directions``,
        ``X_train_``, ``predict(X, return_std=True)``).
    ax
        Axes to draw into; a new figure when None.
    n
        Points along the first input.

    Returns
    -------
    matplotlib.figure.Figure
    """
    import matplotlib.pyplot as plt

    if ax is None:
        fig, ax = plt.subplots(figsize=(7, 3.6))
    else:
        fig = ax.figure
    X = np.asarray(model.X_train_, float)
    lo, hi = X.min(axis=0), X.max(axis=0)
    grid = np.tile((lo + hi) / 2, (n, 1))
    grid[:, 0] = np.linspace(lo[0], hi[0], n)
    mean, std = model.predict(grid, return_std=True)
    names = list(model.output_names_)
    for i, d in enumerate(model.directions_):
        j = names.index(f"{d}_fn_hz")
        ax.plot(grid[:, 0], mean[:, j], color=f"C{i}", label=f"{d.upper()} fn")
        ax.fill_between(grid[:, 0], mean[:, j] - 2 * std[:, j], mean[:, j] + 2 * std[:, j],
                        color=f"C{i}", alpha=0.2)  # fmt: skip
    name = model.input_names[0]
    unit = name.rsplit("_", 1)[-1] if "_" in name else "-"
    others = ", ".join(
        f"{k} = {v:g}" for k, v in zip(model.input_names[1:], grid[0, 1:], strict=True)
    )
    ax.set_xlabel(f"{name} [{unit}]")
    ax.set_ylabel("natural frequency [Hz]")
    ax.set_title(f"prediction ±2σ ({others})" if others else "prediction ±2σ", fontsize=9)
    ax.legend(fontsize=8)
    fig.tight_layout()
    return fig


def model_report(path, provenance: Mapping[str, Any] | None = None) -> Report:
    """Report of a saved pose model (campaign/user model, or a hybrid FRF model).

    Parameters
    ----------
    path : str or pathlib.Path
        The model's HDF5 file.
    provenance : mapping, optional
        Provenance shown at the end (default: this run's command and inputs).

    Returns
    -------
    Report
        Input ranges, fit on the training data, cross-validation and the file's provenance.

    Raises
    ------
    ValueError
        The file is not a robovib pose model.
    """
    import pandas as pd

    from ..report.html import file_sha256

    model = _load_model(path)
    prov = {**report_provenance(provenance, inputs=[path]), **_file_provenance(path)}
    prov.setdefault("model file sha256", file_sha256(path))
    from ..gp.contract import PoseModel

    if not isinstance(model, PoseModel):  # the hybrid FRF model: its own page
        return _frf_model_report(model, path, prov)
    X = np.asarray(model.X_train_, float)
    Y = np.asarray(model.Y_train_, float)
    inputs = pd.DataFrame({"input": list(model.input_names), "min": X.min(axis=0),
                           "max": X.max(axis=0)}).set_index("input")  # fmt: skip
    mean, std = model.predict(X, return_std=True)
    names = list(model.output_names_)
    resid = pd.DataFrame(
        {
            "training cells": np.isfinite(Y).sum(axis=0),
            "mean (SI)": np.nanmean(Y, axis=0),
            "RMS residual at training poses (SI)": np.sqrt(np.nanmean((mean - Y) ** 2, axis=0)),
            "mean predictive std (SI)": std.mean(axis=0),
        },
        index=pd.Index(names, name="output (unit in the name)"),
    )
    tables = [("Training range of each input", inputs), ("Fit at the training poses", resid)]
    figures = [
        ("Predicted natural frequencies along the first input", plot_pose_model_slice(model))
    ]
    cal = model.calibration_ if model.calibrated else None
    paragraphs = [
        f"{type(model).__name__} from {path}: {X.shape[0]} training rows, inputs "
        f"{', '.join(model.input_names)}, outputs {', '.join(names)} (SI).",
        f"Kind: {model.kind} (modes {', '.join(model.directions_)}); bands "
        f"{'calibrated' if model.calibrated else 'NOT calibrated'}.",
    ]
    presence = model.provenance.get("mode_presence")
    if presence:
        import json

        seen = json.loads(str(presence))
        paragraphs.append("Mode presence (fraction of the campaign's recordings that showed the "
                          "mode): " + ", ".join(f"{k} {v['presence']:.0%}"
                                                for k, v in sorted(seen.items())))  # fmt: skip
    if cal is not None:
        from ..gp.plot import plot_calibration

        table = cal.table().set_index("output")
        tables.append(("Band calibration: grouped CV by pose (coverage of the measurement set, "
                       "NLPD, RMSE in SI)", table))  # fmt: skip
        figures.append(("Reliability: PIT histograms and coverage", plot_calibration(cal)))
        paragraphs.append(
            f"Bands calibrated on a {cal.n_folds}-fold CV grouped by pose ({cal.n_poses} poses): "
            "a Student-t scale and tail per output and mode; see docs/bands.md."
        )
    else:
        from ..gp.calibration import UNCALIBRATED_NOTE

        paragraphs.append(f"Bands: {UNCALIBRATED_NOTE}.")
    quality = (getattr(model, "provenance_", None) or {}).get("quality_warnings")
    if quality:  # model fit's named warnings (issue 36): low grouped-CV R², modes left out
        import json

        paragraphs += [f"Warning: {w}" for w in json.loads(quality)]
    section = ReportSection(
        title="Pose model of the modal parameters",
        paragraphs=tuple(paragraphs),
        tables=tuple(tables),
        figures=tuple(figures),
    )
    settings = dict(model.get_params())
    return Report(f"robovib — pose model {Path(path).name}", (section,), settings=settings,
                  provenance=prov)  # fmt: skip


def _frf_model_report(model, path, prov) -> Report:
    import pandas as pd

    from ..frf import FRF, FRFCurve, plot_frf

    lo, hi = float(np.min(model.pose_range_[0])), float(np.max(model.pose_range_[1]))
    s = np.linspace(lo, hi, 5)
    h, sd = model.predict(s, return_std=True)
    f = np.asarray(model.frequency_hz)
    peak = np.argmax(np.abs(h), axis=1)
    table = pd.DataFrame({
        "s_m": s,
        "peak_frequency_hz": f[peak],
        "peak_compliance_um_per_n": 1e6 * np.abs(h[np.arange(s.size), peak]),
        "std_at_peak_um_per_n": 1e6 * sd[np.arange(s.size), peak],
    })  # fmt: skip
    main = FRF(f, h[0], source="model", estimator="model")
    overlays = [
        FRFCurve(f"s = {v:.3f} m", f, hv, std=sv, style="-")
        for v, hv, sv in zip(s[1:], h[1:], sd[1:], strict=True)
    ]
    fig = plot_frf(main, view="both", overlays=overlays, labels=[f"s = {s[0]:.3f} m"],
                   title="predicted compliance along the path (±2σ)")  # fmt: skip
    section = ReportSection(
        title="Hybrid EMA + OMA FRF model (thesis chapter 5)",
        paragraphs=(
            f"{path}: per-bin GP over the path coordinate s in [{lo:g}, {hi:g}] m, "
            f"{f.size} bins {f[0]:g}-{f[-1]:g} Hz.",
        ),
        tables=(("Predicted peak along the path", table),),
        figures=(("Predicted FRFs at five path coordinates", fig),),
    )
    return Report(f"robovib — FRF model {Path(path).name}", (section,),
                  settings={"kernel": model.kernel, "direction": getattr(model, "direction_", None)},
                  provenance=prov)  # fmt: skip


# --------------------------------------------------------------------------------- lobes
def lobes_report(chart, settings: Mapping[str, Any], provenance=None) -> Report:
    """A stability chart (:class:`robovib.milling.chart.LobesChart`) as a report.

    Parameters
    ----------
    chart : LobesChart
        The chart.
    settings : mapping
        The settings that produced it.
    provenance : mapping, optional
        Provenance shown at the end (default: this run's command and inputs).

    Returns
    -------
    Report
        Summary, sampled critical depths and the chart figure.
    """
    import pandas as pd

    from ..milling.chart import plot_lobes_chart

    doc = chart.to_dict()

    def mm(v):
        return "-" if v is None else f"{1e3 * v:.3f}"

    summary = pd.DataFrame({
        "quantity": ["depth stable at every speed [mm]", "most stable speed [rpm]",
                     "critical depth there [mm]", "method", "tool"],
        "value": [mm(doc["minimum_depth_m"]),
                  "-" if doc["most_stable_rpm"] is None else f"{doc['most_stable_rpm']:.0f}",
                  mm(doc["most_stable_depth_m"]), doc["method"],
                  f"{1e3 * chart.tool.diameter_m:g} mm, {chart.tool.n_flutes} flutes"],
    }).set_index("quantity")  # fmt: skip
    rpm = np.asarray(doc["rpm"], float)
    depth = np.array([np.nan if v is None else v for v in doc["a_lim_m"]], float)
    step = max(1, rpm.size // 25)
    samples = pd.DataFrame({"spindle_rpm": rpm[::step], "critical_depth_mm": 1e3 * depth[::step],
                            "limited_by": np.asarray(doc["kind"])[::step]})  # fmt: skip
    paragraphs = (chart.title.replace("\n", "; "), *chart.notes)
    if chart.probability is not None:  # P(stable): the sampled limit's 5/95 % quantiles
        p = chart.probability
        lo, hi = (np.asarray(p.depth_quantile_m(q), float) for q in (0.05, 0.95))
        samples["critical_depth_p05_mm"] = 1e3 * lo[::step]
        samples["critical_depth_p95_mm"] = 1e3 * hi[::step]
        paragraphs = (*paragraphs, (
            f"Uncertainty: {p.settings['n_samples']} samples of the pose model's predictive "
            "distribution; the 5-95 % columns bound the critical depth with 90 % probability, "
            "and the chart's colour is the probability of a stable cut."))  # fmt: skip
    section = ReportSection(
        title="Chatter stability at the pose",
        paragraphs=paragraphs,
        tables=(("Summary", summary), ("Critical axial depth vs spindle speed", samples)),
        figures=(("Stability chart: envelope, unstable region shaded", plot_lobes_chart(chart)),),
    )
    return Report("robovib — stability lobes", (section,), settings=dict(settings),
                  provenance=report_provenance(provenance))  # fmt: skip


def lobes_study_report(
    x_mm: float,
    y_mm: float,
    rz_deg: float,
    *,
    ae_mm: float = 6.0,
    material: str = "al7075",
    feed: str = "x",
    spindle_rpm=None,
    method: str = "sdm",
    model=None,
    rng: int = 0,
    n_samples: int = 0,
) -> Report:
    """Lobes at a pose from the chapter-3 pose model (or ``model``) as a report.

    The defaults are those of ``robovib mill lobes`` (semi-discretization, 200 speeds from 100 to
    3000 rpm, 40 steps per period): the page and the command give the same answer.

    Parameters
    ----------
    x_mm, y_mm, rz_deg : float
        The pose [mm, mm, deg].
    ae_mm : float
        Radial depth of cut [mm].
    material : {"al7075", "acetal"}
        Cutting-force coefficients.
    feed : {"x", "y"}
        Feed direction.
    spindle_rpm : array_like, optional
        Spindle speeds [rpm], rising (default: 200 from 100 to 3000 rpm).
    method : str
        Stability method (``"sdm"`` or ``"zoa"``).
    model : PoseModel, optional
        Pose model of either kind (dominant-mode or multi-mode; default: the shipped chapter-3
        model).
    rng : int
        Seed of the chapter-3 model and of the samples.
    n_samples : int
        Monte-Carlo samples of the model for the probability of a stable cut (0: none).

    Returns
    -------
    Report
        The stability chart at the pose (:func:`lobes_report`).

    Raises
    ------
    ValueError
        Unknown material, feed direction or method; non-finite pose; bad speed range or radial
        depth (checked by :func:`robovib.milling.chart.lobes_chart`).
    """
    from ..gp import get_chapter3_model
    from ..milling import ACETAL, ALUMINIUM_7075, CuttingConditions, MillingTool
    from ..milling.chart import lobes_chart

    mats = {"al7075": ALUMINIUM_7075, "acetal": ACETAL}
    if material not in mats:
        raise ValueError(f"unknown material {material!r}; use one of {', '.join(mats)}")
    if feed not in ("x", "y"):
        raise ValueError(f"unknown feed direction {feed!r}; use x or y")
    for name, v in (("x_mm", x_mm), ("y_mm", y_mm), ("rz_deg", rz_deg), ("ae_mm", ae_mm)):
        if not np.isfinite(v):
            raise ValueError(f"{name} must be finite, got {v}")
    if not ae_mm > 0:
        raise ValueError(f"radial depth ae must be > 0 mm, got {ae_mm}")
    speeds = (
        np.linspace(100.0, 3000.0, 200) if spindle_rpm is None else np.asarray(spindle_rpm, float)
    )
    if (
        speeds.ndim != 1
        or speeds.size < 2
        or not np.all(np.isfinite(speeds))
        or np.any(np.diff(speeds) <= 0)
        or speeds[0] <= 0
    ):
        raise ValueError("spindle_rpm must be 2 or more positive, finite, rising speeds [rpm]")
    even = np.allclose(np.diff(speeds), speeds[1] - speeds[0], rtol=1e-9)
    rpm_range = f"{speeds[0]:g}:{speeds[-1]:g}:{speeds.size}" if even else speeds.tolist()
    model = model if model is not None else get_chapter3_model(rng=rng)
    tool = MillingTool()
    chart = lobes_chart(
        tool=tool, conditions=CuttingConditions(1000.0, 1e-4, 1e-3, ae_mm / 1e3),
        coefficients=mats[material], spindle_rpm=speeds, method=method,
        pose_label=f"X {x_mm:g} mm, Y {y_mm:g} mm, Rz {rz_deg:g}°, feed {feed}",
        material_label=material, pose_model=model, pose=(x_mm, y_mm, rz_deg), feed_direction=feed,
        n_samples=n_samples, rng=rng,
    )  # fmt: skip
    settings = {"x_mm": x_mm, "y_mm": y_mm, "z_mm": 325.0, "rz_deg": rz_deg, "ae_mm": ae_mm,
                "material": material, "feed_direction": feed, "rpm_range": rpm_range,
                "n_speeds": int(speeds.size), "method": method,
                "tool": "25.4 mm, 2 flutes, 30° helix (thesis §3.5)"}  # fmt: skip
    if n_samples:
        settings |= {"n_samples": int(n_samples), "seed": int(rng)}
    return lobes_report(chart, settings)


# ------------------------------------------------------------------------------- control
def control_report(schedule, table9_rows, settings: Mapping[str, Any], provenance=None) -> Report:
    """Gain schedule along a path and the Table 9 comparison as a report.

    Parameters
    ----------
    schedule : GainSchedule
        Gains along the path (:func:`robovib.control.schedule.schedule_gains`).
    table9_rows : sequence of dict
        Rows of the Table 9 comparison.
    settings : mapping
        The settings that produced them.
    provenance : mapping, optional
        Provenance shown at the end (default: this run's command and inputs).

    Returns
    -------
    Report
        The gain schedule and the Table 9 comparison.
    """
    import pandas as pd

    sched = pd.DataFrame({"s_m": schedule.s_m, "w1_m_per_m": schedule.w1, "w2_s": schedule.w2,
                          "r": schedule.r, "stable_with_delay": schedule.stable_with_delay})  # fmt: skip
    t9 = pd.DataFrame(table9_rows)
    unstable = int(np.sum(~np.asarray(schedule.stable_with_delay, bool)))
    notes = (f"{unstable} path points are unstable with the delay",) if unstable else ()
    sections = (
        ReportSection(
            title="LQR gain schedule along the path (thesis §4.3, Fig. 23 analogue)",
            paragraphs=(
                "Gains W = [w1, w2] designed per path point with R tuned for the delay; "
                "dots: the designed gains; lines: the Eq. 28-29 polynomial fits.",
            ),
            notes=notes,
            tables=(("Gains along the path", sched),),
            figures=(("w1 and w2 along the path", schedule.plot()),),
        ),
        ReportSection(
            title="Plant formulations vs thesis Table 9",
            tables=(("LQR gains from the Table 8 predictions (thesis values beside)", t9),),
        ),
    )
    return Report("robovib — vibration control study", sections, settings=dict(settings),
                  provenance=report_provenance(provenance))  # fmt: skip
