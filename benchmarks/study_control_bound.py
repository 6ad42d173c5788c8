"""Issue 40: how much of the X and Z vibration any causal controller can remove (a bound).

For the Table 10 cuts of ``study_control_deploy.py`` (same paths, positions, forces and seeds:
the force of each cut is drawn in the same order from the same generator), the open-loop tip
displacement is split by superposition into the response to the periodic force (the cut with
every disturbance but the non-periodic force: speed error and drift, runout, engagement) and
the response to the rest (the low-pass non-periodic force and the 15 % white background).
Two ceilings on the RMS reduction [%] follow, per cut and direction:

* ``periodic only``: ``1 - rms(y_np) / rms(y_open)`` — a controller that removes the periodic
  response perfectly and leaves the non-periodic one as it is (what a repetitive / harmonic
  learner can do at best);
* ``causal``: the non-periodic response is also reduced by its best linear prediction from
  everything measured one loop delay earlier (true displacement and force, noise-free, lags
  ``delay .. delay + 60 ms``; least squares fitted on the cut itself, i.e. optimistic): what is
  left is ``y_np - prediction``; ``1 - rms(left) / rms(y_open)``. No causal controller whose
  correction lands ``delay`` after its last measurement does better (it would also need a
  perfect periodic cancellation, a perfect actuator model and no sensor noise).
* ``causal, measured``: the same prediction from what the sensors give (the tracker with its
  2 µm noise and 10 µm resolution, the force with its sensor noise and bias at this level),
  its coefficients fitted on the first half of the kept record and applied to the second
  half (out of sample); the reduction over the second half. Closer to what a feedback can
  get, still optimistic (the prediction is taken as cancellable: a feedback changes the
  response it predicts, and its actuator has the gain and delay errors).

    OMP_NUM_THREADS=1 nice python benchmarks/study_control_bound.py            # ~40 s
    OMP_NUM_THREADS=1 nice python benchmarks/study_control_bound.py --paths 2 --level 2 --delay-ms 48
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import replace
from pathlib import Path
from types import SimpleNamespace

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from study_control_deploy import PATHS

from robovib.control.path_design import ControlPath
from robovib.milling.forces import ACETAL, CuttingConditions, MillingTool
from robovib.sim import CutDisturbances, VirtualRobot, run_closed_loop
from robovib.studies.control.milling import TABLE_10_CONDITIONS
from robovib.studies.control.simulate import file_milling_positions


def _positions(path: tuple[str, str]):
    vertices = [[float(v) for v in p.split(",")] for p in path]
    shim = SimpleNamespace(path=ControlPath.through(("x_mm", "y_mm", "rz_deg"), vertices))
    return file_milling_positions(shim)


def _lagged(x: np.ndarray, lags) -> np.ndarray:
    n = x.shape[0]
    cols = []
    for lag in lags:
        s = np.zeros_like(x)
        s[lag:] = x[: n - lag]
        cols.append(s)
    return np.hstack(cols)


def _rotate(move, local: np.ndarray) -> np.ndarray:
    """Tool-frame force -> base frame, as ``milling_study`` does for a workspace move."""
    feed = move.feed_direction()
    normal = np.cross([0.0, 0.0, 1.0], feed)
    force = np.outer(local[:, 0], feed) + np.outer(local[:, 1], normal)
    force[:, 2] += local[:, 2]
    return force


def bound_rows(path, level: float, seed: int, delay_ms: float, history_ms: int = 60) -> list:
    robot, tool = VirtualRobot(), MillingTool()
    dist = CutDisturbances.parse([f"all={level:g}"])
    periodic = replace(dist, nonperiodic_rel=0.0)
    gen = np.random.default_rng(seed)
    sensors = np.random.default_rng([seed, 40])  # its own stream: the forces stay the study's
    d = round(delay_ms)
    rows = []
    for pos, move in _positions(path):
        for i, (rpm, fz, ap) in enumerate(TABLE_10_CONDITIONS):
            cond = CuttingConditions(rpm, fz, ap, 6e-3)
            n = round(move.length_m / cond.feed_speed_m_per_s(tool) * 1000.0)
            t = np.arange(n) / 1000.0
            total = _rotate(move, dist.cutting_force(t, tool, cond, ACETAL, rng=gen))
            total += gen.normal(size=total.shape) * 0.15 * total.std(axis=0)
            per = _rotate(move, periodic.cutting_force(t, tool, cond, ACETAL))
            rest = total - per
            y = {k: run_closed_loop(robot, move, f, 1000.0, None, tracker_noise_m=0.0,
                                    tracker_resolution_m=0.0).true_displacement_m
                 for k, f in (("open", total), ("np", rest))}  # fmt: skip
            keep = slice(n // 5, None)  # as milling_study: after the first fifth
            meas = sensors.normal(size=(n, 3)) * 2e-6  # tracker noise, then its 10 um resolution
            y_meas = np.round((y["np"] + meas) / 1e-5) * 1e-5
            f_meas = rest + sensors.normal(size=rest.shape) * np.hypot(0.5, dist.force_noise_n)
            f_meas += dist.force_bias_n
            half = n // 5 + (n - n // 5) // 2
            row = {"position": pos, "test": i + 1, "rpm": rpm}
            for axis, name in ((0, "x"), (2, "z")):
                y_open, y_np = y["open"][:, axis], y["np"][:, axis]
                past = _lagged(np.column_stack([y_np, rest]), range(d, d + history_ms, 2))
                a = np.column_stack([past, np.ones(n)])[keep]
                coef, *_ = np.linalg.lstsq(a, y_np[keep], rcond=None)
                left = y_np[keep] - a @ coef
                o = np.std(y_open[keep])
                row[f"{name}_np_share"] = np.std(y_np[keep]) / o
                row[f"{name}_periodic_only_pct"] = 100 * (1 - np.std(y_np[keep]) / o)
                row[f"{name}_causal_pct"] = 100 * (1 - np.std(left) / o)
                past = _lagged(np.column_stack([y_meas, f_meas]), range(d, d + history_ms, 2))
                a = np.column_stack([past, np.ones(n)])
                first, second = slice(n // 5, half), slice(half, None)
                coef, *_ = np.linalg.lstsq(a[first], y_np[first], rcond=None)
                left = y_np[second] - a[second] @ coef
                row[f"{name}_measured_pct"] = 100 * (1 - np.std(left) / np.std(y_open[second]))
            rows.append(row)
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--paths", type=int, nargs="+", default=[1, 2], choices=sorted(PATHS))
    ap.add_argument("--level", type=float, default=1.0, help="disturbance level (x realistic)")
    ap.add_argument("--seed", type=int, default=0, help="simulation seed (as the deploy study)")
    ap.add_argument("--delay-ms", type=float, default=None,
                    help="true loop delay [ms] (default 32 + 8 x level)")  # fmt: skip
    a = ap.parse_args()
    delay = 32.0 + 8.0 * a.level if a.delay_ms is None else a.delay_ms
    t0 = time.perf_counter()
    print(f"ceilings on the RMS reduction [%] at {a.level:g}x, seed {a.seed}, delay {delay:g} ms:"
          " mean over the 8 cuts (lowest cut); np/open = rms share of the non-periodic response")  # fmt: skip
    print("| path | position | dir | np/open | periodic only | causal | causal, measured |")
    print("|---|---|---|---|---|---|---|")
    for p in a.paths:
        rows = bound_rows(PATHS[p], a.level, a.seed, delay)
        for pos in ("Position 1", "Position 2"):
            sel = [r for r in rows if r["position"] == pos]
            for d in ("x", "z"):
                share = np.mean([r[f"{d}_np_share"] for r in sel])
                cells = []
                for key in ("periodic_only", "causal", "measured"):
                    v = [r[f"{d}_{key}_pct"] for r in sel]
                    cells.append(f"{np.mean(v):.1f} ({np.min(v):.1f})")
                print(f"| {p} | {pos} | {d.upper()} | {share:.2f} | {' | '.join(cells)} |")
    print(f"total {time.perf_counter() - t0:.0f} s", file=sys.stderr)


if __name__ == "__main__":
    main()
