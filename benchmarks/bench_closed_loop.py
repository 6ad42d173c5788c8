"""Benchmark: the closed-loop simulation of one Table 10 cut (``control simulate milling``).

Run from the repository root::

    python benchmarks/bench_closed_loop.py

Printed, all measured in this run on the same cut (Test 3 at Position 1, 24 s of cutting,
24,000 samples, X and Z controlled): the per-sample reference loop (``method="per-sample"``)
with the old controller (gains interpolated from the schedule at every command, as
``control.studies`` did before), the blocked loop with that controller, and the blocked loop
with the gain table precomputed for the whole run (:class:`robovib.control.StateFeedback`),
first with a cold plant cache and then as the next controller on the same cut (the studies run
several controllers per cut and reuse the plant maps); ratios against the first. Goal
(issue 14): 5-10x.
"""

from __future__ import annotations

import time

import numpy as np

from robovib.control.controllers import ScheduledTable, StateFeedback
from robovib.control.schedule import schedule_gains
from robovib.milling.forces import ACETAL, CuttingConditions, MillingTool, milling_forces
from robovib.modal import ModalParameters
from robovib.sim import POSITION_1_S_M, LinearMove, VirtualRobot, plant, run_closed_loop


def main() -> None:
    robot = VirtualRobot()
    tool = MillingTool()
    cond = CuttingConditions(125.0, 0.3e-3, 6e-3, 6e-3)
    move = LinearMove("path", (POSITION_1_S_M - 0.025,), (POSITION_1_S_M + 0.025,))
    n = round(move.length_m / cond.feed_speed_m_per_s(tool) * 1000.0)
    local = milling_forces(np.arange(n) / 1000.0, tool, cond, ACETAL)
    force = np.column_stack([local[:, 1], -local[:, 0], local[:, 2]])
    grid = np.linspace(move.start[0], move.end[0], 6)
    sched = {
        a: schedule_gains(grid, [ModalParameters(9.5 + a, 1.2e6, 0.15) for _ in grid])
        for a in (0, 2)
    }

    def old_controller(t, disp, vel, coords):  # the pre-issue-15 study controller
        u = np.zeros(3)
        s = float(np.atleast_1d(coords)[0])
        for axis, sc in sched.items():
            w1, w2 = sc.gains_at(s)
            u[axis] = -(w1 * disp[axis] + w2 * vel[axis])
        return u

    table = StateFeedback(
        {a: ScheduledTable(grid, np.column_stack([sc.w1, sc.w2])) for a, sc in sched.items()}
    )
    runs = [
        ("per-sample loop, interpolating controller", dict(method="per-sample"), old_controller),
        ("blocked loop, interpolating controller", {}, old_controller),
        ("blocked loop, gain table, cold plant cache", {}, table),
        ("blocked loop, gain table, same cut again", {}, table),
    ]
    times, out = [], []
    for name, kw, ctrl in runs:
        if "cold" in name or "per-sample" in name:
            plant._CACHE.clear()
        t0 = time.perf_counter()
        rec = run_closed_loop(robot, move, force, 1000.0, ctrl, rng=0, **kw)
        times.append(time.perf_counter() - t0)
        out.append(rec.true_displacement_m)
        print(f"{name:45s}: {times[-1]:6.2f} s  ({times[0] / times[-1]:4.1f} x)")
    err = max(np.max(np.abs(o - out[0])) for o in out[1:]) / np.max(np.abs(out[0]))
    print(f"largest difference from the per-sample loop: {err:.1e} of the peak (rounding)")
    print(f"{n} samples, {n // 4} command periods; goal: 5-10x")


if __name__ == "__main__":
    main()
