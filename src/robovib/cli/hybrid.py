"""``robovib hybrid``: hybrid EMA + OMA model of the whole FRF with Bayesian updating (ch. 5)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import numpy as np
import typer

from ._common import (
    JsonFlag,
    OutOpt,
    SeedOpt,
    Table,
    console,
    emit_json,
    new_app,
    save_figure,
    use_agg,
)

app = new_app("Hybrid EMA + OMA model of the whole FRF with Bayesian updating (thesis ch. 5).")


@app.command("study")
def study(
    background: Annotated[
        float,
        typer.Option(
            help="Broadband force content of the OMA cut (x spread of the periodic force)."
        ),
    ] = 1.0,
    seed: SeedOpt = 0,
    json_out: JsonFlag = False,
) -> None:
    """EMA at 3 poses, OMA from a 600 mm cut, validation: the Table 12 / 13 analogue."""
    from ..hybrid.study import hybrid_study

    res = hybrid_study(background_noise_rel=background, rng=seed)
    if json_out:
        emit_json(res)
        return
    con = console()
    t = Table(
        title="FRF RMSE at the validation pose [um/N] (peak error %) - thesis Table 12 analogue"
    )
    for col in ("dir", "bins", "OMA segs", "flagged", "before (EMA)", "posterior",
                "warm update", "full retrain"):  # fmt: skip
        t.add_column(col, justify="right")
    for d, row in res.items():

        def cell(k, row=row):
            return f"{row[k]['rmse_um_per_n']:.3f} ({row[k]['peak_error_pct']:.0f} %)"

        t.add_row(d.upper(), str(row["n_bins"]), str(row["n_oma_segments"]), f"{100 * row['flagged_fraction']:.0f} %",
                  cell("before"), cell("posterior"), cell("warm"), cell("retrain"))  # fmt: skip
    con.print(t)
    t = Table(title="Optimiser iterations per GP and wall time - thesis Table 13 analogue")
    for col in ("dir", "warm update", "full retrain"):
        t.add_column(col, justify="right")
    for d, row in res.items():
        t.add_row(d.upper(), f"{row['warm']['iterations_mean']:.1f} ({row['warm']['wall_time_s'] * 1e3:.0f} ms)",
                  f"{row['retrain']['iterations_mean']:.1f} ({row['retrain']['wall_time_s'] * 1e3:.0f} ms)")  # fmt: skip
    con.print(t)


@app.command("oma")
def oma(
    record: Annotated[
        Path,
        typer.Argument(
            help="Synchronised CSV: time_s, force_{x,y,z}_n, displacement_{x,y,z}_m, path_s_m (e.g. from `robovib sim mill`/`sim offset-mass`)."
        ),
    ],
    output: OutOpt,
    direction: Annotated[str, typer.Option(help="x, y or z.")] = "x",
    segment_m: Annotated[
        float, typer.Option("--segment", help="Path length per FRF [m] (path coordinates in m).")
    ] = 0.05,
    nperseg: Annotated[int, typer.Option(help="Welch window [samples].")] = 512,
    fmin: Annotated[float, typer.Option(help="Lowest frequency [Hz].")] = 2.0,
    fmax: Annotated[float, typer.Option(help="Highest frequency [Hz].")] = 40.0,
    rpm: Annotated[
        float | None, typer.Option(help="Spindle speed [rpm]: flags its harmonics.")
    ] = None,
    json_out: JsonFlag = False,
) -> None:
    """OMA compliance FRFs per path segment from a milling record (flagged bins stored)."""
    from ..hybrid import oma_frfs_with_path
    from ..io import read_milling_record_csv, write_frfs

    frfs = oma_frfs_with_path(
        read_milling_record_csv(record), direction=direction, segment_length_m=segment_m,
        nperseg=nperseg, f_min_hz=fmin, f_max_hz=fmax, spindle_rpm=rpm,
    )  # fmt: skip
    write_frfs(output, frfs, inputs=[record])
    flagged = [np.asarray(f.meta["flagged"], bool) for f in frfs]
    doc = {"output": str(output), "segments": len(frfs), "s_mid_m": [f.meta["path_s_m"] for f in frfs],
           "flagged_fraction": float(np.mean([fl.mean() for fl in flagged]))}  # fmt: skip
    if json_out:
        emit_json(doc)
    else:
        typer.echo(
            f"wrote {output}: {len(frfs)} OMA FRFs ({direction}), {100 * doc['flagged_fraction']:.0f} % of bins flagged"
        )


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
    json_out: JsonFlag = False,
) -> None:
    """Initial per-bin GP model of the compliance over the path from EMA FRFs."""
    from ..hybrid import FRFPoseModel, frfs_on_path_grid
    from ..io import read_frfs

    frfs = [f for path in ema for f in read_frfs(path)]
    if fmin is None:
        fmin = max([2.0, *(float(f.frequency_hz[0]) for f in frfs)])
    grid = np.arange(fmin, fmax + 1e-9, df_hz)
    h, s, m = frfs_on_path_grid(frfs, grid)
    model = FRFPoseModel(grid).fit(s, h, mask=m)
    model.save(output, inputs=ema)
    doc = {
        "output": str(output),
        "n_frfs": len(s),
        "n_bins": int(grid.size),
        "iterations_mean": model.last_report_.iterations_mean_per_gp,
    }
    if json_out:
        emit_json(doc)
    else:
        typer.echo(f"wrote {output}: {len(s)} EMA FRFs, {grid.size} bins")


@app.command("update")
def update(
    model_file: Annotated[Path, typer.Argument(help="Model from `hybrid fit`.")],
    oma_file: Annotated[Path, typer.Argument(help="OMA FRFs from `hybrid oma`.")],
    output: OutOpt,
    mode: Annotated[
        str, typer.Option(help="warm (re-optimise from the current hyperparameters) or posterior.")
    ] = "warm",
    json_out: JsonFlag = False,
) -> None:
    """Bayesian update of the model with OMA FRFs (separate noise level for OMA)."""
    from ..hybrid import FRFPoseModel, frfs_on_path_grid
    from ..io import read_frfs

    model = FRFPoseModel.load(model_file)
    h, s, m = frfs_on_path_grid(read_frfs(oma_file), model.frequency_hz, partial=True)
    rep = model.update(s, h, mask=m, mode=mode)
    model.save(output, inputs=[model_file, oma_file])
    doc = {"output": str(output), "n_oma": len(s), "mode": mode,
           "iterations_mean": rep.iterations_mean_per_gp, "wall_time_s": rep.wall_time_s}  # fmt: skip
    if json_out:
        emit_json(doc)
    else:
        typer.echo(
            f"wrote {output}: updated with {len(s)} OMA FRFs ({mode}, {rep.iterations_mean_per_gp:.1f} iterations per GP)"
        )


@app.command("predict")
def predict(
    model_file: Annotated[Path, typer.Argument(help="Model file.")],
    path_s: Annotated[float, typer.Option("--path-s", help="Path coordinate [m].")],
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
    """Predicted compliance FRF at a path coordinate, with a band; optional comparison."""
    from ..hybrid import FRFPoseModel, plot_frf_prediction, predict_frf_at
    from ..io import read_frfs

    model = FRFPoseModel.load(model_file)
    meas = read_frfs(measured)[0] if measured is not None else None
    pred = predict_frf_at(model, path_s, meas)
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
        typer.echo("warning: the path coordinate is outside the calibrated range: extrapolation")
    h, sd = pred.compliance_m_per_n, pred.std_m_per_n
    peak = int(np.argmax(np.abs(h)))
    typer.echo(
        f"peak compliance {1e6 * abs(h[peak]):.3f} um/N at {pred.frequency_hz[peak]:.2f} Hz (±{2e6 * sd[peak]:.3f} at 2σ)"
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
    from ..hybrid.study import plot_next_poses, propose_next_poses

    tested = path_s if path_s else [0.0, 0.585, 1.235]
    res = propose_next_poses(tested, k=k, direction=direction, rng=seed)
    if json_out:
        emit_json({"tested_s_m": res.tested_s_m, "next_s_m": res.next_s_m})
    else:
        typer.echo(
            "next hammer-test poses (path distance, m): "
            + ", ".join(f"{p:.3f}" for p in res.next_s_m)
        )
    if plot is not None:
        use_agg()
        save_figure(plot_next_poses(res), plot)
        if not json_out:
            typer.echo(f"wrote {plot}")
