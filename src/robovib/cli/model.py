"""``robovib model``: the pose model of your robot (fit from modal.csv, where to hammer next)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from ._common import (
    JsonFlag,
    KernelOpt,
    Table,
    about_file,
    check_kernel,
    console,
    emit_json,
    escape,
    new_app,
    save_figure,
    use_agg,
)  # fmt: skip

app = new_app(
    "Pose model of your robot: fit it from a campaign's modal.csv, choose the next poses."
)


@app.command("fit")
def fit(
    modal_csv: Annotated[
        Path, typer.Argument(help="modal.csv written by 'robovib campaign process'.")
    ],
    output: Annotated[Path, typer.Option("-o", "--output", help="Model file to write (.h5).")],
    inputs: Annotated[
        str, typer.Option(help="Comma-separated pose columns used as inputs (units in the names).")
    ] = "x_mm,y_mm,rz_deg",
    kernel: KernelOpt = "ard",
    folds: Annotated[int, typer.Option(min=2, help="Folds of the CV grouped by pose.")] = 5,
    use_flagged: Annotated[
        bool, typer.Option("--use-flagged", help="Also train on rows whose fit is flagged.")
    ] = False,
    plot: Annotated[
        Path | None, typer.Option(help="Reliability figure (PIT histograms, coverage) to write.")
    ] = None,
    json_out: JsonFlag = False,
) -> None:
    """Fit the pose model of every output (fn, k, c per direction); print the grouped CV table.

    Given ``modes.csv`` (``campaign process --modes-band``: a ``mode_id`` column) the model has
    every tracked mode of x and y (directions x1, x2, ..., y1, ...), not the dominant one."""
    import warnings

    from ..campaign import fit_campaign_table, mode_switches_found, save_pose_model
    from ..campaign.quality import ModelQualityWarning
    from ..io import check_output_path

    for out in (output, plot):  # refused before the fit: onto the table, a FIFO, a link...
        if out is not None:
            check_output_path(out, inputs=[modal_csv])
    names = [n.strip() for n in inputs.split(",") if n.strip()]
    with (
        warnings.catch_warnings(),
        about_file(modal_csv),
    ):  # warnings printed below from res.warnings; errors name the table
        warnings.simplefilter("ignore", ModelQualityWarning)
        res = fit_campaign_table(modal_csv, inputs=names, kernel=check_kernel(kernel),
                                 n_folds=folds, use_flagged=use_flagged)  # fmt: skip
    save_pose_model(res, output)
    if plot is not None:
        from ..gp.plot import plot_calibration

        use_agg()
        save_figure(plot_calibration(res.model.calibration_), plot)
    switches = mode_switches_found(res.model)
    if json_out:
        emit_json({
            "modal_csv": str(modal_csv), "output": str(output), "inputs": names,
            "n_poses": len(set(res.groups.tolist())), "n_training_rows": len(res.X),
            "mode_switch_found": switches, "excluded_rows": [list(e) for e in res.excluded],
            "cv": res.cv_table.to_dict(orient="records"), "warnings": list(res.warnings),
        })  # fmt: skip
        return
    con = console()
    t = Table(title=f"Cross-validation grouped by pose ({res.model.provenance_['cv_folds']} folds)")
    for col in ("output", "n", "RMSE", "RMSE [%]", "R²", "in 50/90/95 % [%]", "NLPD", "kernel"):
        t.add_column(escape(col), justify="right")
    for r in res.cv_table.to_dict(orient="records"):
        cover = "/".join(f"{100 * r[f'coverage_{p}']:.0f}" for p in (50, 90, 95))
        t.add_row(escape(r["output"]), str(r["n"]), f"{r['rmse']:.4g}",
                  f"{r['relative_rmse_pct']:.2f}", f"{r['r2']:.3f}", cover,
                  f"{r['nlpd']:.3g}", escape(r["covariance"]))  # fmt: skip
    con.print(t)
    con.print("RMSE in the output's SI unit; coverage: held-out hammer tests inside the calibrated "
              "measurement set (docs/bands.md)")  # fmt: skip
    for w in (*res.warnings, *res.model.calibration_.warnings()):
        con.print(f"[yellow]warning:[/] {escape(w)}")
    found = [d for d, f in switches.items() if f]
    con.print("mode switch: " + (f"found in {', '.join(found)}" if found else "none found"))
    con.print(f"wrote {output}")


@app.command("next-poses")
def next_poses_cmd(
    model: Annotated[
        Path, typer.Option("--model", help="Pose model (.h5) from 'robovib model fit'.")
    ],
    candidates: Annotated[
        Path,
        typer.Option("--candidates", help="CSV of candidate poses with the model's input columns."),
    ],
    k: Annotated[int, typer.Option("--k", min=1, help="Poses to choose.")] = 5,
    plot: Annotated[
        Path | None, typer.Option(help="PNG: candidates, measured and chosen poses.")
    ] = None,
    json_out: JsonFlag = False,
) -> None:
    """Where to hammer next: largest integrated variance reduction over the candidates."""
    from ..campaign.selection import next_poses
    from ..gp.saved_model import load_pose_predictor
    from ..io.poses import read_pose_array

    m = load_pose_predictor(model)  # NumPy only: the full model would import scikit-learn
    cand = read_pose_array(candidates, m.input_names)  # no pandas
    res = next_poses(m, cand, k)
    names = list(m.input_names)
    rows = [{**dict(zip(names, map(float, p), strict=True)), "candidate_index": int(i),
             "variance_reduction_normalised": float(g)}
            for p, i, g in zip(res.poses, res.indices, res.variance_reduction, strict=True)]  # fmt: skip
    if plot is not None:
        from ..campaign import plot_next_poses

        use_agg()
        save_figure(plot_next_poses(res), plot)
    if json_out:
        emit_json({"model": str(model), "candidates": str(candidates), "k": k, "next_poses": rows,
                   "total_normalised_variance_before": res.total_variance_before})  # fmt: skip
        return
    t = Table(title=f"Next {k} poses (of {len(cand)} candidates)")
    for col in ("#", *names, "variance reduction [-]"):
        t.add_column(escape(col), justify="right")
    for j, r in enumerate(rows, start=1):
        t.add_row(
            str(j), *(f"{r[n]:g}" for n in names), f"{r['variance_reduction_normalised']:.3f}"
        )
    console().print(t)
