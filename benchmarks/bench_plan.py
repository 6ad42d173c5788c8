"""Issue 39: ``mill plan`` on a 50-segment path on one core (target <= 10 s), against the
per-sample route (``stability_probability``, one ZOA call per sample) for the same work.

The plan evaluates every segment x Rz x speed for every structure (50 x 10 x 12 x 48); the
reference computes P(stable) the per-sample way at a few of those poses and is scaled to the
same number of poses. Then the re-plan after 5 test cuts (``mill plan --cuts``: the structures
x a 32-point common-factor grid, the local factor integrated; same target).

    OMP_NUM_THREADS=1 python benchmarks/bench_plan.py
"""

from __future__ import annotations

import time

import numpy as np


def main() -> None:
    from robovib.gp.chapter3_model import workspace_predictor
    from robovib.milling import ALUMINIUM_7075, CuttingConditions, MillingTool
    from robovib.milling.planning import plan_path
    from robovib.milling.structures import sample_structures
    from robovib.milling.uncertainty import mode_distribution_at_pose, stability_probability

    model = workspace_predictor(None, seed=0, require_inputs=("x_mm", "y_mm", "rz_deg"))
    tool, cond = MillingTool(), CuttingConditions(1750.0, 0.058e-3, 1e-3, 6e-3)
    t0, c0 = time.perf_counter(), time.process_time()
    st = sample_structures(model, 48, rng=0)
    plan = plan_path(st, [[2150, -250], [2650, 500]], tool, cond, ALUMINIUM_7075, n_segments=50)
    t_plan, c_plan = time.perf_counter() - t0, time.process_time() - c0
    n_poses = plan.rz_deg.size * len(plan.settings["rz_grid_deg"])
    rpm = np.asarray(plan.settings["rpm_grid"])
    k = 3
    t0 = time.perf_counter()
    for i in range(k):
        pose = [2200.0 + 100 * i, 0.0, 40.0 * i]
        stability_probability(mode_distribution_at_pose(model, pose, rng=i), tool, cond,
                              ALUMINIUM_7075, rpm, n_samples=48, method="zoa")  # fmt: skip
    t_ref = (time.perf_counter() - t0) / k * n_poses
    print(f"mill plan, 50 segments x {len(plan.settings['rz_grid_deg'])} Rz x {rpm.size} speeds "
          f"x 48 structures (+ vibration bands): {t_plan:.2f} s wall, {c_plan:.2f} s CPU of this "
          f"process (target <= 10 s on one core; wall > CPU: the machine is shared)")  # fmt: skip
    print(f"per-sample ZOA (stability_probability) for the same {n_poses} poses: {t_ref:.0f} s "
          f"(from {k} poses); ratio {t_ref / t_plan:.0f}x")  # fmt: skip
    # the re-plan after 5 test cuts (mill plan --cuts): 48 structures x 32 common factors, the
    # local factor integrated (a 1-D root per segment x Rz x speed, factor_grid.local_quantile)
    from robovib.io.cuts import MeasuredCuts
    from robovib.milling.cut_posterior import update_with_cuts

    cut_pose = np.column_stack([plan.midpoints_mm[::10], plan.rz_deg[::10]])
    cuts = MeasuredCuts(plan.spindle_rpm[::10], 1.5 * plan.depth_m[::10],
                        np.array([False, True, False, True, False]), cut_pose)  # fmt: skip
    t0, c0 = time.perf_counter(), time.process_time()
    upd = update_with_cuts(st, cuts, tool, cond, ALUMINIUM_7075, local_factor=(0.55, 1.3))
    plan_path(upd.structures, [[2150, -250], [2650, 500]], tool, cond, ALUMINIUM_7075,
              n_segments=50)  # fmt: skip
    t_re, c_re = time.perf_counter() - t0, time.process_time() - c0
    print(f"mill plan --cuts (5 cuts; {upd.structures.n_samples} rows, local factor): "
          f"{t_re:.2f} s wall, {c_re:.2f} s CPU (target <= 10 s on one core)")  # fmt: skip


if __name__ == "__main__":
    main()
