"""Benchmark: one GP per frequency bin vs frequency as an extra GP input (thesis §5.2.3).

Run from the repository root::

    python benchmarks/bench_hybrid.py

The thesis rejects a single GP over (pose, frequency) for cost without measuring it. Here both
are fitted to the same FRFs (13 poses along the chapter-4 path, from the virtual robot's truth
with 3 % noise, Re and Im parts) and scored at an unseen pose: per-bin GPs (batched, one call)
vs one ARD GP with inputs (s, f) over all poses x bins. Printed: fit time, ratio, and RMSE.
"""

from __future__ import annotations

import time

import numpy as np

from robovib.gp import BatchedGPRegressor
from robovib.hybrid import FRFPoseModel
from robovib.sim import VirtualRobot


def main() -> None:
    robot = VirtualRobot()
    grid = np.arange(2.0, 40.0, 0.5)
    s_train = np.linspace(0.0, 1.235, 13)
    s_test = 0.5
    rng = np.random.default_rng(0)
    h = robot.path.modes(s_train, "x").compliance(grid)
    h = h * (1 + 0.03 * (rng.normal(size=h.shape) + 1j * rng.normal(size=h.shape)))
    truth = robot.path.modes(s_test, "x").compliance(grid)[0]
    t0 = time.perf_counter()
    per_bin = FRFPoseModel(grid, rng=0).fit(s_train, h)
    t_bin = time.perf_counter() - t0
    err_bin = np.sqrt(np.mean(np.abs(per_bin.predict([s_test])[0] - truth) ** 2)) * 1e6
    xs = np.array([[s, f] for s in s_train for f in grid])
    ys = np.column_stack([h.real.ravel(), h.imag.ravel()]) * 1e6
    t0 = time.perf_counter()
    joint = BatchedGPRegressor(kernel="ard", n_restarts=0, rng=0).fit(xs, ys)
    t_joint = time.perf_counter() - t0
    pred = joint.predict(np.column_stack([np.full(grid.size, s_test), grid]))
    err_joint = np.sqrt(np.mean(np.abs((pred[:, 0] + 1j * pred[:, 1]) / 1e6 - truth) ** 2)) * 1e6
    print(f"{s_train.size} poses x {grid.size} bins (Re, Im); validation at s = {s_test} m")
    print(
        f"per-bin GPs ({2 * grid.size} GPs of {s_train.size} points): fit {t_bin:7.3f} s, RMSE {err_bin:.4f} um/N"
    )
    print(
        f"one GP over (s, f) ({xs.shape[0]} points)        : fit {t_joint:7.3f} s, RMSE {err_joint:.4f} um/N"
    )
    print(f"cost ratio joint / per-bin: {t_joint / t_bin:.1f} x")


if __name__ == "__main__":
    main()
