"""Issue 24: do the calibrated ±2σ bands of a user's campaign cover the truth at unseen poses?

A virtual hammer campaign (``sim campaign``: four file layouts, 2 hits per recording) at
``--poses`` poses, with and without test-to-test scatter, goes through ``campaign process`` and
``model fit`` (calibrated, kernel chosen by grouped CV); at ``--unseen`` poses inside the sampled
box the latent ±2σ band of fn, k and c (the modal parameters themselves) is checked against the
virtual robot's true dominant mode. Printed per case: checks covered (of 3 x 3 x unseen) for the
calibrated model and for the plain GP (before), and the median |error|/σ.

    python benchmarks/study_campaign_bands.py            # 40 poses, 25 unseen, seeds 11 12 (~6 min)
    python benchmarks/study_campaign_bands.py --seeds 5  # another campaign
"""

from __future__ import annotations

import argparse
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np
import pandas as pd

SCATTER = (0.01, 0.04, 0.04)  # Table A1's within-pose relative std of (fn, k, c), RMS over poses


def one(seed: int, n_poses: int, n_unseen: int, scatter) -> dict:
    from robovib.campaign import fit_pose_model_from_table, process_campaign
    from robovib.gp import PoseModalModel
    from robovib.sim import simulate_campaign

    rng = np.random.default_rng(seed)
    x = 2100 + 450 * (np.arange(n_poses) + rng.uniform(size=n_poses)) / n_poses
    poses = np.column_stack([x, rng.uniform(-300, 600, n_poses), rng.uniform(0, 180, n_poses)])
    with tempfile.TemporaryDirectory() as tmp, warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sim = simulate_campaign(poses, tmp, rng=seed, n_hits=2, n_truth=n_unseen, scatter=scatter)
        process_campaign(sim.manifest, Path(tmp) / "out", n_workers=1)
        fit = fit_pose_model_from_table(Path(tmp) / "out" / "modal.csv")
        plain = PoseModalModel(mode_switch="auto", rng=0).fit(fit.X, fit.Y)
        truth = pd.read_csv(sim.truth)
    X = truth[["x_mm", "y_mm", "rz_deg"]].to_numpy()
    T = []
    for d in "xyz":
        fn, k, z = (
            truth[f"{d}_{q}"].to_numpy() for q in ("fn_hz", "stiffness_n_per_m", "damping_ratio")
        )
        T += [fn, k, 2 * z * k / (2 * np.pi * fn)]
    T = np.column_stack(T)
    pred = fit.model.predictive(X)
    mean, std = pred.point(), pred.point_std("latent")
    m0, s0 = plain.predict(X, return_std=True)
    inside = np.abs(mean - T) <= 2 * std
    inside0 = np.abs(m0 - T) <= 2 * s0
    return {
        "covered": int(inside.sum()), "covered_before": int(inside0.sum()), "checks": T.size,
        "median_err_over_std": float(np.median(np.abs(mean - T) / std)),
        "median_err_over_std_before": float(np.median(np.abs(m0 - T) / s0)),
        "median_rel_err_pct": float(100 * np.median(np.abs(mean / T - 1))),
        "kernels": ",".join(sorted(set(fit.model.covariances_))),
    }  # fmt: skip


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=[11, 12])
    ap.add_argument("--poses", type=int, default=40)
    ap.add_argument("--unseen", type=int, default=25)
    args = ap.parse_args(argv)
    print(
        f"{'case':24s} {'covered':>9s} {'before':>9s} {'|e|/σ':>7s} {'before':>7s} {'|e| %':>6s}  kernels"
    )
    for scatter in (None, SCATTER):
        for seed in args.seeds:
            t0 = time.perf_counter()
            r = one(seed, args.poses, args.unseen, scatter)
            name = f"seed {seed}, " + ("scatter" if scatter else "no scatter")
            print(f"{name:24s} {r['covered']:4d}/{r['checks']:<4d} {r['covered_before']:4d}/{r['checks']:<4d} "
                  f"{r['median_err_over_std']:7.2f} {r['median_err_over_std_before']:7.2f} "
                  f"{r['median_rel_err_pct']:6.2f}  {r['kernels']}  ({time.perf_counter() - t0:.0f} s)",
                  flush=True)  # fmt: skip


if __name__ == "__main__":
    main()
