"""Benchmark (issue 27): a 200-speed 2-DOF stability chart at a pose, fast SDM against today's SDM.

Run from the repository root::

    python benchmarks/bench_sdm.py [--speeds 200] [--repeats 3] [--ref-steps 320]

For each pose of the shipped chapter-3 pose model (its predicted feed and normal modes, 25.4 mm
2-flute tool, 6 mm radial depth, down-milling, Al 7075, 100-3000 rpm) it prints, measured in the
same run on one core (one BLAS thread, pinned to one CPU where the OS allows):

* the wall and CPU time of the chart with the dense eigenvalue solver and a depth scan at every
  speed (today's SDM: every eigenvalue of the monodromy matrix, ``eigensolver="dense",
  warm_start=False``) and with the defaults (Arnoldi iterations, depths warm-started from the
  neighbouring speeds), the median of ``--repeats`` runs, and their ratio (both use the
  balanced matrix exponential, so the ratio understates the gain over the unbalanced SDM);
* the largest relative difference of the two charts' critical depths;
* the largest relative difference of the fast chart from the converged SDM limit at every
  speed: the same method with ``--ref-steps`` steps across the cut and a 1e-5 depth tolerance.

Target: within 1 % of the converged limit at every speed in <= 1 s on one core.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np

from robovib.gp.chapter3_model import load_chapter3_predictor
from robovib.milling import ALUMINIUM_7075
from robovib.milling.chart import cutting_setup
from robovib.milling.sdm import sdm_lobes
from robovib.milling.uncertainty import mode_distribution_at_pose

POSES = ((2400.0, 0.0, 45.0), (2700.0, 0.0, 0.0), (2100.0, 600.0, 90.0))


def _timed(fn, repeats: int):
    """Median wall and CPU seconds of ``repeats`` calls, and the last result."""
    walls, cpus, out = [], [], None
    for _ in range(repeats):
        t0, c0 = time.perf_counter(), time.process_time()
        out = fn()
        walls.append(time.perf_counter() - t0)
        cpus.append(time.process_time() - c0)
    return statistics.median(walls), statistics.median(cpus), out


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--speeds", type=int, default=200, help="speeds of the chart")
    ap.add_argument("--repeats", type=int, default=3, help="timed runs of each chart")
    ap.add_argument("--ref-steps", type=int, default=320, help="steps of the converged SDM")
    opts = ap.parse_args(argv)
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})
    model = load_chapter3_predictor()
    tool, cond, coef = cutting_setup(
        ALUMINIUM_7075, diameter_m=0.0254, n_flutes=2, helix_deg=30.0, radial_depth_m=6e-3
    )
    rpm = np.linspace(100.0, 3000.0, opts.speeds)
    load = os.getloadavg()
    print(f"load average before: {load[0]:.2f}; {opts.speeds} speeds, 40 steps across the cut, "
          f"one core; converged reference: {opts.ref_steps} steps, rtol 1e-5")  # fmt: skip
    head = (f"{'pose x,y,rz':>18s} {'fn x/y [Hz]':>12s} {'dense s':>8s} {'arnoldi s':>9s} "
            f"{'ratio':>6s} {'dense cpu':>9s} {'arn. cpu':>8s} {'ratio':>6s} "
            f"{'|fast-dense|':>12s} {'|fast-conv|':>11s} {'|dense-conv|':>12s}")  # fmt: skip
    print(head)
    ok_wall = ok_cpu = True
    for pose in POSES:
        dist = mode_distribution_at_pose(model, pose)
        mx, my = (dist["x"].mean,), (dist["y"].mean,)

        def chart(solver, mx=mx, my=my):
            # "dense": the reference search (scan at every speed, every eigenvalue);
            # "arnoldi": the fast one (Arnoldi multiplier, depths warm-started from neighbours)
            return sdm_lobes(mx, my, tool, cond, coef, rpm, eigensolver=solver,
                             warm_start=solver != "dense").a_lim_m  # fmt: skip

        t_dense, c_dense, a_dense = _timed(lambda: chart("dense"), opts.repeats)
        t_fast, c_fast, a_fast = _timed(lambda: chart("arnoldi"), opts.repeats)
        ref = sdm_lobes(mx, my, tool, cond, coef, rpm, steps_per_period=opts.ref_steps,
                        max_steps=max(200, opts.ref_steps), rtol=1e-5).a_lim_m  # fmt: skip
        d_fd = float(np.max(np.abs(a_fast / a_dense - 1)))
        d_fc = float(np.max(np.abs(a_fast / ref - 1)))
        d_dc = float(np.max(np.abs(a_dense / ref - 1)))
        ok_wall &= t_fast <= 1.0 and d_fc <= 0.01
        ok_cpu &= c_fast <= 1.0 and d_fc <= 0.01
        fn = f"{mx[0].natural_frequency_hz:.1f}/{my[0].natural_frequency_hz:.1f}"
        where = ",".join(f"{v:g}" for v in pose)
        print(f"{where:>18s} {fn:>12s} {t_dense:8.3f} {t_fast:9.3f} {t_dense / t_fast:6.2f} "
              f"{c_dense:9.3f} {c_fast:8.3f} {c_dense / c_fast:6.2f} "
              f"{d_fd:12.2e} {d_fc:11.2e} {d_dc:12.2e}")  # fmt: skip
    load = os.getloadavg()
    print(f"load average after: {load[0]:.2f}")
    print("target (<= 1 s, within 1 % of the converged SDM at every speed): "
          f"wall {'met' if ok_wall else 'NOT met'}, CPU {'met' if ok_cpu else 'NOT met'} "
          "(on a machine busier than one job per core, CPU seconds are the fairer figure)")  # fmt: skip


if __name__ == "__main__":
    main()
