"""Issue 29: stability from every mode — multi-mode pose model vs dominant-mode, against the truth.

A user's path on the virtual robot: a hammer campaign (``sim campaign``, ``--campaign-poses``
poses) -> ``campaign process`` with every mode fitted in ``--band`` and tracked across poses
(``modes.csv``) -> two pose models: the dominant-mode one (``modal.csv``, as chapter 3) and the
multi-mode one (:func:`robovib.campaign.fit_multimode_pose_model`). At ``--poses`` unseen poses
and ``--speeds`` (defaults: 1300 rpm, tooth passing 43 Hz near the X secondary mode; 1900 rpm,
63 Hz near the X high mode; 2600 rpm) the stability limit is predicted from ``--samples`` joint
draws of each model's calibrated predictive distribution (semi-discretization on all sampled
modes, :func:`robovib.milling.stability_probability`) and compared with the SDM limit of the
truth's modes (every mode, X and Y). Printed per model: median and 90th percentile of the
relative error of the predicted median limit, and how often the 90 % band (5-95 % quantiles of
the samples) contains the true limit. Also the tool-tip vibration (peak-to-valley per
revolution, X and Y) of a stable cut (half the true limit) predicted from each model's mean
modes vs the truth's.

    python benchmarks/study_multimode.py                      # ~15 min on one core
    python benchmarks/study_multimode.py --poses 5 --samples 10 --campaign-poses 15   # quick
    python benchmarks/study_multimode.py --scatter 0 0 0      # a clean campaign (no scatter)
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np


def fit_models(n_poses: int, seed: int, band_hz, scatter=(0.01, 0.04, 0.04), robot=None):
    """Sim campaign -> campaign process (every mode) -> dominant and multi-mode pose models.

    ``scatter``: test-to-test scatter of (fn, k, zeta) per recording; ``None``: a clean campaign.
    ``robot``: the virtual robot hammered (``None``: the thesis robot).
    """
    import pandas as pd

    from robovib.campaign import (
        ProcessingSettings,
        fit_multimode_pose_model,
        fit_pose_model_from_table,
        process_campaign,
    )
    from robovib.sim import simulate_campaign

    rng = np.random.default_rng(seed)
    x = 2100 + 450 * (np.arange(n_poses) + rng.uniform(size=n_poses)) / n_poses
    poses = np.column_stack([x, rng.uniform(-300, 600, n_poses), rng.uniform(0, 180, n_poses)])
    with tempfile.TemporaryDirectory() as tmp, warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sim = simulate_campaign(poses, tmp, rng=seed, n_hits=2, n_truth=0, scatter=scatter,
                                robot=robot)  # fmt: skip
        out = Path(tmp) / "out"
        process_campaign(sim.manifest, out, n_workers=1,
                         settings=ProcessingSettings(modes_band_hz=tuple(band_hz)))  # fmt: skip
        dominant = fit_pose_model_from_table(out / "modal.csv").model
        modes = pd.read_csv(out / "modes.csv")
        multi = fit_multimode_pose_model(modes).model
    return dominant, multi, modes


def _vibration(modes_x, modes_y, tool, cond, coef, fs=2000.0, duration_s=1.0):
    from robovib.milling.forces import milling_forces
    from robovib.milling.prediction import convolve_force, peak_to_valley_per_revolution

    t = np.arange(int(fs * duration_s)) / fs
    f = milling_forces(t, tool, cond, coef)
    out = []
    for j, modes in enumerate((modes_x, modes_y)):
        x = convolve_force(f[:, j], fs, modes=modes)
        half = x.size // 2  # steady state: the second half
        out.append(float(np.mean(peak_to_valley_per_revolution(x[half:], fs, cond.spindle_rpm))))
    return np.array(out)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--poses", type=int, default=20)
    ap.add_argument("--campaign-poses", type=int, default=36)
    ap.add_argument("--speeds", type=float, nargs="+", default=None,
                    help="spindle speeds [rpm]; default 1300 1900 2600 on the thesis robot, and on "
                         "a --robot-seed robot the speeds whose tooth passing sits on its X "
                         "secondary and switching modes, and 2600")  # fmt: skip
    ap.add_argument("--samples", type=int, default=40)
    ap.add_argument("--band", type=float, nargs=2, default=[5.0, 100.0])
    ap.add_argument("--seed", type=int, default=21)
    ap.add_argument("--scatter", type=float, nargs=3, default=[0.01, 0.04, 0.04],
                    metavar=("FN", "K", "ZETA"),
                    help="test-to-test scatter of the campaign (relative stds of fn, k, zeta per "
                         "recording); 0 0 0: a clean campaign")  # fmt: skip
    ap.add_argument(
        "--robot-seed",
        type=int,
        default=None,
        help="a robot of the family (robovib.sim.family) instead of the thesis robot",
    )
    ap.add_argument("--figure", type=Path, default=None, help="PNG of predicted vs true limits")
    ap.add_argument("--json", type=Path, default=None, help="per-case results")
    args = ap.parse_args(argv)

    from robovib.milling import ALUMINIUM_7075, CuttingConditions, MillingTool
    from robovib.milling.sdm import sdm_lobes
    from robovib.milling.uncertainty import (
        mode_distribution_at_pose,
        mode_distributions_at_pose,
        stability_probability,
    )
    from robovib.sim import VirtualRobot

    t0 = time.perf_counter()
    robot = VirtualRobot.variant(args.robot_seed)
    scatter = tuple(args.scatter) if any(v > 0 for v in args.scatter) else None
    dominant, multi, _modes = fit_models(args.campaign_poses, args.seed, args.band, scatter, robot)
    pres = json.loads(multi.provenance_["mode_presence"])
    print(f"campaign of {args.campaign_poses} poses processed, models fitted "
          f"({time.perf_counter() - t0:.0f} s); tracked modes: "
          + ", ".join(f"{k} {v['presence']:.2f}" for k, v in pres.items()))  # fmt: skip
    print(f"multi-mode model directions: {', '.join(multi.directions)}")
    tool = MillingTool()
    rng = np.random.default_rng(args.seed + 1)
    unseen = np.column_stack([rng.uniform(2150, 2500, args.poses), rng.uniform(-250, 550, args.poses),
                              rng.uniform(5, 175, args.poses)])  # fmt: skip
    speeds = args.speeds or [1300.0, 1900.0, 2600.0]
    if args.robot_seed is not None:
        from robovib.sim.family import tooth_passing_speeds_rpm

        on_modes = tooth_passing_speeds_rpm(robot, unseen * [1e-3, 1e-3, 1], tool.n_flutes)
        speeds = args.speeds or [
            round(on_modes["x secondary"]),
            round(on_modes["x switching"]),
            2600.0,
        ]
        print(f"robot seed {args.robot_seed} (switch region: {robot.draw.switch}); tooth passing "
              + ", ".join(f"on the {k} mode at {v:.0f} rpm" for k, v in on_modes.items()))  # fmt: skip
    rpm = np.asarray(speeds, float)
    cond0 = CuttingConditions(float(rpm[0]), 0.058e-3, 1e-3, 6e-3)
    names = ("dominant", "multi-mode")
    rows = []
    for i, pose in enumerate(unseen):
        coords = np.array([[pose[0] / 1e3, pose[1] / 1e3, pose[2]]])
        tx = robot.workspace.modes(coords, "x").at(0)
        ty = robot.workspace.modes(coords, "y").at(0)
        truth = sdm_lobes(tx, ty, tool, cond0, ALUMINIUM_7075, rpm).a_lim_m
        dists = {
            "dominant": mode_distribution_at_pose(dominant, pose, rng=i),
            "multi-mode": mode_distributions_at_pose(multi, pose, rng=i),
        }
        res = {}
        for name in names:
            p = stability_probability(dists[name], tool, cond0, ALUMINIUM_7075, rpm,
                                      n_samples=args.samples, method="sdm", rng=i)  # fmt: skip
            res[name] = p
        for s, speed in enumerate(rpm):
            cond = CuttingConditions(float(speed), 0.058e-3, 0.5 * float(truth[s]), 6e-3)
            vib_true = _vibration(tx, ty, tool, cond, ALUMINIUM_7075)
            row = {"pose": pose.tolist(), "rpm": float(speed), "true_mm": 1e3 * float(truth[s]),
                   "vib_true_um": (1e6 * vib_true).tolist()}  # fmt: skip
            for name in names:
                a = res[name].a_lim_samples_m[:, s]
                d = dists[name]
                mx = [m.mean for m in (d["x"] if isinstance(d["x"], list) else [d["x"]])]
                my = [m.mean for m in (d["y"] if isinstance(d["y"], list) else [d["y"]])]
                vib = _vibration(mx, my, tool, cond, ALUMINIUM_7075)
                row[name] = {
                    "median_mm": 1e3 * float(np.median(a)),
                    "q05_mm": 1e3 * float(np.quantile(a, 0.05)),
                    "q95_mm": 1e3 * float(np.quantile(a, 0.95)),
                    "mean_modes_mm": 1e3 * float(res[name].mean.a_lim_m[s]),
                    "vib_um": (1e6 * vib).tolist(),
                }
            rows.append(row)
        print(f"  pose {i + 1}/{len(unseen)} ({time.perf_counter() - t0:.0f} s)", flush=True)

    true = np.array([r["true_mm"] for r in rows])
    sp = np.array([r["rpm"] for r in rows])
    print(f"\n{len(rows)} cases ({args.poses} unseen poses x {rpm.size} speeds), "
          f"{args.samples} samples each, SDM on the sampled modes vs SDM on the truth's modes; "
          f"campaign scatter (fn, k, zeta): {scatter or 'none'}")  # fmt: skip
    print(f"{'model':12s} {'speed':>7s} {'median |err| %':>15s} {'p90 |err| %':>12s} "
          f"{'90% band covers':>16s} {'truth above all':>16s} {'vib |err| % x/y':>17s}")  # fmt: skip
    summary = {}
    for name in names:
        med = np.array([r[name]["median_mm"] for r in rows])
        lo = np.array([r[name]["q05_mm"] for r in rows])
        hi = np.array([r[name]["q95_mm"] for r in rows])
        vt = np.array([r["vib_true_um"] for r in rows])
        vp = np.array([r[name]["vib_um"] for r in rows])
        verr = 100 * np.abs(vp - vt) / vt
        err = 100 * np.abs(med - true) / true
        cover = (lo <= true) & (true <= hi)
        for sel_name, sel in [*((f"{v:.0f}", sp == v) for v in rpm), ("all", sp > 0)]:
            print(f"{name:12s} {sel_name:>7s} {np.median(err[sel]):15.1f} "
                  f"{np.quantile(err[sel], 0.9):12.1f} "
                  f"{f'{cover[sel].sum()}/{sel.sum()}':>16s} {int(np.sum(true[sel] > hi[sel])):16d} "
                  f"{np.median(verr[sel, 0]):8.1f}/{np.median(verr[sel, 1]):.1f}")  # fmt: skip
        summary[name] = {"median_abs_error_pct": float(np.median(err)),
                         "p90_abs_error_pct": float(np.quantile(err, 0.9)),
                         "coverage_90": float(cover.mean()),
                         "vibration_median_abs_error_pct_xy": np.median(verr, axis=0).tolist()}  # fmt: skip
    print(json.dumps(summary, indent=1))
    if args.json:
        args.json.write_text(json.dumps({"summary": summary, "cases": rows}, indent=1))
    if args.figure:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, axes = plt.subplots(1, 2, figsize=(10, 4.5), sharex=True, sharey=True)
        for ax, name in zip(axes, names, strict=True):
            med = np.array([r[name]["median_mm"] for r in rows])
            lo = np.array([r[name]["q05_mm"] for r in rows])
            hi = np.array([r[name]["q95_mm"] for r in rows])
            for v, mk in zip(rpm, "osd^v", strict=False):
                sel = sp == v
                ax.errorbar(true[sel], med[sel], yerr=[med[sel] - lo[sel], hi[sel] - med[sel]],
                            fmt=mk, ms=4, capsize=2, label=f"{v:.0f} rpm")  # fmt: skip
            m = float(max(true.max(), np.max([r[n]["q95_mm"] for r in rows for n in names])))
            ax.plot([0, m], [0, m], "k--", lw=1)
            ax.set(title=f"{name}: median |err| {summary[name]['median_abs_error_pct']:.0f} %, "
                         f"band covers {100 * summary[name]['coverage_90']:.0f} %",
                   xlabel="true SDM limit (all modes) [mm]")  # fmt: skip
        axes[0].set_ylabel("predicted limit, median and 5-95 % of samples [mm]")
        axes[0].legend(fontsize=8)
        fig.tight_layout()
        fig.savefig(args.figure, dpi=120)
        print(f"figure: {args.figure}")
    print(f"total {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
