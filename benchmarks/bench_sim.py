"""Benchmark: a 600 mm milling pass of the virtual robot at 1 kHz (thesis §3.5 conditions).

Run from the repository root::

    python benchmarks/bench_sim.py

Prints the wall time of the whole pass (cutting forces, pose-varying truth, time-varying
dynamics of all modes, sensors) — goal: well under a second on one core — and, for the
dynamics alone, the ratio against the plain sequential per-sample recursion of the same
time-varying system (vectorised over modes), measured in the same run, with their agreement.
"""

from __future__ import annotations

import time

import numpy as np

from robovib.milling import ALUMINIUM_7075, CuttingConditions, MillingTool
from robovib.sim import LinearMove, VirtualRobot, affine_scan, simulate_milling, zoh_transition


def sequential(p, b):
    x = np.zeros(p[0].shape[0])
    v = np.zeros_like(x)
    out = np.empty(p[0].shape)
    for i in range(p[0].shape[1]):
        x, v = (
            p[0][:, i] * x + p[1][:, i] * v + b[0][:, i],
            p[2][:, i] * x + p[3][:, i] * v + b[1][:, i],
        )
        out[:, i] = x
    return out


def main() -> None:
    robot = VirtualRobot()
    tool = MillingTool()
    cond = CuttingConditions(1750, 0.058e-3, 3e-3, 25.4e-3)
    move = LinearMove("workspace", (2.1, 0.0, 0.0), (2.7, 0.0, 0.0))
    simulate_milling(
        robot,
        LinearMove("workspace", (2.1, 0.0, 0.0), (2.11, 0.0, 0.0)),
        tool,
        cond,
        ALUMINIUM_7075,
        rng=0,
    )
    t0 = time.perf_counter()
    run = simulate_milling(robot, move, tool, cond, ALUMINIUM_7075, rng=0)
    t_pass = time.perf_counter() - t0
    n = run.time_s.size
    print(
        f"600 mm pass at {cond.feed_speed_m_per_s(tool) * 1e3:.2f} mm/s: {n} samples at 1 kHz, 7 modes"
    )
    print(
        f"whole pass (forces + truth + dynamics + sensors): {t_pass:.3f} s  (goal: well under 1 s)"
    )

    rng = np.random.default_rng(0)
    fn = np.vstack([np.linspace(16, 23, n), np.linspace(40, 60, n)] * 3 + [np.linspace(63, 64, n)])
    k = np.full_like(fn, 4e6)
    z = np.full_like(fn, 0.08)
    p00, p01, p10, p11, g0, g1 = zoh_transition(fn, k, z, 1e-3)
    force = rng.normal(size=n) * 100
    b = (g0 * force, g1 * force)
    t0 = time.perf_counter()
    x_scan, _ = affine_scan(p00, p01, p10, p11, *b)
    t_scan = time.perf_counter() - t0
    t0 = time.perf_counter()
    x_seq = sequential((p00, p01, p10, p11), b)
    t_seq = time.perf_counter() - t0
    err = np.max(np.abs(x_scan[:, 1:] - x_seq)) / np.max(np.abs(x_seq))
    print(f"dynamics, blocked scan      : {t_scan:.3f} s")
    print(f"dynamics, sequential loop   : {t_seq:.3f} s")
    print(
        f"speed-up                    : {t_seq / t_scan:.1f} x   (max relative difference {err:.1e})"
    )


if __name__ == "__main__":
    main()
