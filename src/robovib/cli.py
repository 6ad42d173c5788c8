"""Command-line interface of robovib (thin: parsing, unit conversion at the edge, printing)."""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Annotated

import numpy as np
import typer
from rich.console import Console
from rich.markup import escape
from rich.table import Table

app = typer.Typer(
    help="robovib: pose-dependent dynamics of machining robots.",
    no_args_is_help=True,
    add_completion=False,
)
gpr_app = typer.Typer(help="GP models of the modal parameters over the workspace (thesis ch. 3).")
app.add_typer(gpr_app, name="gpr")

JsonFlag = Annotated[
    bool, typer.Option("--json", help="Print one JSON document instead of tables.")
]
KernelOpt = Annotated[
    str,
    typer.Option(
        help="GP kernel: 'ard' (one length scale per input) or 'isotropic' (thesis Eq. 7)."
    ),
]
SeedOpt = Annotated[int, typer.Option(help="Seed of fold shuffles and optimiser restarts.")]
ModeSwitchOpt = Annotated[
    bool,
    typer.Option(
        "--mode-switch/--no-mode-switch",
        help="Classify the ~63 Hz X-mode switch at full extension (default) or smooth over it with one GP (thesis).",
    ),
]


def _console() -> Console:
    return Console(file=sys.stdout, width=max(Console().width, 140))


def _emit_json(doc: dict) -> None:
    typer.echo(json.dumps(doc, indent=2, allow_nan=True, default=_json_default))


def _json_default(obj):
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, np.generic):
        return obj.item()
    raise TypeError(f"not JSON serialisable: {type(obj).__name__}")


def _check_kernel(kernel: str) -> str:
    if kernel not in ("ard", "isotropic"):
        raise typer.BadParameter(f"unknown kernel {kernel!r}; use 'ard' or 'isotropic'")
    return kernel


@app.command()
def demo(
    kernel: KernelOpt = "ard",
    seed: SeedOpt = 0,
    printed_stiffness: Annotated[
        bool,
        typer.Option(
            help="Use Table A1's stiffness cells as printed (tests 59-60 shifted) instead of the corrected reading."
        ),
    ] = False,
    mode_switch: ModeSwitchOpt = True,
    json_out: JsonFlag = False,
) -> None:
    """Chapter-3 study on the shipped thesis data: GPR vs thesis Table 2, MLR, external validation."""
    from .studies.chapter3 import chapter3_study

    study = chapter3_study(
        kernel=_check_kernel(kernel),
        stiffness_reading="printed" if printed_stiffness else "corrected",
        mode_switch=mode_switch,
        rng=seed,
    )
    if json_out:
        frame = study.to_frame()
        _emit_json(
            {
                "settings": study.settings,
                "outputs": frame.reset_index(names="output").to_dict(orient="records"),
            }
        )
        return
    con = _console()
    s = study
    variant = "X-mode switch classified" if mode_switch else "one GP per output"
    t = Table(
        title=f"5-fold CV of the modal-parameter GPR on Table A1 (kernel={kernel}, {variant}, seed={seed})"
    )
    for col in (
        "output",
        "thesis GPR R²",
        "thesis RMSE",
        "plain CV R²",
        "plain RMSE",
        "grouped CV R²",
        "grouped RMSE",
    ):
        t.add_column(col, justify="right")
    for i, name in enumerate(s.outputs):
        t.add_row(
            escape(name),
            f"{s.thesis_gpr_r2[i]:.2f}",
            f"{s.thesis_gpr_rmse[i]:.2f}",
            f"{s.gpr_plain_r2[i]:.2f}",
            f"{s.gpr_plain_rmse[i]:.2f}",
            f"{s.gpr_grouped_r2[i]:.2f}",
            f"{s.gpr_grouped_rmse[i]:.2f}",
        )
    con.print(t)
    con.print(
        "plain CV = the thesis' protocol (replicates of a test pose stay in training); "
        "grouped CV = all replicates of a pose held out together (prediction at unseen poses)."
    )
    t = Table(title="2nd-order MLR baseline")
    for col in (
        "output",
        "thesis MLR R²",
        "thesis RMSE",
        "in-sample R²",
        "in-sample RMSE",
        "5-fold CV R²",
        "CV RMSE",
    ):
        t.add_column(col, justify="right")
    for i, name in enumerate(s.outputs):
        t.add_row(
            escape(name),
            f"{s.thesis_mlr_r2[i]:.2f}",
            f"{s.thesis_mlr_rmse[i]:.2f}",
            f"{s.mlr_insample_r2[i]:.2f}",
            f"{s.mlr_insample_rmse[i]:.2f}",
            f"{s.mlr_cv_r2[i]:.2f}",
            f"{s.mlr_cv_rmse[i]:.2f}",
        )
    con.print(t)
    t = Table(
        title="External validation on Table A2 (30 unseen poses), GPR fitted on all of Table A1"
    )
    for col in ("output", "RMSE", "mean rel. error", "max rel. error"):
        t.add_column(col, justify="right")
    for i, name in enumerate(s.outputs):
        t.add_row(
            escape(name),
            f"{s.external_rmse[i]:.3f}",
            f"{100 * s.external_mean_relative_error[i]:.1f} %",
            f"{100 * s.external_max_relative_error[i]:.1f} %",
        )
    con.print(t)


@gpr_app.command("predict")
def gpr_predict(
    x: Annotated[float, typer.Option("--x", help="Tool-tip X in the robot base frame [mm].")],
    y: Annotated[float, typer.Option("--y", help="Tool-tip Y in the robot base frame [mm].")],
    rz: Annotated[float, typer.Option("--rz", help="Rotation about the tool axis [deg].")],
    kernel: KernelOpt = "ard",
    seed: SeedOpt = 0,
    mode_switch: ModeSwitchOpt = True,
    json_out: JsonFlag = False,
) -> None:
    """Predicted dominant-mode parameters at a pose (Z = 325 mm, Rx = Ry = 0) with ±2σ."""
    from .datasets import X_HIGH_MODE_THRESHOLD_HZ
    from .studies.chapter3 import OUTPUT_LABELS
    from .studies.chapter3 import fit_chapter3_regressor as fit_chapter3_model

    pose = np.array([[x, y, rz]], dtype=float)
    if not np.all(np.isfinite(pose)):
        raise typer.BadParameter("pose coordinates must be finite numbers")
    model = fit_chapter3_model(kernel=_check_kernel(kernel), mode_switch=mode_switch, rng=seed)
    base = model.low_model_ if mode_switch else model
    lo, hi = base.X_train_.min(axis=0), base.X_train_.max(axis=0)
    outside = [
        name
        for name, v, a, b in zip(("x", "y", "rz"), pose[0], lo, hi, strict=True)
        if v < a or v > b
    ]
    mean, std = model.predict(pose, return_std=True)
    mean, std = mean[0], std[0]
    records = [
        {
            "output": label,
            "mean": float(m),
            "std": float(s),
            "lower_2sigma": float(m - 2 * s),
            "upper_2sigma": float(m + 2 * s),
        }
        for label, m, s in zip(OUTPUT_LABELS, mean, std, strict=True)
    ]
    note = None
    p_high = float(model.high_mode_probability(pose)[0]) if mode_switch else None
    if p_high is not None and 0.2 < p_high < 0.8:
        note = (
            f"P(~63 Hz X mode dominant) = {p_high:.2f}: the data cannot tell which X mode dominates "
            "here; the X values are those of the more probable mode"
        )
    elif p_high is None and mean[0] - 2 * std[0] < X_HIGH_MODE_THRESHOLD_HZ < mean[0] + 2 * std[0]:
        note = "the X band straddles the 16-23 Hz / ~63 Hz mode switch: the dominant X mode is uncertain here"
    if json_out:
        _emit_json(
            {
                "pose": {"x_mm": x, "y_mm": y, "z_mm": 325.0, "rz_deg": rz},
                "extrapolation": outside,
                "x_high_mode_probability": p_high,
                "note": note,
                "predictions": records,
            }
        )
        return
    con = _console()
    t = Table(title=f"GPR prediction at X={x:g} mm, Y={y:g} mm, Rz={rz:g}° (Z=325 mm)")
    for col in ("output", "mean", "± 2σ", "range (2σ)"):
        t.add_column(col, justify="right")
    for r in records:
        t.add_row(
            escape(r["output"]),
            f"{r['mean']:.3f}",
            f"{2 * r['std']:.3f}",
            escape(f"[{r['lower_2sigma']:.3f}, {r['upper_2sigma']:.3f}]"),
        )
    con.print(t)
    if outside:
        con.print(
            f"[yellow]warning:[/] {', '.join(outside)} outside the calibrated workspace: extrapolation"
        )
    if note:
        con.print(f"[yellow]note:[/] {note}")


frf_app = typer.Typer(help="FRFs from impact-hammer recordings (thesis §3.2.1).")
modal_app = typer.Typer(help="Modal parameters from FRFs.")
app.add_typer(frf_app, name="frf")
app.add_typer(modal_app, name="modal")


def _fail(message: str) -> None:
    typer.echo(f"error: {message}", err=True)
    raise typer.Exit(code=2)


@frf_app.command("compute")
def frf_compute(
    recording: Annotated[
        Path, typer.Argument(help="Hammer recording: .csv or .uff/.unv (dataset 58 time records).")
    ],
    output: Annotated[Path, typer.Option("-o", "--output", help="FRF file to write: .h5 or .uff.")],
    direction: Annotated[
        str | None, typer.Option(help="Excitation/response direction x, y or z (robot base frame).")
    ] = None,
    estimator: Annotated[
        str, typer.Option(help="H1 (noise on the response) or H2 (noise on the force).")
    ] = "H1",
    pretrigger_ms: Annotated[
        float, typer.Option(help="Pre-trigger kept before each hit [ms].")
    ] = 10.0,
    force_window_ms: Annotated[
        float, typer.Option(help="Force window after the trigger [ms]; 0 = none.")
    ] = 10.0,
    exp_window_tau_ms: Annotated[
        float,
        typer.Option(help="Exponential window time constant [ms] on both channels; 0 = none."),
    ] = 0.0,
    f_max_hz: Annotated[
        float, typer.Option("--fmax", help="Highest frequency kept [Hz] (<= Nyquist).")
    ] = 200.0,
    f_min_hz: Annotated[
        float,
        typer.Option(
            "--fmin",
            help="Lowest frequency kept [Hz] (compliance = accelerance / -w^2 blows up at 0).",
        ),
    ] = 2.0,
    keep_flagged: Annotated[
        bool, typer.Option(help="Keep hits flagged for double hits or overload (default: reject).")
    ] = False,
    path_s: Annotated[
        float | None,
        typer.Option(
            help="Pose as distance along a tool path [m], stored with the FRF (hybrid model)."
        ),
    ] = None,
    force_sensitivity: Annotated[
        float | None, typer.Option(help="Hammer sensitivity [mV/N] for a force channel in V or mV.")
    ] = None,
    response_sensitivity: Annotated[
        float | None,
        typer.Option(
            help="Response sensor sensitivity [mV per --response-unit] for a channel in V or mV."
        ),
    ] = None,
    response_unit: Annotated[
        str, typer.Option(help="Unit of the response sensitivity (g, m/s^2, m/s, m).")
    ] = "g",
    json_out: JsonFlag = False,
) -> None:
    """Averaged compliance FRF of a hammer recording, with per-hit quality control."""
    from .frf import impact_frf
    from .io import read_recording, write_frfs

    if direction is not None and direction not in ("x", "y", "z"):
        _fail(f"unknown direction {direction!r}; use x, y or z")
    try:
        from .io import Sensitivity

        rec = read_recording(
            recording, direction,
            Sensitivity(force_sensitivity, "N") if force_sensitivity else None,
            Sensitivity(response_sensitivity, response_unit) if response_sensitivity else None,
        )  # fmt: skip
        result = impact_frf(
            rec.forces, rec.responses, rec.sample_rate_hz,
            response_quantity=rec.response_quantity, estimator=estimator,
            pretrigger_s=pretrigger_ms / 1e3,
            force_window_s=force_window_ms / 1e3 if force_window_ms > 0 else None,
            exp_window_tau_s=exp_window_tau_ms / 1e3 if exp_window_tau_ms > 0 else None,
            reject=not keep_flagged, f_max_hz=f_max_hz, direction=rec.direction, pose=rec.pose,
        )  # fmt: skip
        frf = result.frf.to_compliance(f_min_hz)
        if path_s is not None:
            from dataclasses import replace

            frf = replace(frf, meta={**frf.meta, "path_s_m": float(path_s)})
        write_frfs(output, [frf])
    except (ValueError, OSError) as exc:
        _fail(str(exc))
    hits = [
        {
            "hit": h.index,
            "accepted": h.accepted,
            "peak_force_n": h.peak_force_n,
            "pulse_width_ms": 1e3 * h.pulse_width_s,
            "reasons": list(h.reasons),
        }
        for h in result.hits
    ]
    summary = {
        "recording": str(recording),
        "output": str(output),
        "sample_rate_hz": rec.sample_rate_hz,
        "response_quantity": rec.response_quantity,
        "direction": frf.direction,
        "n_hits": rec.n_hits,
        "n_averaged": frf.n_averages,
        "frequency_range_hz": [float(frf.frequency_hz[0]), float(frf.frequency_hz[-1])],
        "df_hz": frf.df_hz,
        "mean_coherence": float(np.mean(frf.coherence)),
        "hits": hits,
    }
    if json_out:
        _emit_json(summary)
        return
    con = _console()
    t = Table(
        title=f"Hits of {recording.name} ({rec.sample_rate_hz:g} Hz, {rec.response_quantity})"
    )
    for col in ("hit", "accepted", "peak force [N]", "pulse [ms]", "flags"):
        t.add_column(col, justify="right")
    for h in hits:
        t.add_row(
            str(h["hit"]),
            "yes" if h["accepted"] else "[red]no[/]",
            f"{h['peak_force_n']:.1f}",
            f"{h['pulse_width_ms']:.2f}",
            escape("; ".join(h["reasons"])),
        )
    con.print(t)
    con.print(
        f"wrote {output}: compliance FRF, {frf.frequency_hz[0]:g}-{frf.frequency_hz[-1]:g} Hz, "
        f"df = {frf.df_hz:.3g} Hz, {frf.n_averages} hits averaged, mean coherence {summary['mean_coherence']:.3f}"
    )


@modal_app.command("fit")
def modal_fit(
    frf_file: Annotated[Path, typer.Argument(help="FRF file (.h5 or .uff).")],
    band: Annotated[
        tuple[float, float] | None,
        typer.Option(help="Fit band LO HI [Hz]; default: around the dominant peak."),
    ] = None,
    modes: Annotated[
        bool, typer.Option("--modes", help="Also identify all modes in the band (LSCF + LSFD).")
    ] = False,
    max_order: Annotated[int, typer.Option(help="Highest LSCF model order for --modes.")] = 30,
    plot: Annotated[
        Path | None,
        typer.Option(help="PNG of magnitude, phase and coherence with the fitted curve."),
    ] = None,
    json_out: JsonFlag = False,
) -> None:
    """Dominant-mode fit (fn, k, c, zeta with standard errors) of every FRF in a file."""
    from .io import read_frfs
    from .modal import fit_dominant_mode, fit_modes

    try:
        frfs = read_frfs(frf_file)
    except (ValueError, OSError) as exc:
        _fail(str(exc))
    results = []
    for i, frf in enumerate(frfs):
        try:
            dom = fit_dominant_mode(frf, band)
            multi = fit_modes(frf, band, max_order=max_order) if modes else None
        except (ValueError, RuntimeError) as exc:
            _fail(f"FRF {i}: {exc}")
        results.append((frf, dom, multi))
    if plot is not None:
        from .modal.plot import plot_frf_fit

        frf, dom, multi = results[0]
        shown = frf.band(*dom.band_hz) if multi is None else frf.band(*multi.band_hz)
        fitted = multi.modes if multi is not None else (dom.parameters,)
        plot_frf_fit(
            shown,
            fitted,
            plot,
            residual=0j if multi else dom.residual_compliance,
            title=f"{frf_file.name}, FRF 0",
        )
    docs = []
    for i, (frf, dom, multi) in enumerate(results):
        doc = {
            "index": i,
            "direction": frf.direction,
            "pose": frf.pose,
            "dominant_mode": dom.to_dict(),
        }
        if multi is not None:
            doc["modes"] = [m.to_dict() for m in multi.modes]
        docs.append(doc)
    if json_out:
        _emit_json({"file": str(frf_file), "frfs": docs})
        return
    con = _console()
    t = Table(title=f"Dominant mode of each FRF in {frf_file.name}")
    for col in ("FRF", "dir", "fn [Hz]", "k [MN/m]", "c [kN·s/m]", "zeta [%]", "band [Hz]"):
        t.add_column(escape(col), justify="right")
    for i, (frf, dom, _) in enumerate(results):
        p, sd = dom.parameters, dom.std
        t.add_row(
            str(i), frf.direction or "-",
            f"{p.natural_frequency_hz:.3f} ± {sd['natural_frequency_hz']:.3f}",
            f"{p.stiffness_n_per_m / 1e6:.4f} ± {sd['stiffness_n_per_m'] / 1e6:.4f}",
            f"{p.damping_ns_per_m / 1e3:.3f} ± {sd['damping_ns_per_m'] / 1e3:.3f}",
            f"{100 * p.damping_ratio:.2f} ± {100 * sd['damping_ratio']:.2f}",
            f"{dom.band_hz[0]:.1f}-{dom.band_hz[1]:.1f}",
        )  # fmt: skip
    con.print(t)
    for i, (_, _, multi) in enumerate(results):
        if multi is None:
            continue
        t = Table(
            title=f"FRF {i}: modes in {multi.band_hz[0]:.1f}-{multi.band_hz[1]:.1f} Hz (LSCF + LSFD)"
        )
        for col in ("mode", "fn [Hz]", "k [MN/m]", "zeta [%]"):
            t.add_column(escape(col), justify="right")
        for j, m in enumerate(multi.modes):
            t.add_row(
                str(j + 1),
                f"{m.natural_frequency_hz:.3f}",
                f"{m.stiffness_n_per_m / 1e6:.4f}",
                f"{100 * m.damping_ratio:.2f}",
            )
        con.print(t)
    if plot is not None:
        con.print(f"wrote {plot}")


sim_app = typer.Typer(
    help="The virtual robot: synthetic hammer tests, milling passes and offset-mass runs."
)
app.add_typer(sim_app, name="sim")
OutOpt = Annotated[Path, typer.Option("-o", "--output", help="File to write.")]


def _materials():
    from .milling import ACETAL, ALUMINIUM_7075

    return {"al7075": ALUMINIUM_7075, "acetal": ACETAL}


@sim_app.command("hammer")
def sim_hammer(
    output: OutOpt,
    x: Annotated[
        float, typer.Option("--x", help="Tool-tip X [mm] (workspace 2100-2700).")
    ] = 2400.0,
    y: Annotated[float, typer.Option("--y", help="Tool-tip Y [mm] (workspace -300-600).")] = 0.0,
    rz: Annotated[
        float, typer.Option("--rz", help="Rotation about the tool axis [deg] (0-180).")
    ] = 45.0,
    direction: Annotated[str, typer.Option(help="Hit and response direction x, y or z.")] = "x",
    hits: Annotated[int, typer.Option(help="Number of hits.")] = 5,
    sample_rate_hz: Annotated[
        float, typer.Option(help="Accelerometer/hammer sample rate [Hz].")
    ] = 17066.0,
    duration_s: Annotated[float, typer.Option(help="Record length per hit [s].")] = 4.0,
    snr_db: Annotated[float, typer.Option(help="Response signal-to-noise ratio [dB].")] = 40.0,
    path_s: Annotated[
        float | None,
        typer.Option(
            help="Test on the chapter-4 path instead: distance from its start [m] (0-1.235)."
        ),
    ] = None,
    seed: SeedOpt = 0,
    json_out: JsonFlag = False,
) -> None:
    """Impact-hammer test of the virtual robot at a workspace pose (or a path point), UFF 58 or CSV."""
    from .io import write_recording_uff
    from .sim import VirtualRobot, simulate_hammer_test

    try:
        where, domain = (
            ((x / 1e3, y / 1e3, rz), "workspace") if path_s is None else (path_s, "path")
        )
        rec = simulate_hammer_test(
            VirtualRobot(), where, direction, domain=domain, n_hits=hits,
            sample_rate_hz=sample_rate_hz, duration_s=duration_s, snr_db=snr_db, rng=seed,
        )  # fmt: skip
        if output.suffix.lower() in (".uff", ".unv"):
            write_recording_uff(output, rec)
        elif output.suffix.lower() == ".csv":
            _write_recording_csv(output, rec)
        else:
            _fail(f"unknown output format {output.suffix!r}; use .uff or .csv")
    except ValueError as exc:
        _fail(str(exc))
    doc = {"output": str(output), "pose_mm_deg": [x, y, 325.0, 0.0, 0.0, rz], "direction": direction,
           "hits": rec.n_hits, "sample_rate_hz": rec.sample_rate_hz, "samples_per_hit": int(rec.forces.shape[1])}  # fmt: skip
    if json_out:
        _emit_json(doc)
    else:
        typer.echo(
            f"wrote {output}: {rec.n_hits} hits, {rec.forces.shape[1]} samples at {rec.sample_rate_hz:g} Hz, direction {direction}"
        )


def _write_recording_csv(path: Path, rec) -> None:
    n = rec.forces.shape[1]
    t = np.arange(n) / rec.sample_rate_hz
    unit = {"acceleration": "m_per_s2", "velocity": "m_per_s", "displacement": "m"}[
        rec.response_quantity
    ]
    with path.open("w") as fh:
        fh.write(f"hit,time_s,force_n,{rec.response_quantity}_{unit}\n")
        for h in range(rec.n_hits):
            for i in range(n):
                fh.write(f"{h},{t[i]:.9g},{rec.forces[h, i]:.9g},{rec.responses[h, i]:.9g}\n")


@sim_app.command("mill")
def sim_mill(
    output: OutOpt,
    x0: Annotated[float, typer.Option(help="Start X [mm].")] = 2100.0,
    y0: Annotated[float, typer.Option(help="Start Y [mm].")] = 0.0,
    x1: Annotated[float, typer.Option(help="End X [mm].")] = 2700.0,
    y1: Annotated[float, typer.Option(help="End Y [mm].")] = 0.0,
    rz: Annotated[float, typer.Option("--rz", help="Rotation about the tool axis [deg].")] = 0.0,
    rpm: Annotated[float, typer.Option(help="Spindle speed [rpm].")] = 1750.0,
    fz_mm: Annotated[float, typer.Option("--fz", help="Feed per tooth [mm].")] = 0.058,
    ap_mm: Annotated[float, typer.Option("--ap", help="Axial depth of cut [mm].")] = 3.0,
    ae_mm: Annotated[
        float, typer.Option("--ae", help="Radial depth of cut [mm] (25.4 = slotting).")
    ] = 25.4,
    material: Annotated[
        str, typer.Option(help="Cutting-coefficient preset: al7075 or acetal.")
    ] = "al7075",
    path: Annotated[
        tuple[float, float] | None,
        typer.Option(
            help="Cut along the chapter-4 path instead: START END distances [m] (0-1.235)."
        ),
    ] = None,
    background: Annotated[
        float, typer.Option(help="Broadband force content (x spread of the periodic force).")
    ] = 0.15,
    seed: SeedOpt = 0,
    json_out: JsonFlag = False,
) -> None:
    """Milling pass on the virtual robot (thesis §3.5: 25.4 mm 2-flute 30° helix tool); CSV out."""
    from .milling import CuttingConditions, MillingTool
    from .sim import LinearMove, VirtualRobot, simulate_milling

    mats = _materials()
    if material not in mats:
        _fail(f"unknown material {material!r}; use one of {', '.join(mats)}")
    try:
        cond = CuttingConditions(rpm, fz_mm / 1e3, ap_mm / 1e3, ae_mm / 1e3)
        if path is None:
            move = LinearMove("workspace", (x0 / 1e3, y0 / 1e3, rz), (x1 / 1e3, y1 / 1e3, rz))
        else:
            move = LinearMove("path", (path[0],), (path[1],))
        run = simulate_milling(
            VirtualRobot(),
            move,
            MillingTool(),
            cond,
            mats[material],
            background_noise_rel=background,
            rng=seed,
        )
        run.to_csv(output)
    except ValueError as exc:
        _fail(str(exc))
    doc = {
        "output": str(output), "samples": int(run.time_s.size), "duration_s": float(run.time_s[-1]),
        "mean_force_n": run.force_n.mean(axis=0), "mean_deflection_mm": 1e3 * run.true_displacement_m.mean(axis=0),
        **run.meta,
    }  # fmt: skip
    if json_out:
        _emit_json(doc)
    else:
        typer.echo(
            f"wrote {output}: {run.time_s.size} samples over {run.time_s[-1]:.1f} s; mean deflection "
            f"X/Y/Z = {', '.join(f'{v:.3f}' for v in doc['mean_deflection_mm'])} mm"
        )


@sim_app.command("offset-mass")
def sim_offset_mass(
    output: OutOpt,
    rpm: Annotated[
        float, typer.Option(help="Spindle speed [rpm] (thesis: 480, 960, 1440).")
    ] = 480.0,
    s_start: Annotated[
        float,
        typer.Option(help="Start on the chapter-4 path [m] (0 = retracted, 1.235 = extended)."),
    ] = 1.235,
    s_end: Annotated[float, typer.Option(help="End on the chapter-4 path [m].")] = 0.335,
    speed_mm_s: Annotated[
        float, typer.Option("--speed", help="Robot speed along the path [mm/s].")
    ] = 84.0,
    seed: SeedOpt = 0,
    json_out: JsonFlag = False,
) -> None:
    """Rotating offset-mass run (1 kg at 50.8 mm, thesis §4.3.3) along the chapter-4 path; CSV out."""
    from .sim import LinearMove, VirtualRobot, simulate_offset_mass

    try:
        run = simulate_offset_mass(
            VirtualRobot(),
            LinearMove("path", (s_start,), (s_end,)),
            rpm,
            speed_m_per_s=speed_mm_s / 1e3,
            rng=seed,
        )
        run.to_csv(output)
    except ValueError as exc:
        _fail(str(exc))
    amp = 1e3 * np.abs(run.true_displacement_m).max(axis=0)
    doc = {"output": str(output), "samples": int(run.time_s.size), "peak_vibration_mm": amp}
    if json_out:
        _emit_json(doc)
    else:
        typer.echo(
            f"wrote {output}: {run.time_s.size} samples; peak vibration X/Y = {amp[0]:.3f}/{amp[1]:.3f} mm"
        )


robot_app = typer.Typer(
    help="Analytical KR500-3 model: kinematics, stiffness, mass, eigenfrequencies (thesis §3.4)."
)
app.add_typer(robot_app, name="robot")


@robot_app.command("fk")
def robot_fk(
    joints: Annotated[
        tuple[float, float, float, float, float, float],
        typer.Option(help="KUKA joint angles A1..A6 [deg]."),
    ],
    json_out: JsonFlag = False,
) -> None:
    """Tool-tip and flange position [mm] and orientation of given joint angles."""
    from .robot import KR500

    robot = KR500()
    try:
        tip, flange = robot.fk(joints), robot.fk(joints, flange=True)
        cond = robot.condition_number(joints)
    except ValueError as exc:
        _fail(str(exc))
    doc = {"joints_deg": list(joints), "tool_tip_mm": tip[:3, 3] * 1e3, "flange_mm": flange[:3, 3] * 1e3,
           "rotation": tip[:3, :3], "jacobian_condition_number": cond}  # fmt: skip
    if json_out:
        _emit_json(doc)
    else:
        typer.echo(
            f"tool tip [mm]: {np.round(doc['tool_tip_mm'], 2).tolist()}   flange [mm]: {np.round(doc['flange_mm'], 2).tolist()}"
        )
        typer.echo(f"Jacobian condition number: {cond:.3g}")


def _workspace_pose(x, y, z, rz):
    from .robot import KR500, tool_down_orientation

    robot = KR500()
    q = robot.ik(np.array([x, y, z]) / 1e3, tool_down_orientation(rz))
    return robot, q


@robot_app.command("ik")
def robot_ik(
    x: Annotated[float, typer.Option("--x", help="Tool-tip X [mm].")],
    y: Annotated[float, typer.Option("--y", help="Tool-tip Y [mm].")],
    z: Annotated[float, typer.Option("--z", help="Tool-tip Z [mm].")] = 325.0,
    rz: Annotated[
        float, typer.Option("--rz", help="Rotation about the (downward) tool axis [deg].")
    ] = 0.0,
    json_out: JsonFlag = False,
) -> None:
    """Joint angles for a tool-tip pose with the tool axis pointing down (chapter-3 convention)."""
    try:
        robot, q = _workspace_pose(x, y, z, rz)
    except ValueError as exc:
        _fail(str(exc))
    doc = {"joints_deg": q, "jacobian_condition_number": robot.condition_number(q)}
    if json_out:
        _emit_json(doc)
    else:
        typer.echo(
            f"A1..A6 [deg]: {np.round(q, 3).tolist()}   (condition number {doc['jacobian_condition_number']:.3g})"
        )


@robot_app.command("stiffness")
def robot_stiffness(
    x: Annotated[float, typer.Option("--x", help="Tool-tip X [mm].")],
    y: Annotated[float, typer.Option("--y", help="Tool-tip Y [mm].")],
    z: Annotated[float, typer.Option("--z", help="Tool-tip Z [mm].")] = 325.0,
    rz: Annotated[float, typer.Option("--rz", help="Rotation about the tool axis [deg].")] = 0.0,
    json_out: JsonFlag = False,
) -> None:
    """Analytical stiffness (Table 4 joint stiffness), principal directions and eigenfrequencies."""
    from .robot.dynamics import cartesian_modes, cartesian_stiffness

    try:
        robot, q = _workspace_pose(x, y, z, rz)
        k = cartesian_stiffness(robot, q)
        modes = cartesian_modes(robot, q)
    except ValueError as exc:
        _fail(str(exc))
    kt_vals, kt_vecs = np.linalg.eigh(modes.stiffness_n_per_m)
    doc = {
        "joints_deg": q,
        "directional_stiffness_n_per_m": dict(
            zip("xyz", modes.directional_stiffness(), strict=True)
        ),
        "translational_principal_stiffness_n_per_m": kt_vals,
        "principal_directions": kt_vecs,
        "natural_frequencies_hz": modes.natural_frequencies_hz,
        "mode_directions": modes.directions,
        "cartesian_stiffness_6x6": k,
    }
    if json_out:
        _emit_json(doc)
        return
    typer.echo(
        "directional stiffness [MN/m]: "
        + ", ".join(
            f"{d.upper()} {v / 1e6:.3f}" for d, v in doc["directional_stiffness_n_per_m"].items()
        )
    )
    for f, u in zip(modes.natural_frequencies_hz, modes.directions.T, strict=True):
        typer.echo(f"mode {f:7.2f} Hz  direction {np.round(u, 3).tolist()}")


@robot_app.command("identify")
def robot_identify(
    tests: Annotated[
        Path,
        typer.Argument(
            help="CSV: a1_deg..a6_deg, fx_n, fy_n, fz_n, mx_nm, my_nm, mz_nm, dx_m, dy_m, dz_m[, rx_rad, ry_rad, rz_rad]."
        ),
    ],
    json_out: JsonFlag = False,
) -> None:
    """Joint stiffnesses from compliance tests (thesis Eq. 12, Table 3/4 procedure)."""
    import pandas as pd

    from .robot import KR500
    from .robot.dynamics import TABLE_4_JOINT_STIFFNESS, identify_joint_stiffness

    try:
        df = pd.read_csv(tests)
        j = df[[f"a{i}_deg" for i in range(1, 7)]].to_numpy()
        w = df[["fx_n", "fy_n", "fz_n", "mx_nm", "my_nm", "mz_nm"]].to_numpy()
        dcols = ["dx_m", "dy_m", "dz_m"] + (
            ["rx_rad", "ry_rad", "rz_rad"] if "rx_rad" in df else []
        )
        k = identify_joint_stiffness(KR500(), j, w, df[dcols].to_numpy())
    except KeyError as exc:
        _fail(f"{tests}: missing column {exc}")
    except (ValueError, OSError) as exc:
        _fail(str(exc))
    doc = {
        "joint_stiffness_n_m_per_rad": k,
        "table_4_n_m_per_rad": TABLE_4_JOINT_STIFFNESS,
        "n_tests": len(df),
    }
    if json_out:
        _emit_json(doc)
    else:
        for i, (ki, ti) in enumerate(zip(k, TABLE_4_JOINT_STIFFNESS, strict=True)):
            typer.echo(f"A{i + 1}: {ki / 1e6:.3f} x 1e6 N m/rad   (thesis Table 4: {ti / 1e6:.2f})")


@robot_app.command("compare")
def robot_compare(
    plot: Annotated[
        Path | None, typer.Option(help="PNG of relative errors vs arm extension (thesis Fig. 11).")
    ] = None,
    gp_inputs: Annotated[
        bool,
        typer.Option(
            "--gp-inputs", help="Also compare GP inputs: Cartesian vs joint angles on Table A2."
        ),
    ] = False,
    json_out: JsonFlag = False,
) -> None:
    """Analytical model vs Table A1 measurements: relative errors of fn and stiffness per direction."""
    from .studies.analytical import compare_with_table_a1, gp_input_comparison, plot_comparison

    table = compare_with_table_a1().to_frame()
    summary = {}
    for d in "xyz":
        for q in ("fn", "stiffness"):
            e = table[f"{q}_{d}_rel_error"]
            summary[f"{q}_{d}"] = {
                "mean_rel_error": float(e.mean()),
                "min": float(e.min()),
                "max": float(e.max()),
            }
    gp = gp_input_comparison().to_frame() if gp_inputs else None
    if plot is not None:
        plot_comparison(table, plot)
    if json_out:
        doc = {"summary": summary, "poses": table.to_dict(orient="records")}
        if gp is not None:
            doc["gp_inputs"] = gp.to_dict(orient="records")
        _emit_json(doc)
        return
    con = _console()
    t = Table(
        title="Analytical (Table 4 joint stiffness, solid links) vs measured (Table A1 means)"
    )
    for col in ("quantity", "mean error", "min", "max"):
        t.add_column(col, justify="right")
    for key, v in summary.items():
        t.add_row(
            key,
            f"{100 * v['mean_rel_error']:+.0f} %",
            f"{100 * v['min']:+.0f} %",
            f"{100 * v['max']:+.0f} %",
        )
    con.print(t)
    if gp is not None:
        piv = gp.pivot(index="output", columns="inputs", values="mean_relative_error")
        t = Table(title="GP external validation on Table A2: mean relative error by input set")
        t.add_column("output")
        for c in piv.columns:
            t.add_column(escape(c), justify="right")
        for out, row in piv.iterrows():
            t.add_row(out, *[f"{100 * v:.1f} %" for v in row])
        con.print(t)
    if plot is not None:
        con.print(f"wrote {plot}")


mill_app = typer.Typer(help="Milling vibration and chatter stability at a pose (thesis §3.5).")
app.add_typer(mill_app, name="mill")
RpmOpt = Annotated[float, typer.Option(help="Spindle speed [rpm].")]
FzOpt = Annotated[float, typer.Option("--fz", help="Feed per tooth [mm].")]
ApOpt = Annotated[float, typer.Option("--ap", help="Axial depth of cut [mm].")]
AeOpt = Annotated[
    float,
    typer.Option("--ae", help="Radial depth of cut [mm] (25.4 = slotting with the 25.4 mm tool)."),
]
MaterialOpt = Annotated[str, typer.Option(help="Cutting-coefficient preset: al7075 or acetal.")]
FeedOpt = Annotated[str, typer.Option(help="Feed direction in the base frame: x or y.")]


def _material(name: str):
    mats = _materials()
    if name not in mats:
        _fail(f"unknown material {name!r}; use one of {', '.join(mats)}")
    return mats[name]


def _read_force_file(path: Path, sample_rate_hz: float) -> np.ndarray:
    import pandas as pd

    from .milling.prediction import resample_force

    df = pd.read_csv(path)
    cols = ["force_x_n", "force_y_n", "force_z_n"]
    if "time_s" not in df or any(c not in df for c in cols):
        raise ValueError(f"{path}: need columns time_s, {', '.join(cols)}")
    data = df[cols].to_numpy()
    if not np.all(np.isfinite(data)):
        raise ValueError(f"{path}: force columns contain NaN or inf")
    return resample_force(df["time_s"].to_numpy(), data, sample_rate_hz)


@mill_app.command("predict")
def mill_predict(
    x: Annotated[float, typer.Option("--x", help="Tool-tip X [mm].")],
    y: Annotated[float, typer.Option("--y", help="Tool-tip Y [mm].")],
    rz: Annotated[float, typer.Option("--rz", help="Rotation about the tool axis [deg].")],
    rpm: RpmOpt = 1750.0,
    fz: FzOpt = 0.058,
    ap: ApOpt = 3.0,
    ae: AeOpt = 25.4,
    material: MaterialOpt = "al7075",
    feed: FeedOpt = "x",
    forces: Annotated[
        Path | None,
        typer.Option(
            help="Measured forces CSV (time_s, force_x_n, force_y_n, force_z_n), any rate."
        ),
    ] = None,
    samples: Annotated[
        int, typer.Option(help="Monte-Carlo draws of the GP prediction for the band.")
    ] = 50,
    seed: SeedOpt = 0,
    json_out: JsonFlag = False,
) -> None:
    """Mean deflection and peak-to-valley per revolution at a pose, with 95 % bands."""
    from .gp import fit_chapter3_model
    from .milling import CuttingConditions
    from .milling.workflow import predict_at_pose

    try:
        cond = CuttingConditions(rpm, fz / 1e3, ap / 1e3, ae / 1e3)
        f = _read_force_file(forces, 1000.0) if forces is not None else None
        res = predict_at_pose(
            fit_chapter3_model(rng=seed), x, y, rz, cond, coefficients=_material(material),
            forces_n=f, feed_direction=feed, n_samples=samples, rng=seed,
        )  # fmt: skip
    except (ValueError, OSError) as exc:
        _fail(str(exc))
    rows = [
        {"direction": r.direction, "mean_deflection_mm": 1e3 * r.mean_deflection_m,
         "mean_deflection_band_mm": [1e3 * v for v in r.mean_deflection_band_m],
         "peak_to_valley_mm": 1e3 * r.peak_to_valley_m,
         "peak_to_valley_band_mm": [1e3 * v for v in r.peak_to_valley_band_m],
         "mode": r.mode.to_dict()}
        for r in res
    ]  # fmt: skip
    if json_out:
        _emit_json(
            {"pose_mm_deg": [x, y, 325.0, 0, 0, rz], "spindle_rpm": rpm, "predictions": rows}
        )
        return
    con = _console()
    t = Table(
        title=f"Milling vibration at X={x:g}, Y={y:g} mm, Rz={rz:g}° ({rpm:g} rpm, fz {fz} mm, ap {ap} mm, ae {ae} mm)"
    )
    for col in (
        "dir",
        "mode fn [Hz]",
        "mean deflection [mm]",
        "95 % band",
        "P-V / rev [mm]",
        "95 % band",
    ):
        t.add_column(col, justify="right")
    for r in rows:
        t.add_row(
            r["direction"].upper(), f"{r['mode']['natural_frequency_hz']:.2f}", f"{r['mean_deflection_mm']:.4f}",
            escape(f"[{r['mean_deflection_band_mm'][0]:.4f}, {r['mean_deflection_band_mm'][1]:.4f}]"),
            f"{r['peak_to_valley_mm']:.4f}", escape(f"[{r['peak_to_valley_band_mm'][0]:.4f}, {r['peak_to_valley_band_mm'][1]:.4f}]"),
        )  # fmt: skip
    con.print(t)


@mill_app.command("lobes")
def mill_lobes(
    x: Annotated[float, typer.Option("--x", help="Tool-tip X [mm].")],
    y: Annotated[float, typer.Option("--y", help="Tool-tip Y [mm].")],
    rz: Annotated[float, typer.Option("--rz", help="Rotation about the tool axis [deg].")],
    ae: AeOpt = 6.0,
    material: MaterialOpt = "al7075",
    feed: FeedOpt = "x",
    rpm_min: Annotated[float, typer.Option(help="Lowest speed of the plot [rpm].")] = 100.0,
    rpm_max: Annotated[float, typer.Option(help="Highest speed of the plot [rpm].")] = 3000.0,
    plot: Annotated[Path | None, typer.Option(help="PNG of the lobes.")] = None,
    seed: SeedOpt = 0,
    json_out: JsonFlag = False,
) -> None:
    """Stability lobes (zero-order method) from the pose's predicted X/Y modes."""
    from .gp import fit_chapter3_model
    from .milling import CuttingConditions, MillingTool
    from .milling.stability import stability_lobes
    from .milling.workflow import pose_modes

    try:
        pose = pose_modes(fit_chapter3_model(rng=seed), (x, y, rz))
        modes = {d: m.parameters for d, m in pose.items()}
        cond = CuttingConditions(1000.0, 1e-4, 1e-3, ae / 1e3)
        feed_dir, normal = ("x", "y") if feed == "x" else ("y", "x")
        lobes = stability_lobes(
            [modes[feed_dir]], [modes[normal]], MillingTool(), cond, _material(material), n_lobes=40
        )
    except ValueError as exc:
        _fail(str(exc))
    speeds = np.linspace(rpm_min, rpm_max, 200)
    crit = lobes.critical_depth(speeds)
    if plot is not None:
        lobes.plot(path=plot, rpm_range=(rpm_min, rpm_max))
    doc = {
        "minimum_critical_depth_mm": 1e3 * lobes.minimum_depth_m,
        "spindle_rpm": speeds,
        "critical_depth_mm": 1e3 * crit,
    }
    if json_out:
        _emit_json(doc)
    else:
        typer.echo(
            f"minimum critical axial depth (all speeds): {doc['minimum_critical_depth_mm']:.3f} mm"
        )
        best = int(np.argmax(crit))
        typer.echo(
            f"most stable speed in {rpm_min:g}-{rpm_max:g} rpm: {speeds[best]:.0f} rpm ({1e3 * crit[best]:.2f} mm)"
        )
        if plot is not None:
            typer.echo(f"wrote {plot}")


@mill_app.command("map")
def mill_map(
    rz: Annotated[float, typer.Option("--rz", help="Rotation about the tool axis [deg].")] = 0.0,
    rpm: RpmOpt = 1750.0,
    ae: AeOpt = 6.0,
    material: MaterialOpt = "al7075",
    feed: FeedOpt = "x",
    nx: Annotated[int, typer.Option(help="Grid points in X.")] = 13,
    ny: Annotated[int, typer.Option(help="Grid points in Y.")] = 10,
    plot: Annotated[Path | None, typer.Option(help="PNG heat map over X-Y.")] = None,
    seed: SeedOpt = 0,
    json_out: JsonFlag = False,
) -> None:
    """Critical axial depth at a spindle speed over the workspace: where to mill."""
    from rich.progress import Progress

    from .gp import fit_chapter3_model
    from .milling import CuttingConditions, MillingTool
    from .milling.workflow import workspace_lobe_map

    xs, ys = np.linspace(2100, 2700, nx), np.linspace(-300, 600, ny)
    model = fit_chapter3_model(rng=seed)
    try:
        cond = CuttingConditions(rpm, 1e-4, 1e-3, ae / 1e3)
        with Progress(transient=True, disable=json_out) as bar:
            task = bar.add_task("lobes over the workspace", total=nx * ny)
            grid = workspace_lobe_map(model, rz, MillingTool(), cond, _material(material), x_mm=xs, y_mm=ys,
                                      feed_direction=feed, progress=lambda done, total: bar.update(task, completed=done))  # fmt: skip
    except ValueError as exc:
        _fail(str(exc))
    if plot is not None:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots(figsize=(7, 5))
        im = ax.pcolormesh(
            xs, ys, np.minimum(grid, 10 * np.nanmin(grid)) * 1e3, shading="auto", cmap="viridis"
        )
        fig.colorbar(im, ax=ax, label="critical axial depth [mm]")
        ax.set_xlabel("X [mm]")
        ax.set_ylabel("Y [mm]")
        ax.set_title(f"critical depth at {rpm:g} rpm, Rz = {rz:g}°, ae = {ae:g} mm")
        fig.tight_layout()
        fig.savefig(plot, dpi=120)
        plt.close(fig)
    i, j = np.unravel_index(np.argmax(grid), grid.shape)
    doc = {
        "x_mm": xs,
        "y_mm": ys,
        "critical_depth_mm": grid * 1e3,
        "best_pose_mm": [xs[j], ys[i]],
        "best_depth_mm": 1e3 * grid[i, j],
    }
    if json_out:
        _emit_json(doc)
    else:
        typer.echo(
            f"deepest stable cut at X={xs[j]:.0f}, Y={ys[i]:.0f} mm: {1e3 * grid[i, j]:.2f} mm; shallowest: {1e3 * np.min(grid):.2f} mm"
        )
        if plot is not None:
            typer.echo(f"wrote {plot}")


control_app = typer.Typer(help="Pose-dependent LQR vibration control (thesis ch. 4).")
app.add_typer(control_app, name="control")


@control_app.command("gains")
def control_gains(
    x: Annotated[float, typer.Option("--x", help="Tool-tip X [mm].")],
    y: Annotated[float, typer.Option("--y", help="Tool-tip Y [mm].")],
    rz: Annotated[float, typer.Option("--rz", help="Rotation about the tool axis [deg].")],
    direction: Annotated[str, typer.Option(help="x, y or z.")] = "x",
    period_ms: Annotated[float, typer.Option(help="Command period [ms] (RSI: 4 ms).")] = 4.0,
    delay_ms: Annotated[float, typer.Option(help="Actuator delay [ms] (KRC4: 32 ms).")] = 32.0,
    r: Annotated[float, typer.Option("--r", help="Input weight R (Q = diag(1, 0.001)).")] = 0.001,
    json_out: JsonFlag = False,
) -> None:
    """LQR gains W = [w1, w2] at a pose from the GP's predicted mode, with the delay analysis."""
    from .control import delay_analysis, design_delay_aware_lqr, design_lqr, tune_r_for_delay
    from .gp import fit_chapter3_model
    from .milling.workflow import pose_modes

    if direction not in ("x", "y", "z"):
        _fail(f"unknown direction {direction!r}")
    try:
        pose = pose_modes(fit_chapter3_model(), (x, y, rz))
        modes = {d: m.parameters for d, m in pose.items()}
        mode = modes[direction]
        d = design_lqr(mode, period_ms / 1e3, r=[[r]])
        da = delay_analysis(d, delay_ms / 1e3)
        tuned, r_tuned = tune_r_for_delay(mode, period_ms / 1e3, delay_ms / 1e3)
        aware = design_delay_aware_lqr(mode, period_ms / 1e3, delay_ms / 1e3, r=[[1.0]])
        from .control import loop_margins

        margins = loop_margins(d, round(delay_ms / period_ms))
    except ValueError as exc:
        _fail(str(exc))
    doc = {
        "mode": mode.to_dict(), "w1": d.gains[0], "w2": d.gains[1], "spectral_radius_no_delay": d.spectral_radius,
        "stable_with_delay": da.stable, "spectral_radius_with_delay": da.spectral_radius,
        "max_stable_delay_ms": 1e3 * da.max_stable_delay_s,
        "delay_tuned": {"r": r_tuned, "w1": tuned.gains[0], "w2": tuned.gains[1]},
        "delay_aware": {"gains": aware.gains, "spectral_radius": aware.spectral_radius},
        "margins_with_delay": {"gain_margins": margins.gain_margins, "phase_crossovers_hz": margins.phase_crossovers_hz,
                               "phase_margins_deg": margins.phase_margins_deg, "gain_crossovers_hz": margins.gain_crossovers_hz},
    }  # fmt: skip
    if json_out:
        _emit_json(doc)
        return
    typer.echo(
        f"mode: fn {mode.natural_frequency_hz:.2f} Hz, k {mode.stiffness_n_per_m / 1e6:.3f} MN/m, zeta {mode.damping_ratio:.3f}"
    )
    typer.echo(f"W = [{d.gains[0]:.4g}, {d.gains[1]:.4g}] (R = {r:g}); with {delay_ms:g} ms delay: "
               f"{'stable' if da.stable else 'UNSTABLE'} (spectral radius {da.spectral_radius:.3f}, largest stable delay {1e3 * da.max_stable_delay_s:g} ms)")  # fmt: skip
    if not da.stable:
        typer.echo(
            f"best-damped R with the delay: {r_tuned:.3g} -> W = [{tuned.gains[0]:.4g}, {tuned.gains[1]:.4g}]"
        )
    if margins.gain_margins.size:
        typer.echo(
            f"gain margin with the delay: {margins.gain_margins[0]:.3g} at {margins.phase_crossovers_hz[0]:.2f} Hz"
        )
    typer.echo(f"delay-aware LQR (R = 1): spectral radius {aware.spectral_radius:.3f}")


@control_app.command("schedule")
def control_schedule(
    path: Annotated[
        Path | None,
        typer.Option(
            help="CSV of modes along a path: s_m, fn_hz, stiffness_n_per_m, damping_ratio. Default: virtual-robot EMA along the chapter-4 path."
        ),
    ] = None,
    direction: Annotated[
        str, typer.Option(help="Direction of the virtual-robot path model (x, y, z).")
    ] = "x",
    plot: Annotated[
        Path | None, typer.Option(help="PNG of w1, w2 vs path distance (thesis Fig. 23).")
    ] = None,
    seed: SeedOpt = 0,
    json_out: JsonFlag = False,
) -> None:
    """Gains along a path (R tuned for the 32 ms delay), with the Eq. 28-29 polynomial fits."""
    from .control.schedule import schedule_gains
    from .modal import ModalParameters

    warnings_seen: list[str] = []
    try:
        if path is not None:
            import pandas as pd

            df = pd.read_csv(path)
            need = ["s_m", "fn_hz", "stiffness_n_per_m", "damping_ratio"]
            missing = [c for c in need if c not in df]
            if missing:
                _fail(f"{path}: missing columns {missing}")
            s = df["s_m"].to_numpy()
            modes = [
                ModalParameters(r.fn_hz, r.stiffness_n_per_m, r.damping_ratio)
                for r in df.itertuples()
            ]
        else:
            from .control.studies import path_modal_model
            from .sim import VirtualRobot

            model = path_modal_model(VirtualRobot(), directions=(direction,), rng=seed)
            s = np.linspace(0.335, 1.235, 20)
            modes = [model.mode(si, direction) for si in s]
        sched = schedule_gains(s, modes, warn=warnings_seen.append)
    except ValueError as exc:
        _fail(str(exc))
    if plot is not None:
        sched.plot(plot)
    doc = {"s_m": sched.s_m, "w1": sched.w1, "w2": sched.w2, "r": sched.r, "stable_with_delay": sched.stable_with_delay,
           "w1_poly_high_to_low": sched.w1_poly, "w2_poly_high_to_low": sched.w2_poly, "warnings": warnings_seen}  # fmt: skip
    if json_out:
        _emit_json(doc)
        return
    for si, w1, w2 in zip(sched.s_m, sched.w1, sched.w2, strict=True):
        typer.echo(f"s = {si * 1e3:7.1f} mm   w1 = {w1:9.5f}   w2 = {w2:9.5f}")
    for w in warnings_seen:
        typer.echo(f"warning: {w}")
    if plot is not None:
        typer.echo(f"wrote {plot}")


@control_app.command("table9")
def control_table9(json_out: JsonFlag = False) -> None:
    """Gains from the thesis' Table 8 inputs under each plant formulation, beside Table 9."""
    from .studies.table9 import table_9_comparison

    rows = table_9_comparison().to_dict()["rows"]
    if json_out:
        _emit_json({"rows": rows})
        return
    con = _console()
    t = Table(
        title="LQR gains from Table 8 predictions (T = 4 ms, Q = diag(1, 0.001), R = 0.001) vs Table 9"
    )
    for col in ("formulation", "input", "pos", "dir", "w1", "thesis w1", "w2", "thesis w2"):
        t.add_column(col, justify="right")
    for r in rows:
        t.add_row(
            r["formulation"],
            r["input"],
            str(r["position"]),
            r["direction"],
            f"{r['w1']:.4g}",
            f"{r['thesis_w1']:.3g}",
            f"{r['w2']:.4g}",
            f"{r['thesis_w2']:.3g}",
        )
    con.print(t)


@control_app.command("simulate")
def control_simulate(
    experiment: Annotated[str, typer.Argument(help="offset-mass or milling.")],
    plot: Annotated[
        Path | None,
        typer.Option(help="PNG of the X vibration per controller (offset-mass, first speed)."),
    ] = None,
    seed: SeedOpt = 0,
    json_out: JsonFlag = False,
) -> None:
    """Closed-loop runs on the virtual robot: Table 7 (offset mass) or Table 10 (milling) analogue."""
    from rich.progress import Progress

    from .control.studies import milling_study, offset_mass_study, path_modal_model
    from .sim import VirtualRobot

    if experiment not in ("offset-mass", "milling"):
        _fail(f"unknown experiment {experiment!r}; use offset-mass or milling")
    robot = VirtualRobot()
    with Progress(transient=True, disable=json_out) as bar:
        task = bar.add_task("virtual EMA along the path + closed-loop runs", total=None)
        model = path_modal_model(robot, rng=seed)
        rows = (
            offset_mass_study(robot, model, rng=seed, keep_traces=plot is not None)
            if experiment == "offset-mass"
            else milling_study(robot, model, rng=seed)
        )
        bar.update(task, completed=1)
    traces = (
        [r.pop("trace_x_m") for r in rows if "trace_x_m" in r]
        if experiment == "offset-mass"
        else []
    )
    if plot is not None and experiment == "offset-mass":
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        first = rows[0]["speed_rpm"]
        fig, ax = plt.subplots(figsize=(9, 4))
        for r, x in zip([r for r in rows if r["unstable"] is None], traces, strict=True):
            if r["speed_rpm"] == first:
                ax.plot(np.arange(x.size) / 1000.0, 1e3 * x, lw=0.7, label=r["controller"])
        ax.set_xlabel("time [s] (robot moving from the extended end toward the base)")
        ax.set_ylabel("X vibration [mm]")
        ax.set_title(f"offset mass at {first:g} rpm on the virtual robot")
        ax.legend(fontsize=8)
        fig.tight_layout()
        fig.savefig(plot, dpi=120)
        plt.close(fig)
    if json_out:
        _emit_json({"experiment": experiment, "rows": rows})
        return
    import pandas as pd

    df = pd.DataFrame(rows)
    con = _console()
    con.print(escape(df.round(3).to_string(index=False)))


hybrid_app = typer.Typer(
    help="Hybrid EMA + OMA model of the whole FRF with Bayesian updating (thesis ch. 5)."
)
app.add_typer(hybrid_app, name="hybrid")


@hybrid_app.command("study")
def hybrid_study_cmd(
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
    from .hybrid.study import hybrid_study

    res = hybrid_study(background_noise_rel=background, rng=seed)
    if json_out:
        _emit_json(res)
        return
    con = _console()
    t = Table(
        title="FRF RMSE at the validation pose [um/N] (peak error %) - thesis Table 12 analogue"
    )
    for col in (
        "dir",
        "bins",
        "OMA segs",
        "flagged",
        "before (EMA)",
        "posterior",
        "warm update",
        "full retrain",
    ):
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


def _frfs_on_grid(frfs, grid, partial: bool = False):
    """Complex compliances (n, n_f) interpolated on ``grid``, path coordinates and bin masks.

    ``partial=True``: grid bins outside an FRF's range are masked (missing), not an error.
    """
    vals, s, masks = [], [], []
    for i, f in enumerate(frfs):
        if "path_s_m" not in f.meta:
            raise ValueError(
                f"FRF {i} has no path coordinate (write it with --path-s / from `hybrid oma`)"
            )
        if f.quantity != "compliance":
            raise ValueError(f"FRF {i} is {f.quantity}, expected compliance")
        outside = (grid < f.frequency_hz[0] - 1e-3) | (grid > f.frequency_hz[-1] + 1e-3)
        if np.any(outside) and not partial:
            raise ValueError(
                f"FRF {i} covers {f.frequency_hz[0]:g}-{f.frequency_hz[-1]:g} Hz, not the model grid {grid[0]:g}-{grid[-1]:g} Hz"
            )
        vals.append(
            np.interp(grid, f.frequency_hz, f.values.real)
            + 1j * np.interp(grid, f.frequency_hz, f.values.imag)
        )
        flagged = np.asarray(f.meta.get("flagged", np.zeros(f.frequency_hz.size, bool)), bool)
        nearest = np.clip(np.searchsorted(f.frequency_hz, grid), 0, f.frequency_hz.size - 1)
        masks.append(~flagged[nearest] & ~outside)
        s.append(float(f.meta["path_s_m"]))
    return np.array(vals), np.array(s), np.array(masks)


@hybrid_app.command("oma")
def hybrid_oma(
    record: Annotated[
        Path,
        typer.Argument(
            help="Synchronised CSV: time_s, force_{x,y,z}_n, displacement_{x,y,z}_m, path_s_m (e.g. from `robovib sim mill`/`sim offset-mass`)."
        ),
    ],
    output: OutOpt,
    direction: Annotated[str, typer.Option(help="x, y or z.")] = "x",
    segment_mm: Annotated[float, typer.Option(help="Path length per FRF [mm].")] = 50.0,
    nperseg: Annotated[int, typer.Option(help="Welch window [samples].")] = 512,
    fmin: Annotated[float, typer.Option(help="Lowest frequency [Hz].")] = 2.0,
    fmax: Annotated[float, typer.Option(help="Highest frequency [Hz].")] = 40.0,
    rpm: Annotated[
        float | None, typer.Option(help="Spindle speed [rpm]: flags its harmonics.")
    ] = None,
    json_out: JsonFlag = False,
) -> None:
    """OMA compliance FRFs per path segment from a milling record (flagged bins stored)."""
    from dataclasses import replace

    import pandas as pd

    from .hybrid import oma_frfs
    from .io import write_frfs

    try:
        df = pd.read_csv(record)
        need = [
            "time_s",
            "force_x_n",
            "force_y_n",
            "force_z_n",
            "displacement_x_m",
            "displacement_y_m",
            "displacement_z_m",
            "path_s_m",
        ]
        missing = [c for c in need if c not in df]
        if missing:
            _fail(f"{record}: missing columns {missing}")
        segs = oma_frfs(
            df["time_s"].to_numpy(), df[need[1:4]].to_numpy(), df[need[4:7]].to_numpy(), df["path_s_m"].to_numpy(),
            direction=direction, segment_length_m=segment_mm / 1e3, nperseg=nperseg, f_min_hz=fmin, f_max_hz=fmax,
            spindle_rpm=rpm,
        )  # fmt: skip
        frfs = [
            replace(sg.frf, meta={"path_s_m": sg.s_mid_m, "flagged": sg.flagged}) for sg in segs
        ]
        write_frfs(output, frfs)
    except (ValueError, OSError) as exc:
        _fail(str(exc))
    doc = {"output": str(output), "segments": len(segs), "s_mid_m": [sg.s_mid_m for sg in segs],
           "flagged_fraction": float(np.mean([sg.flagged.mean() for sg in segs]))}  # fmt: skip
    if json_out:
        _emit_json(doc)
    else:
        typer.echo(
            f"wrote {output}: {len(segs)} OMA FRFs ({direction}), {100 * doc['flagged_fraction']:.0f} % of bins flagged"
        )


@hybrid_app.command("fit")
def hybrid_fit(
    ema: Annotated[
        list[Path],
        typer.Argument(help="EMA FRF files (.h5) with path coordinates (frf compute --path-s)."),
    ],
    output: OutOpt,
    fmin: Annotated[float, typer.Option(help="Model grid start [Hz].")] = 2.0,
    fmax: Annotated[float, typer.Option(help="Model grid end [Hz].")] = 40.0,
    df_hz: Annotated[
        float, typer.Option("--df", help="Model grid step [Hz] (match the OMA resolution).")
    ] = 1.953125,
    json_out: JsonFlag = False,
) -> None:
    """Initial per-bin GP model of the compliance over the path from EMA FRFs."""
    from .hybrid import FRFPoseModel
    from .io import read_frfs

    grid = np.arange(fmin, fmax + 1e-9, df_hz)
    try:
        h, s, m = _frfs_on_grid([f for path in ema for f in read_frfs(path)], grid)
        model = FRFPoseModel(grid).fit(s, h, mask=m)
        model.save(output)
    except (ValueError, OSError) as exc:
        _fail(str(exc))
    doc = {
        "output": str(output),
        "n_frfs": len(s),
        "n_bins": int(grid.size),
        "iterations_mean": model.last_report_.iterations_mean_per_gp,
    }
    _emit_json(doc) if json_out else typer.echo(
        f"wrote {output}: {len(s)} EMA FRFs, {grid.size} bins"
    )


@hybrid_app.command("update")
def hybrid_update(
    model_file: Annotated[Path, typer.Argument(help="Model from `hybrid fit`.")],
    oma: Annotated[Path, typer.Argument(help="OMA FRFs from `hybrid oma`.")],
    output: OutOpt,
    mode: Annotated[
        str, typer.Option(help="warm (re-optimise from the current hyperparameters) or posterior.")
    ] = "warm",
    json_out: JsonFlag = False,
) -> None:
    """Bayesian update of the model with OMA FRFs (separate noise level for OMA)."""
    from .hybrid import FRFPoseModel
    from .io import read_frfs

    try:
        model = FRFPoseModel.load(model_file)
        h, s, m = _frfs_on_grid(read_frfs(oma), model.frequency_hz, partial=True)
        rep = model.update(s, h, mask=m, mode=mode)
        model.save(output)
    except (ValueError, OSError) as exc:
        _fail(str(exc))
    doc = {
        "output": str(output),
        "n_oma": len(s),
        "mode": mode,
        "iterations_mean": rep.iterations_mean_per_gp,
        "wall_time_s": rep.wall_time_s,
    }
    _emit_json(doc) if json_out else typer.echo(
        f"wrote {output}: updated with {len(s)} OMA FRFs ({mode}, {rep.iterations_mean_per_gp:.1f} iterations per GP)"
    )


@hybrid_app.command("predict")
def hybrid_predict(
    model_file: Annotated[Path, typer.Argument(help="Model file.")],
    s: Annotated[float, typer.Option("--s", help="Path coordinate [m].")],
    measured: Annotated[
        Path | None, typer.Option(help="A measured FRF file to compare with (first FRF).")
    ] = None,
    plot: Annotated[
        Path | None, typer.Option(help="PNG: predicted FRF with 95 % band (and the measured one).")
    ] = None,
    json_out: JsonFlag = False,
) -> None:
    """Predicted compliance FRF at a path coordinate, with a band; optional comparison."""
    from .frf import FRF
    from .hybrid import FRFPoseModel
    from .io import read_frfs

    try:
        model = FRFPoseModel.load(model_file)
        h, sd = model.predict([s], return_std=True)
        h, sd = h[0], sd[0]
        meas = None
        if measured is not None:
            f0 = read_frfs(measured)[0]
            if f0.quantity != "compliance":
                _fail(f"{measured}: FRF is {f0.quantity}, expected compliance")
            meas = np.interp(model.frequency_hz, f0.frequency_hz, f0.values.real) + 1j * np.interp(
                model.frequency_hz, f0.frequency_hz, f0.values.imag
            )
    except (ValueError, OSError) as exc:
        _fail(str(exc))
    doc = {"s_m": s, "extrapolating": bool(model.extrapolating([s])[0]), "frequency_hz": model.frequency_hz,
           "compliance_abs_um_per_n": 1e6 * np.abs(h), "std_um_per_n": 1e6 * sd}  # fmt: skip
    if meas is not None:
        doc["rmse_um_per_n"] = float(1e6 * np.sqrt(np.mean(np.abs(h - meas) ** 2)))
    if plot is not None:
        from .modal.plot import plot_frf_fit

        fig = plot_frf_fit(
            FRF(model.frequency_hz, h, source="model", estimator="model"),
            title=f"prediction at s = {s:g} m",
        )
        ax = fig.axes[0]
        ax.fill_between(
            model.frequency_hz,
            np.maximum(np.abs(h) - 2 * sd, 1e-12),
            np.abs(h) + 2 * sd,
            color="C0",
            alpha=0.2,
            label="±2σ",
        )
        if meas is not None:
            ax.semilogy(model.frequency_hz, np.abs(meas), "k--", label="measured")
        ax.legend(fontsize=8)
        fig.savefig(plot, dpi=120)
    if json_out:
        _emit_json(doc)
        return
    if doc["extrapolating"]:
        typer.echo("warning: s is outside the calibrated range: extrapolation")
    peak = int(np.argmax(np.abs(h)))
    typer.echo(
        f"peak compliance {1e6 * abs(h[peak]):.3f} um/N at {model.frequency_hz[peak]:.2f} Hz (±{2e6 * sd[peak]:.3f} at 2σ)"
    )
    if meas is not None:
        typer.echo(f"RMSE vs measured: {doc['rmse_um_per_n']:.3f} um/N")
    if plot is not None:
        typer.echo(f"wrote {plot}")


@hybrid_app.command("next-poses")
def hybrid_next_poses(
    k: Annotated[int, typer.Option("--k", help="Number of poses to propose.")] = 3,
    ema: Annotated[
        str, typer.Option(help="Comma-separated path coordinates [m] already tested.")
    ] = "0,0.585,1.235",
    direction: Annotated[str, typer.Option(help="x, y or z.")] = "x",
    seed: SeedOpt = 0,
    plot: Annotated[
        Path | None, typer.Option(help="PNG of the variance along the path with the proposals.")
    ] = None,
    json_out: JsonFlag = False,
) -> None:
    """Where to hammer next along the chapter-4 path: largest integrated predictive variance."""
    from .hybrid import FRFPoseModel
    from .hybrid.study import ema_frf_on_grid
    from .sim import PATH_LENGTH_M, VirtualRobot

    try:
        tested = np.array([float(v) for v in ema.split(",")])
    except ValueError:
        _fail(f"--ema must be comma-separated numbers, got {ema!r}")
    robot = VirtualRobot()
    grid = np.arange(2.0, 40.0, 1.0)
    rng = np.random.default_rng(seed)
    try:
        frfs = np.array([ema_frf_on_grid(robot, s, direction, grid, rng) for s in tested])
        model = FRFPoseModel(grid, rng=seed).fit(tested, frfs)
        picks = model.next_poses(np.linspace(0, PATH_LENGTH_M, 50), k=k)[:, 0]
    except ValueError as exc:
        _fail(str(exc))
    if plot is not None:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        cand = np.linspace(0, PATH_LENGTH_M, 200)
        fig, ax = plt.subplots(figsize=(7, 3.5))
        ax.plot(
            cand * 1e3,
            model.integrated_variance(cand),
            color="C0",
            label="integrated predictive variance",
        )
        for i, s_t in enumerate(tested):
            ax.axvline(s_t * 1e3, color="k", lw=1, label="tested" if i == 0 else None)
        for i, s_p in enumerate(picks):
            ax.axvline(s_p * 1e3, color="C3", ls="--", lw=1, label="proposed" if i == 0 else None)
        ax.set_xlabel("distance along the path [mm]")
        ax.set_ylabel("sum over bins of var [(um/N)^2]")
        ax.legend(fontsize=8)
        fig.tight_layout()
        fig.savefig(plot, dpi=120)
        plt.close(fig)
    if json_out:
        _emit_json({"tested_s_m": tested, "next_s_m": picks})
    else:
        typer.echo(
            "next hammer-test poses (path distance, m): " + ", ".join(f"{p:.3f}" for p in picks)
        )


def main() -> None:
    app()


if __name__ == "__main__":
    main()
