"""Benchmark: chatter stability charts (semi-discretization) per pose, on one core and on Dask.

Run from the repository root::

    python benchmarks/bench_chatter.py [--poses 6] [--speeds 200] [--figure sdm_vs_zoa.png]
                                       [--simulate]

Prints, measured in the same run:

* seconds per pose for a ``--speeds``-speed SDM chart on one core (Dask ``sync`` scheduler),
  and the speed-up of the same map with 2 local worker processes;
* the cost of the zero-order method for the same chart and the SDM / ZOA cost ratio;
* with ``--simulate``: the simulated stability limit (regenerative time-domain simulation,
  bisection on the depth) against the SDM prediction at two poses of the virtual robot;
* with ``--figure``: the published 1-DOF benchmark (a/D = 0.05, down-milling) SDM vs ZOA chart.

Poses come from the virtual robot's dominant modes (a pose model with a known truth).
"""

from __future__ import annotations

import argparse
import os
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np

from robovib.milling import CuttingCoefficients, CuttingConditions, MillingTool
from robovib.milling.lobes import insperger_benchmark, plot_method_comparison
from robovib.milling.maps import workspace_lobe_map
from robovib.milling.sdm import sdm_lobes
from robovib.sim import VirtualRobot, simulated_stability_limit

AL = CuttingCoefficients(ktc=796e6, krc=168e6, kac=0.0)
TOOL = MillingTool()
COND = CuttingConditions(1750, 0.058e-3, 3e-3, 6e-3, down_milling=True)


class TruthModel:
    """Dominant modes of the virtual robot as a pose model (thesis units, inputs mm/mm/deg)."""

    def __init__(self) -> None:
        self.ws = VirtualRobot().workspace

    def predict(self, x, return_std=False):
        c = np.atleast_2d(x) * np.array([1e-3, 1e-3, 1.0])
        cols = []
        for d in ("x", "y", "z"):
            m = self.ws.modes(c, d).dominant()
            cols += [
                m.fn_hz[:, 0],
                m.stiffness_n_per_m[:, 0] / 1e6,
                m.damping_ns_per_m()[:, 0] / 1e3,
            ]
        mean = np.column_stack(cols)
        return (mean, 0 * mean) if return_std else mean


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--poses", type=int, default=6)
    ap.add_argument("--speeds", type=int, default=200)
    ap.add_argument("--figure", default=None)
    ap.add_argument("--simulate", action="store_true")
    args = ap.parse_args()
    model = TruthModel()
    xs = np.linspace(2100, 2700, args.poses)
    rpm = np.linspace(1000, 6000, args.speeds)
    common = dict(scheduler=None, poses_per_chunk=1)
    workspace_lobe_map(model, xs[:1], [0.0], [45.0], rpm[:5], TOOL, COND, AL, scheduler="sync")
    t0 = time.perf_counter()
    one = workspace_lobe_map(model, xs, [0.0], [45.0], rpm, TOOL, COND, AL,
                             **{**common, "scheduler": "sync"})  # fmt: skip
    t_one = time.perf_counter() - t0
    t0 = time.perf_counter()
    two = workspace_lobe_map(model, xs, [0.0], [45.0], rpm, TOOL, COND, AL,
                             **{**common, "scheduler": "processes"}, n_workers=2)  # fmt: skip
    t_two = time.perf_counter() - t0
    assert np.allclose(one.a_lim_m.values, two.a_lim_m.values, equal_nan=True)
    t0 = time.perf_counter()
    workspace_lobe_map(model, xs, [0.0], [45.0], rpm, TOOL, COND, AL,
                       **{**common, "scheduler": "threads"}, n_workers=2)  # fmt: skip
    t_thr = time.perf_counter() - t0
    t0 = time.perf_counter()
    workspace_lobe_map(model, xs, [0.0], [45.0], rpm, TOOL, COND, AL, method="zoa",
                       scheduler="sync", poses_per_chunk=1)  # fmt: skip
    t_zoa = time.perf_counter() - t0
    n = args.poses
    print(f"machine: {os.cpu_count()} CPUs, load average {os.getloadavg()[0]:.1f}")
    print(f"SDM chart, {args.speeds} speeds: {t_one / n:.2f} s per pose on one core (sync)")
    print(
        f"  2 local worker processes: {t_two / n:.2f} s per pose -> speed-up {t_one / t_two:.2f}x"
    )
    print(f"  2 local threads: {t_thr / n:.2f} s per pose -> speed-up {t_one / t_thr:.2f}x")
    print(
        f"ZOA chart, same speeds: {t_zoa / n:.3f} s per pose -> SDM costs {t_one / t_zoa:.0f}x ZOA"
    )
    if args.simulate:
        ws = VirtualRobot().workspace
        for pose in [(2.4, 0.0, 45.0), (2.2, 0.4, 0.0)]:
            mx, my = ws.modes([pose], "x").at(0), ws.modes([pose], "y").at(0)
            a = sdm_lobes(mx, my, TOOL, COND, AL, [1750.0]).a_lim_m[0]
            t0 = time.perf_counter()
            lo, hi = simulated_stability_limit(mx, my, TOOL, COND, AL, (0.7 * a, 1.4 * a),
                                               n_bisections=4, n_tooth_periods=300,
                                               steps_per_tooth=60)  # fmt: skip
            mid = 0.5 * (lo + hi)
            print(f"pose {pose}: SDM limit {a * 1e3:.3f} mm, simulated {lo * 1e3:.3f}-{hi * 1e3:.3f} mm "
                  f"(mid {mid * 1e3:.3f} mm, {100 * (mid / a - 1):+.1f} %), {time.perf_counter() - t0:.0f} s")  # fmt: skip
    if args.figure:
        import matplotlib

        matplotlib.use("Agg")
        sdm, zoa = insperger_benchmark()
        fig = plot_method_comparison(
            [sdm, zoa],
            title="1-DOF benchmark (2 teeth, a/D = 0.05, down-milling): SDM vs ZOA",
        )
        fig.tight_layout()
        fig.savefig(args.figure, dpi=130)
        flip = sdm.kind == "flip"
        print(f"figure {args.figure}: {flip.sum()} of {flip.size} speeds on flip lobes; "
              f"ZOA/SDM there up to {np.max(zoa.a_lim_m[flip] / sdm.a_lim_m[flip]):.1f}x")  # fmt: skip


if __name__ == "__main__":
    main()
