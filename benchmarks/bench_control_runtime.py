"""Issue 40: time of one ``RuntimeController.step`` (the call an RSI bridge makes every 4 ms).

A controller file is designed from the virtual robot's path model along the whole chapter-4
path and driven, outside the simulator, with the force and tracker samples of Table 10 cut 1
(125 rpm, 1 kHz, 4 samples per cycle) while the path coordinate moves along the cut. Every
``step`` is timed; the run is repeated ``repeats`` times and each cycle's fastest time kept
(the machine's other load preempts single calls). The reference, measured in the same run, is
the same controller run as a planned-run controller (gains tabulated for the run, no per-step
lookup): the ratio is what the run-time lookup costs. Prints p50, p99 and max [ms] against the
4 ms RSI budget and the 0.5 ms p99 target.

    OMP_NUM_THREADS=1 python benchmarks/bench_control_runtime.py [--names adaptive+force,robust]
    OMP_NUM_THREADS=1 python benchmarks/bench_control_runtime.py --file ctl.json   # a file's own

``--file`` times a controller file instead (e.g. one ``study_control_deploy.py --workdir``
wrote: designed from a campaign model, with ``gains.feedback``), over a 50 mm stretch at the
middle of its path. The reference always runs the file's own tracker, guard and learner
settings.
"""

from __future__ import annotations

import argparse
import time
import tracemalloc

import numpy as np

from robovib.control.controller_file import design_controller
from robovib.control.controllers import ScheduledTable  # noqa: F401  (warm the import)
from robovib.control.design import assemble_controller
from robovib.control.path_design import ControlPath
from robovib.control.runtime import RuntimeController
from robovib.milling.forces import ACETAL, CuttingConditions, MillingTool
from robovib.sim import POSITION_1_S_M, REALISTIC_LEVELS, VirtualRobot, path_modal_model

BUDGET_MS = 4.0
TARGET_P99_MS = 0.5


def _times(step, n_cmd, repeats):
    best = np.full(n_cmd, np.inf)
    for _ in range(repeats):
        reset, call = step()
        reset()
        for k in range(n_cmd):
            t0 = time.perf_counter()
            call(k)
            best[k] = min(best[k], time.perf_counter() - t0)
    return best * 1e3


def main(names=("adaptive+force", "feedforward+robust", "robust"), n_cmd: int = 2500,
         repeats: int = 3, file=None) -> None:  # fmt: skip
    if file is None:
        model = path_modal_model(VirtualRobot(), directions=("x", "z"))
        path = ControlPath.through(("s_m",), [[0.0], [1.235]])
    tool, cond = MillingTool(), CuttingConditions(125.0, 0.5e-3, 6e-3, 6e-3)
    t = np.arange(4 * n_cmd) / 1000.0
    local = REALISTIC_LEVELS.cutting_force(t, tool, cond, ACETAL, rng=0)
    force = np.column_stack([local[:, 1], -local[:, 0], local[:, 2]])
    gen = np.random.default_rng(1)
    tracker_m = 2e-5 * np.sin(2 * np.pi * 4.17 * t)[:, None] + 2e-6 * gen.normal(size=force.shape)
    tracker_mm = tracker_m * 1e3
    if file is None:
        s = POSITION_1_S_M - 0.025 + 0.05 * np.arange(n_cmd) / n_cmd
        designs = [(name, None) for name in names]
    else:
        from robovib.control.controller_file import load_controller

        rt0 = load_controller(file)
        mid = float(np.median(rt0.tables.grid))
        s = mid - 0.025 + 0.05 * np.arange(n_cmd) / n_cmd
        designs = [(f"{rt0.name} (file)", rt0.doc)]
    blocks = [(max(0, 4 * k - 3), 4 * k + 1) for k in range(n_cmd)]
    print(f"per-step time over {n_cmd} cycles, best of {repeats} [ms]; budget {BUDGET_MS} ms, "
          f"p99 target {TARGET_P99_MS} ms")  # fmt: skip
    print(f"{'controller':22s} {'p50':>7s} {'p99':>7s} {'max':>7s} {'planned p99':>12s} "
          f"{'ratio':>6s} {'alloc/step':>11s}")  # fmt: skip
    for name, doc in designs:
        if doc is None:
            doc = design_controller(model, path, name, spindle_rpm=125.0, teeth=tool.n_flutes)
        rt = RuntimeController(doc)
        # the reference runs the file's own settings (a designed file's differ from
        # assemble_controller's defaults: loop identification, pooling, 2-period lag)
        settings = {"tracker": rt.tracker_settings, "guard": rt.guard_settings,
                    "learner": rt.learner_settings}  # fmt: skip

        def live(rt=rt):
            def call(k):
                lo, hi = blocks[k]
                rt.step_arrays(force[lo:hi], tracker_mm[lo:hi], s[k])

            return (lambda: rt.reset(spindle_rpm=125.0, max_duration_s=(n_cmd + 2) * 0.004)), call

        def planned(rt=rt, settings=settings):
            ctl = assemble_controller(rt.name, rt.tables, excitation_period_s=rt.excitation_period_s,
                                      teeth=tool.n_flutes, **settings)  # fmt: skip

            def call(k):
                lo, hi = blocks[k]
                ctl.command(k, tracker_m[lo:hi], force[lo:hi])

            return (lambda: ctl.reset(s, 0.004, 1000.0)), call

        tl = _times(live, n_cmd, repeats)
        tp = _times(planned, n_cmd, repeats)
        # memory held after the steps (buffers are allocated by reset): growth per step
        start, step_once = live()
        start()
        tracemalloc.start()
        for j in range(n_cmd // 4):
            step_once(j)
        before = tracemalloc.get_traced_memory()[0]
        for j in range(n_cmd // 4, n_cmd):
            step_once(j)
        grown = (tracemalloc.get_traced_memory()[0] - before) / (n_cmd - n_cmd // 4)
        tracemalloc.stop()
        p50, p99, mx = np.percentile(tl, 50), np.percentile(tl, 99), tl.max()
        print(f"{name:22s} {p50:7.3f} {p99:7.3f} {mx:7.3f} {np.percentile(tp, 99):12.3f} "
              f"{p99 / np.percentile(tp, 99):6.2f} {grown:9.1f} B")  # fmt: skip


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--names", default="adaptive+force,feedforward+robust,robust")
    ap.add_argument("--cycles", type=int, default=2500)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--file", default=None, help="time this controller file instead")
    a = ap.parse_args()
    main(tuple(a.names.split(",")), a.cycles, a.repeats, a.file)
