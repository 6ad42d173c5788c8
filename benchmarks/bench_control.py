"""Benchmark: the control-cycle path — modal prediction + gains at a new pose.

Run from the repository root::

    python benchmarks/bench_control.py

Goal: modal prediction + gains < 100 µs (10 % of a 1 kHz cycle). Printed: the GP prediction of
all 9 modal outputs at a new pose (``predict_one``), the gain lookup in a precomputed schedule
(interpolation and polynomial), and — as the reference measured in the same run — solving the
Riccati equation afresh at the pose (SciPy), with the ratio.

Second part: the per-cycle compute of every run-time controller of
:mod:`robovib.control.controllers` (one ``command`` call, X and Z controlled, 4 tracker and
force samples per 4 ms cycle), against the 4 ms command period (budget: well under it).
"""

from __future__ import annotations

import time

import numpy as np

from robovib.control import design_lqr
from robovib.control.schedule import schedule_gains
from robovib.modal import ModalParameters
from robovib.studies.chapter3 import fit_chapter3_regressor


def per_call(fn, n=2000):
    fn()
    t0 = time.perf_counter()
    for _ in range(n):
        fn()
    return (time.perf_counter() - t0) / n


def main() -> None:
    model = fit_chapter3_regressor(mode_switch=False)
    pose = np.array([2450.0, 120.0, 60.0])
    t_gp = per_call(lambda: model.predict_one(pose))
    mean, _ = model.predict_one(pose)
    mode = ModalParameters.from_fn_k_c(mean[0], mean[1] * 1e6, mean[2] * 1e3)
    s = np.linspace(0, 0.9, 20)
    sched = schedule_gains(
        s, [ModalParameters(10 - 3 * x, (1.4 - 0.6 * x) * 1e6, 0.15) for x in s], r=100.0
    )
    t_interp = per_call(lambda: sched.gains_at(0.437))
    t_poly = per_call(lambda: sched.gains_at(0.437, "poly"))
    t_dare = per_call(lambda: design_lqr(mode), n=300)
    print(f"GP predict_one, 9 modal outputs      : {t_gp * 1e6:7.1f} µs")
    print(f"gain lookup (interpolation)          : {t_interp * 1e6:7.1f} µs")
    print(f"gain lookup (polynomial, Eq. 28-29)  : {t_poly * 1e6:7.1f} µs")
    print(
        f"prediction + lookup                  : {(t_gp + t_interp) * 1e6:7.1f} µs  (goal < 100 µs)"
    )
    print(
        f"reference: fresh Riccati solve       : {t_dare * 1e6:7.1f} µs  ({t_dare / t_interp:.0f} x the lookup)"
    )


def controllers_per_cycle() -> None:
    from robovib.control.design import CONTROLLERS, build_controllers
    from robovib.sim import POSITION_1_S_M, VirtualRobot, path_modal_model

    model = path_modal_model(VirtualRobot(), n_points=10, n_hits=2)
    grid = np.linspace(POSITION_1_S_M - 0.025, POSITION_1_S_M + 0.025, 6)
    ctrls = build_controllers(model, {0: "x", 2: "z"}, grid, excitation_period_s=0.12,
                              s_start=grid[0], s_end=grid[-1])  # fmt: skip
    n_cmd = 3000
    coords = np.linspace(grid[0], grid[-1], n_cmd)
    gen = np.random.default_rng(0)
    tracker = np.round(gen.normal(size=(n_cmd, 4, 3)) * 1e-4 / 1e-5) * 1e-5
    force = gen.normal(size=(n_cmd, 4, 3)) * 100.0
    t_ref = per_call(lambda: np.interp(0.437, grid, grid), n=20000)
    print(f"\nper-cycle compute of each controller (budget: 4 ms command period); "
          f"reference np.interp call: {t_ref * 1e6:.1f} µs")  # fmt: skip
    for name in CONTROLLERS:
        c = ctrls[name]
        c.reset(coords, 0.004, 1000.0)
        c.command(0, tracker[0, -1:], force[0, -1:])
        t0 = time.perf_counter()
        for k in range(1, n_cmd):
            c.command(k, tracker[k], force[k])
        dt = (time.perf_counter() - t0) / (n_cmd - 1)
        print(f"  {name:20s}: {dt * 1e6:7.1f} µs per cycle  ({dt / 0.004 * 100:5.2f} % of 4 ms, "
              f"{dt / t_ref:5.1f} x np.interp)")  # fmt: skip


if __name__ == "__main__":
    main()
    controllers_per_cycle()
