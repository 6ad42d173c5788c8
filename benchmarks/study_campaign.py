"""Study: the end-to-end campaign of the CI test, with its unseen-pose errors printed.

Run from the repository root::

    python benchmarks/study_campaign.py [--poses 30] [--seed 7]

Same campaign as ``tests/campaign/test_campaign.py``: poses x 3 directions on the virtual robot
(X 2100-2550 mm, Y -300-600 mm, Rz 0-180°), four file layouts, 2 hits of 2 s at 1280 Hz;
processed (``process_campaign``), the pose model fitted on ``modal.csv``
(``fit_pose_model_from_table``) and compared with the virtual robot's dominant modes at 25
unseen poses. Printed: grouped-by-pose CV table, median / 90th percentile / max relative error
of fn, k and ζ per direction, and the first 5 next poses over 200 candidates.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd

from robovib.campaign import fit_pose_model_from_table, next_poses, process_campaign
from robovib.sim import simulate_campaign


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--poses", type=int, default=30)
    ap.add_argument("--seed", type=int, default=7)
    args = ap.parse_args()
    rng = np.random.default_rng(args.seed)
    n = args.poses
    x = 2100 + 450 * (np.arange(n) + rng.uniform(size=n)) / n
    poses = np.column_stack([x, rng.uniform(-300, 600, n), rng.uniform(0, 180, n)])
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        sim = simulate_campaign(poses, tmp, rng=1, n_hits=2, duration_s=2.0, n_truth=25)
        t1 = time.perf_counter()
        process_campaign(sim.manifest, Path(tmp) / "out", n_workers=2)
        t2 = time.perf_counter()
        fit = fit_pose_model_from_table(Path(tmp) / "out" / "modal.csv")
        t3 = time.perf_counter()
        truth = pd.read_csv(sim.truth)
    print(f"model: {type(fit.model).__name__}; simulate {t1 - t0:.1f} s, process {t2 - t1:.1f} s, "
          f"fit + CV {t3 - t2:.1f} s")  # fmt: skip
    print(fit.cv_table.to_string(index=False, float_format=lambda v: f"{v:.4g}"))
    X = truth[["x_mm", "y_mm", "rz_deg"]].to_numpy()
    pred = fit.model.predict(X)
    print(f"\nrelative error at {len(X)} unseen poses: median / 90th pct / max [%]")
    for j, d in enumerate("xyz"):
        fn, k, c = pred[:, 3 * j], pred[:, 3 * j + 1], pred[:, 3 * j + 2]
        zeta = c * 2 * np.pi * fn / (2 * k)
        parts = []
        for name, p, t in (("fn", fn, truth[f"{d}_fn_hz"]),
                           ("k", k, truth[f"{d}_stiffness_n_per_m"]),
                           ("zeta", zeta, truth[f"{d}_damping_ratio"])):  # fmt: skip
            e = 100 * np.abs(p / t - 1)
            parts.append(f"{name} {np.median(e):.1f} / {np.quantile(e, 0.9):.1f} / {e.max():.1f}")
        print(f"  {d}: " + ";  ".join(parts))
    cand = np.column_stack([rng.uniform(2100, 2550, 200), rng.uniform(-300, 600, 200),
                            rng.uniform(0, 180, 200)])  # fmt: skip
    nx = next_poses(fit.model, cand, k=5)
    print("\nnext poses (x_mm, y_mm, rz_deg) and integrated variance reduction:")
    for p, g in zip(nx.poses, nx.variance_reduction, strict=True):
        print(f"  {p[0]:7.1f} {p[1]:7.1f} {p[2]:6.1f}   {g:.3f}")


if __name__ == "__main__":
    main()
