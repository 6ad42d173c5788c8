"""Issue 25: compute time of one command cycle of the milling controllers (budget: 4 ms).

Each controller is designed for cut 1 at Position 1 and driven, outside the simulator, with the
tracker and force samples of that cut (1 kHz, 4 per cycle); the time of every ``command`` call
is measured. The run is repeated ``repeats`` times and each cycle's fastest time kept (the
machine's other load preempts single calls). Prints mean, 99th percentile and max [ms].

    OMP_NUM_THREADS=1 python benchmarks/bench_control_cycle.py
"""

from __future__ import annotations

import time

import numpy as np

from robovib.control.design import build_controllers
from robovib.milling.forces import ACETAL, CuttingConditions, MillingTool
from robovib.sim import POSITION_1_S_M, REALISTIC_LEVELS, VirtualRobot, path_modal_model

NAMES = (
    "feedforward+robust",
    "repetitive",
    "adaptive",
    "adaptive+robust",
    "adaptive-feedforward",
    "adaptive+force",
)


def main(n_cmd: int = 2500, repeats: int = 3) -> None:
    robot = VirtualRobot()
    model = path_modal_model(robot, directions=("x", "z"))
    tool, cond = MillingTool(), CuttingConditions(125.0, 0.5e-3, 6e-3, 6e-3)
    grid = np.linspace(POSITION_1_S_M - 0.025, POSITION_1_S_M + 0.025, 6)
    ctrls = build_controllers(model, {0: "x", 2: "z"}, grid, names=NAMES,
                              excitation_period_s=1 / cond.tooth_passing_hz(tool), teeth=tool.n_flutes)  # fmt: skip
    t = np.arange(4 * n_cmd) / 1000.0
    local = REALISTIC_LEVELS.cutting_force(t, tool, cond, ACETAL, rng=0)
    force = np.column_stack([local[:, 1], -local[:, 0], local[:, 2]])
    y = np.random.default_rng(0).normal(size=force.shape) * 1e-5
    coords = np.linspace(grid[0], grid[-1], n_cmd)
    print(
        f"{'controller':24s} mean [ms]   p99 [ms]   max [ms]  (command period 4 ms, {n_cmd} cycles)"
    )
    for name in NAMES:
        c = ctrls[name]
        dt = np.full(n_cmd, np.inf)
        for _ in range(repeats):
            c.reset(coords, 0.004, 1000.0)
            for k in range(n_cmd):
                i0 = 4 * k
                a = max(0, i0 - 3)
                t0 = time.perf_counter()
                c.command(k, y[a : i0 + 1], force[a : i0 + 1])
                dt[k] = min(dt[k], time.perf_counter() - t0)
        ms = dt * 1e3
        print(f"{name:24s} {ms.mean():9.3f} {np.percentile(ms, 99):10.3f} {ms.max():10.3f}")


if __name__ == "__main__":
    main()
