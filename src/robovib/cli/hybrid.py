"""``robovib hybrid``: hybrid EMA + OMA model of the whole FRF with Bayesian updating (ch. 5)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from . import _hybrid_options as hopt
from . import hybrid_study
from ._common import (
    ForceOpt,
    JsonFlag,
    OutOpt,
    SeedOpt,
    about_file,
    check_output,
    emit_json,
    new_app,
    save_figure,
    use_agg,
)

app = new_app("Hybrid EMA + OMA model of the whole FRF with Bayesian updating (thesis chapter 5).")


# The simulation study on the virtual robot lives in its own module; listed first.
app.command("study")(hybrid_study.study)


@app.command("oma")
def oma(
    record: hopt.RecordArg,
    output: OutOpt,
    direction: Annotated[str, typer.Option(help="x, y or z.")] = "x",
    segment_m: hopt.SegmentOpt = 0.05,
    nperseg: hopt.NpersegOpt = 512,
    noverlap: hopt.NoverlapOpt = None,
    window: hopt.WindowOpt = "hann",
    fmin: Annotated[float, typer.Option(help="Lowest frequency [Hz].")] = 2.0,
    fmax: Annotated[float, typer.Option(help="Highest frequency [Hz].")] = 40.0,
    rpm: Annotated[
        float | None, typer.Option(help="Spindle speed [rpm]: flags its harmonics.")
    ] = None,
    min_coherence: Annotated[float, typer.Option(help="Bins below are flagged.")] = 0.5,
    force: ForceOpt = False,
    json_out: JsonFlag = False,
) -> None:
    """OMA compliance FRFs per path segment from a milling record (flagged bins stored).

    The record is a cut along the path (path_s_m column) or in the workspace (x_m, y_m,
    rz_deg columns); a warning says when too few bins pass the coherence check.
    """
    from ..hybrid import flagged_fraction, oma_frfs_with_path
    from ..io import read_milling_record_csv, write_frfs

    check_output(output, [record], force)
    with about_file(record):  # "record too short" etc. name the file
        frfs = oma_frfs_with_path(
            read_milling_record_csv(record), direction=direction, segment_length_m=segment_m,
            nperseg=nperseg, noverlap=noverlap, window=window, f_min_hz=fmin, f_max_hz=fmax,
            spindle_rpm=rpm, min_coherence=min_coherence,
        )  # fmt: skip
    write_frfs(output, frfs, inputs=[record], force=force)
    doc = {"output": str(output), "segments": len(frfs), "s_mid_m": [f.meta["path_s_m"] for f in frfs],
           "n_bins": int(frfs[0].frequency_hz.size), "df_hz": float(frfs[0].df_hz),
           "flagged_fraction": flagged_fraction(frfs)}  # fmt: skip
    emit_json(doc) if json_out else typer.echo(f"wrote {output}: {len(frfs)} OMA FRFs ({direction}), "
                                               f"{100 * doc['flagged_fraction']:.0f} % of bins flagged")  # fmt: skip


@app.command("fit")
def fit(
    ema: Annotated[
        list[Path],
        typer.Argument(help="EMA FRF files (.h5) with path coordinates (frf compute --path-s)."),
    ],
    output: OutOpt,
    fmin: Annotated[
        float | None,
        typer.Option(help="Model grid start [Hz]; default: where all EMA FRFs have data (>= 2)."),
    ] = None,
    fmax: Annotated[float, typer.Option(help="Model grid end [Hz].")] = 40.0,
    df_hz: Annotated[
        float, typer.Option("--df", help="Model grid step [Hz] (match the OMA resolution).")
    ] = 1.953125,
    inputs: Annotated[
        str,
        typer.Option(
            help="Pose inputs: path (the path coordinate s, m) or workspace (x, y in m, rz in deg from each FRF's pose; ARD kernel)."
        ),
    ] = "path",
    force: ForceOpt = False,
    json_out: JsonFlag = False,
) -> None:
    """Initial per-bin GP model of the compliance over the path or the workspace from EMA FRFs.

    All FRFs must be of one direction (kept in the model and checked by ``hybrid update``).
    """
    from ..hybrid import fit_frf_model
    from ..io import read_frfs

    check_output(output, ema, force)
    frfs = []
    for path in ema:
        read = read_frfs(path)
        other = sorted({f.source for f in read if f.source != "EMA"})
        if other:
            raise ValueError(
                f"{path}: holds {', '.join(other)} FRFs, not hammer-test (EMA) ones: 'hybrid fit' "
                "starts the model from EMA FRFs; add OMA FRFs with 'hybrid update'"
            )
        frfs += read
    with about_file(ema[0] if len(ema) == 1 else None):  # "FRF 0: no path coordinate" names it
        model = fit_frf_model(frfs, inputs, fmin, fmax, df_hz)
    model.save(output, provenance={"ema_files": ",".join(str(p) for p in ema)}, inputs=ema,
               force=force)  # fmt: skip
    doc = {
        "output": str(output),
        "direction": model.direction_,
        "n_frfs": len(frfs),
        "n_bins": int(model.frequency_hz_.size),
        "input_names": list(model.input_names),
        "iterations_mean": model.last_report_.iterations_mean_per_gp,
    }
    if json_out:
        emit_json(doc)
    else:
        typer.echo(
            f"wrote {output}: {len(frfs)} EMA FRFs ({model.direction_}), {model.frequency_hz_.size} bins"
        )


@app.command("update")
def update(
    model_file: Annotated[Path, typer.Argument(help="Model from `hybrid fit`.")],
    oma_file: Annotated[Path, typer.Argument(help="OMA FRFs from `hybrid oma`.")],
    output: OutOpt,
    mode: hopt.UpdateModeOpt = "robust",
    reoptimize: Annotated[
        bool, typer.Option(help="robust only: then re-optimise all hyperparameters (warm start).")
    ] = False,
    force: ForceOpt = False,
    json_out: JsonFlag = False,
) -> None:
    """Bayesian update of the model with OMA FRFs (separate noise level for OMA); says what was rejected.

    The FRFs must be OMA FRFs of the model's direction (checked, never mixed).
    """
    from ..hybrid import FRFPoseModel
    from ..io import read_frfs

    check_output(output, [model_file, oma_file], force)
    model = FRFPoseModel.load(model_file)
    s = read_frfs(oma_file)
    with about_file(oma_file):  # "FRF 0: no path coordinate" names the file
        rep = model.update_frfs(s, mode=mode, reoptimize=reoptimize)
    model.save(output, provenance={"updated_with": str(oma_file), "update_mode": mode},
               inputs=[model_file, oma_file], force=force)  # fmt: skip
    doc = {"output": str(output), "n_oma": len(s), **rep.to_dict()}
    if json_out:
        emit_json(doc)
    else:
        its = (f"{rep.iterations_mean_per_gp:.1f} optimiser iterations per GP"
               if rep.iterations_mean_per_gp > 0 else "hyperparameters kept, not re-optimised")  # fmt: skip
        typer.echo(f"wrote {output}: updated with {len(s)} OMA FRFs ({mode}, {its})")
        if mode == "robust":
            typer.echo(rep.describe())


@app.command("predict")
def predict(
    model_file: Annotated[Path, typer.Argument(help="Model file.")],
    path_s: Annotated[
        float | None, typer.Option("--path-s", help="Path coordinate [m] (path models).")
    ] = None,
    x_mm: Annotated[
        float | None, typer.Option("--x", help="Tool-tip X [mm] (workspace models).")
    ] = None,
    y_mm: Annotated[
        float | None, typer.Option("--y", help="Tool-tip Y [mm] (workspace models).")
    ] = None,
    rz_deg: Annotated[
        float | None,
        typer.Option("--rz", help="Rotation about the tool axis [deg] (workspace models)."),
    ] = None,
    measured: Annotated[
        Path | None, typer.Option(help="A measured FRF file to compare with (first FRF).")
    ] = None,
    plot: Annotated[
        Path | None,
        typer.Option(
            help="PNG: predicted FRF (magnitude/unwrapped phase, real/imaginary) with 95 % band and the measured one."
        ),
    ] = None,
    json_out: JsonFlag = False,
) -> None:
    """Predicted compliance FRF at a path coordinate or a workspace pose, with a band."""
    from ..gp.pose_units import pose_in_units
    from ..hybrid import FRFPoseModel, plot_frf_prediction, predict_frf_at
    from ..io import read_frfs

    check_output(plot, [model_file, measured])
    model = FRFPoseModel.load(model_file)
    given = {"s_m": path_s, "x_mm": x_mm, "y_mm": y_mm, "rz_deg": rz_deg}
    pose = pose_in_units(model.input_names, given, hopt.POSE_OPTIONS)  # in the model's units
    meas = read_frfs(measured)[0] if measured is not None else None
    pred = predict_frf_at(model, pose, meas)
    doc = pred.to_dict()

    def draw() -> None:
        if plot is not None:
            use_agg()
            save_figure(plot_frf_prediction(pred), plot, inputs=[model_file, measured])

    if json_out:
        emit_json(doc)
        draw()
        return
    if pred.extrapolating:
        typer.echo("warning: the pose is outside the calibrated range: extrapolation")
    f_peak, h_peak, sd_peak = pred.peak()
    typer.echo(
        f"peak compliance {1e6 * abs(h_peak):.3f} um/N at {f_peak:.2f} Hz (±{2e6 * sd_peak:.3f} at 2σ)"
    )
    if pred.rmse_um_per_n is not None:
        typer.echo(f"RMSE vs measured: {pred.rmse_um_per_n:.3f} um/N")
    if plot is not None:
        draw()
        typer.echo(f"wrote {plot}")


@app.command("next-poses")
def next_poses(
    k: Annotated[int, typer.Option("--k", help="Number of poses to propose.")] = 3,
    path_s: Annotated[
        list[float] | None,
        typer.Option(
            "--path-s",
            help="Path coordinate [m] already hammer-tested; repeat the option (default: 0, 0.585, 1.235).",
        ),
    ] = None,
    direction: Annotated[str, typer.Option(help="x, y or z.")] = "x",
    seed: SeedOpt = 0,
    plot: Annotated[
        Path | None, typer.Option(help="PNG of the variance along the path with the proposals.")
    ] = None,
    json_out: JsonFlag = False,
) -> None:
    """Where to hammer next along the chapter-4 path: largest integrated predictive variance."""
    from ..campaign.plot import plot_next_poses
    from ..studies.hybrid import propose_next_poses

    check_output(plot)
    tested = path_s if path_s else [0.0, 0.585, 1.235]
    res = propose_next_poses(tested, k=k, direction=direction, rng=seed)
    next_s_m = res.poses[:, 0]
    if json_out:
        emit_json({"tested_s_m": [float(s) for s in tested], "next_s_m": next_s_m})
    else:
        typer.echo(
            "next hammer-test poses (path distance, m): " + ", ".join(f"{p:.3f}" for p in next_s_m)
        )
    if plot is not None:
        use_agg()
        save_figure(plot_next_poses(res), plot)
        if not json_out:
            typer.echo(f"wrote {plot}")
