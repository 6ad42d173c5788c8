"""Issue 36: does the latent ±2σ of a clean factorial-grid campaign hold the truth between levels?

Poses on a factorial grid (3 X levels × 4 Y levels × 3 Rz levels = 36 poses, no test-to-test
scatter); checks at ``--checks`` random poses inside the grid's box, at least 20 % of a level
spacing away from every level of every coordinate (off-grid). Two routes:

* ``truth``: the virtual robot's exact dominant modes at the grid poses are the training data
  (isolates the pose model: calibration, mode-switch test);
* ``campaign``: a simulated hammer campaign at the grid poses goes through ``campaign process``
  and ``model fit`` (what a user does).

Printed per route and seed: checks covered (9 outputs × checks), per output, poses with all nine
outputs covered, the median |error|/σ and relative error, the mode-switch decision per direction.

    python benchmarks/study_factorial_bands.py                       # truth route, seeds 0 1 2 (~1 min)
    python benchmarks/study_factorial_bands.py --route campaign --seeds 0   # ~2 min
"""

from __future__ import annotations

import argparse
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

LEVELS = ((2100.0, 2325.0, 2550.0), (-300.0, 0.0, 300.0, 600.0), (0.0, 90.0, 180.0))
QUANTITIES = ("fn_hz", "stiffness_n_per_m", "damping_ns_per_m")


def grid_poses() -> np.ndarray:
    """(36, 3) factorial grid of ``LEVELS``."""
    return np.array([[a, b, c] for a in LEVELS[0] for b in LEVELS[1] for c in LEVELS[2]], float)


def off_grid_poses(n: int, rng) -> np.ndarray:
    """(n, 3) uniform poses in the grid's box, >= 20 % of a level spacing from every level."""
    lo = [lv[0] for lv in LEVELS]
    hi = [lv[-1] for lv in LEVELS]
    out = []
    while len(out) < n:
        p = rng.uniform(lo, hi)
        if all(
            np.min(np.abs(np.asarray(lv) - p[i])) > 0.2 * np.diff(lv)[0]
            for i, lv in enumerate(LEVELS)
        ):
            out.append(p)
    return np.array(out)


def targets(table) -> np.ndarray:
    """(n, 9) SI targets [fn, k, c] per direction x, y, z of a truth table."""
    return np.column_stack([table[f"{d}_{q}"] for d in "xyz" for q in QUANTITIES])


def one(seed: int, route: str, n_checks: int, robot_seed: int | None = None) -> dict:
    from robovib.campaign import fit_pose_model_from_table, process_campaign
    from robovib.gp import PoseModalModel
    from robovib.sim import VirtualRobot, simulate_campaign
    from robovib.sim.campaign import truth_table

    robot = VirtualRobot.variant(robot_seed)
    X = grid_poses()
    Xc = off_grid_poses(n_checks, np.random.default_rng(seed))
    T = targets(truth_table(robot, Xc))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        if route == "truth":
            model = PoseModalModel(rng=0, calibrate=True, covariance="auto").fit(
                X, targets(truth_table(robot, X))
            )
        else:
            with tempfile.TemporaryDirectory() as tmp:
                sim = simulate_campaign(X, tmp, rng=seed, n_hits=2, n_truth=0, robot=robot)
                process_campaign(sim.manifest, Path(tmp) / "out", n_workers=1)
                model = fit_pose_model_from_table(Path(tmp) / "out" / "modal.csv", rng=0).model
    pred = model.predictive(Xc)
    mean, std = pred.point(), pred.point_std("latent")
    inside = np.abs(mean - T) <= 2 * std
    return {
        "covered": int(inside.sum()),
        "checks": int(inside.size),
        "per_output": inside.sum(axis=0),
        "poses_covered": int(inside.all(axis=1).sum()),
        "median_err_over_std": float(np.median(np.abs(mean - T) / std)),
        "median_rel_err_pct": float(100 * np.median(np.abs(mean / T - 1))),
        "switch": "".join(d if s.found else "-" for d, s in model.mode_switches_.items()),
    }


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--route", choices=("truth", "campaign"), default="truth")
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    ap.add_argument("--checks", type=int, default=24)
    ap.add_argument(
        "--robot-seed",
        type=int,
        default=None,
        help="a robot of the family (robovib.sim.family) instead of the thesis robot",
    )
    args = ap.parse_args(argv)
    print(f"route {args.route}: 36 grid poses, {args.checks} off-grid checks x 9 outputs")
    print(
        f"{'seed':>4s} {'covered':>9s} {'%':>6s} {'poses':>6s} {'|e|/σ':>6s} {'|e| %':>6s} switch  per output (x fn k c, y fn k c, z fn k c)"
    )
    total = n = 0
    for seed in args.seeds:
        t0 = time.perf_counter()
        r = one(seed, args.route, args.checks, args.robot_seed)
        total, n = total + r["covered"], n + r["checks"]
        print(f"{seed:4d} {r['covered']:4d}/{r['checks']:<4d} {100 * r['covered'] / r['checks']:6.1f} "
              f"{r['poses_covered']:3d}/{args.checks:<2d} {r['median_err_over_std']:6.2f} "
              f"{r['median_rel_err_pct']:6.2f} {r['switch']:>6s}  {' '.join(map(str, r['per_output']))}"
              f"  ({time.perf_counter() - t0:.0f} s)")  # fmt: skip
    print(f"all: {total}/{n} = {100 * total / n:.1f} % of off-grid checks inside the latent ±2σ")


if __name__ == "__main__":
    main()
