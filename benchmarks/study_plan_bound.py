"""Issue 39: the MRR gain a planner can attain at all, from the virtual robot's truth.

The Done-when asks for a planned MRR >= 1.3x that of the best fixed Rz and speed. Before
blaming the model or the planner, this measures the *attainable* gain: the planner's own
optimiser (:func:`robovib.milling.planning.choose_configurations`, Rz and speed jointly per
segment under the Rz-rate limit) and its fixed comparison
(:func:`~robovib.milling.planning.fixed_configuration`, the best single Rz and speed under the
same depth rule) are fed the *truth's* stability limits instead of a model's quantile: the
zero-order limit (:func:`robovib.milling.structures.zoa_limits`, the batched ZOA tested against
``stability_lobes``) of every mode of the virtual robot's truth at each segment midpoint, Rz and
speed (X modes along the feed, Y normal; the study's tool, material and engagement), capped at
``--max-depth-mm``. A perfect model gives the planner exactly these limits, so the oracle ratio

    (mean MRR of the best plan) / (mean MRR of the best fixed Rz and speed)

is an upper bound on what any model can make the planner claim *honestly* (the study compares
at the same P(stable); a model's quantile adds noise along the path, not attainable gain). The
mean MRR is the volume over the machining time (``planning`` module docs), for both depth rules:
``segment`` (each segment as deep as allowed) and ``path`` (one depth for the whole path).

Paths: ``--paths`` straight paths of ``--segments`` segments with random ends in the study's
region (X 2150-2650 mm, Y -250-550 mm; ``--region workspace``: the whole chapter-3 workspace,
X 2100-2700, Y -300-600), from ``--seed`` (not the study's paths). Robots: the thesis robot and
``--robot-seeds`` of the family (``robovib.sim.family``). Speed ranges: ``--rpm-ranges`` (the
study's 1000-3500 rpm and wider ones a user could allow: the lobes of the ~63 Hz switching X
mode and the secondary modes of a 2-flute tool lie at 600-2000 rpm, the dominant modes' at
200-700 rpm). ``--check-time-domain N`` compares the ZOA limit with the regenerative
time-domain simulation of the truth (``sim.simulated_stability_limit``) at N random
(pose, speed) points.

    nice python benchmarks/study_plan_bound.py                      # thesis robot (~20 s)
    nice python benchmarks/study_plan_bound.py --paths 20 --robot-seeds 0-11 \
        --rpm-ranges 1000-3500,300-3500,1000-2000,1000-6000           # 13 robots (~4 min)

Measured (eleventh session; mean over paths): on the thesis robot the oracle ratio is
1.00-1.06 for the study's 1000-3500 rpm (the top speed is past the last lobe of every mode and
wins at every pose; Rz moves the limit little outside the switch region), at most 1.12 for any
range tried (1000-2000 rpm, one depth per path, where the ~63 Hz mode's pocket matters but the
MRR is ~3x lower than at 3500 rpm). Over 12 robots of the family it is 1.00-1.11 for all but
robot 6 (1.24 at the 20 mm cap, 1.30 at 60 mm, one depth per path, 1000-3500 rpm; 30-40 % of
its paths >= 1.3): its dominant modes favour Rz ~ 70-80 deg (a narrow peak of the limit at
3500 rpm) while its switching X mode (Rz_s 71 deg, x_s 2.62 m) forbids that Rz at the far end,
so a fixed Rz must compromise and the plan reorients. Paths across the whole workspace
(``--region workspace``) give the same picture. The ZOA differs from the time-domain truth by
-25 to +30 % pointwise (``--check-time-domain 6``), so these are the bound of the zero-order
physics, not of every detail of the simulation (``study_plan_bound_sdm.py``: the same oracle
from the truth's multi-mode SDM limits and from its time-domain simulation).
"""

from __future__ import annotations

import argparse
import time

import numpy as np

REGIONS = {"study": ((2150.0, 2650.0), (-250.0, 550.0)),
           "workspace": ((2100.0, 2700.0), (-300.0, 600.0))}  # fmt: skip


def truth_limits(robot, poses_mm_deg, rpm, tool, cond, coef, points_per_decade=150.0):
    """(P, J) ZOA limits [m] of the truth's modes (inf: no lobe in reach)."""
    from robovib.milling.structures import zoa_limits

    c = np.column_stack([poses_mm_deg[:, :2] / 1e3, poses_mm_deg[:, 2]])
    mx, my = robot.workspace.modes(c, "x"), robot.workspace.modes(c, "y")
    fn = np.concatenate([mx.fn_hz, my.fn_hz], axis=1)
    k = np.concatenate([mx.stiffness_n_per_m, my.stiffness_n_per_m], axis=1)
    z = np.concatenate([mx.damping_ratio, my.damping_ratio], axis=1)
    feed = np.arange(fn.shape[1]) < mx.fn_hz.shape[1]
    return zoa_limits(fn, k, z, feed, rpm, tool, cond, coef, points_per_decade=points_per_decade)


def parse_ranges(text: str) -> list[tuple[float, float]]:
    out = []
    for item in text.split(","):
        lo, hi = (float(v) for v in item.split("-"))
        out.append((lo, hi))
    return out


def parse_seeds(text: str) -> list[int | None]:
    seeds: list[int | None] = [None]
    for item in filter(None, text.split(",")):
        if "-" in item:
            a, b = (int(v) for v in item.split("-"))
            seeds += list(range(a, b + 1))
        else:
            seeds.append(int(item))
    return seeds


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--paths", type=int, default=40)
    ap.add_argument("--segments", type=int, default=20)
    ap.add_argument("--seed", type=int, default=101, help="paths (not the study's seeds)")
    ap.add_argument("--region", choices=tuple(REGIONS), default="study")
    ap.add_argument("--robot-seeds", default="", help="e.g. 0-11 (the thesis robot always)")
    ap.add_argument("--rpm-ranges", default="1000-3500,300-3500,1000-2000,1000-6000,300-12000")
    ap.add_argument("--speeds-per-1000-rpm", type=float, default=8.0,
                    help="speed grid density (the planner's default: 12 over 2500 rpm)")  # fmt: skip
    ap.add_argument("--rz-step", type=float, default=10.0, help="Rz grid step over 0-180 deg")
    ap.add_argument("--max-rz-rate", type=float, default=1.0, help="deg per mm of path")
    ap.add_argument("--max-depth-mm", default="20,60", help="depth caps [mm] (the tool)")
    ap.add_argument("--check-time-domain", type=int, default=0)
    args = ap.parse_args(argv)

    from robovib.milling import ALUMINIUM_7075, CuttingConditions, MillingTool
    from robovib.milling.planning import choose_configurations, fixed_configuration
    from robovib.sim import VirtualRobot

    t0 = time.perf_counter()
    tool, coef = MillingTool(), ALUMINIUM_7075
    cond = CuttingConditions(1750.0, 0.058e-3, 1e-3, 6e-3)
    ranges = parse_ranges(args.rpm_ranges)
    caps = [float(v) * 1e-3 for v in args.max_depth_mm.split(",")]
    lo_all, hi_all = min(r[0] for r in ranges), max(r[1] for r in ranges)
    n_rpm = round((hi_all - lo_all) / 1000 * args.speeds_per_1000_rpm) + 1
    rpm = np.unique(np.concatenate([np.linspace(lo_all, hi_all, n_rpm),
                                    [v for r in ranges for v in r]]))  # fmt: skip
    rz = np.arange(0.0, 180.0, args.rz_step)
    rng = np.random.default_rng(args.seed)
    (x0, x1), (y0, y1) = REGIONS[args.region]
    ends = rng.uniform([x0, y0], [x1, y1], (args.paths, 2, 2))
    t = (np.arange(args.segments) + 0.5) / args.segments
    mid = ends[:, 0, None, :] + t[None, :, None] * (ends[:, 1] - ends[:, 0])[:, None, :]
    length = np.linalg.norm(ends[:, 1] - ends[:, 0], axis=1) / args.segments  # (P,)
    poses = np.column_stack([np.repeat(mid.reshape(-1, 2), rz.size, axis=0),
                             np.tile(rz, args.paths * args.segments)])  # fmt: skip
    print(f"# study_plan_bound: {args.paths} paths x {args.segments} segments ({args.region} "
          f"region, seed {args.seed}), Rz 0-{rz[-1]:g} step {args.rz_step:g} deg, Rz rate <= "
          f"{args.max_rz_rate:g} deg/mm, {rpm.size} speeds {lo_all:g}-{hi_all:g} rpm, 2-flute "
          "tool, ae 6 mm, truth's ZOA limits")  # fmt: skip
    print("\noracle ratio = best plan's mean MRR / best fixed Rz+speed's, from the truth's limits: "
          "mean over paths (90th percentile; fraction of paths >= 1.3)")  # fmt: skip
    head = " | ".join(f"{lo:g}-{hi:g} rpm" for lo, hi in ranges)
    print(f"\n| robot | depth cap [mm] | depth rule | {head} |")
    print("|---|---|---|" + "---|" * len(ranges))
    summary = []
    for seed in parse_seeds(args.robot_seeds):
        robot = VirtualRobot.variant(seed)
        lim = truth_limits(robot, poses, rpm, tool, cond, coef)
        lim = lim.reshape(args.paths, args.segments, rz.size, rpm.size)
        name = "thesis" if seed is None else f"seed {seed}"
        for cap in caps:
            for rule in ("segment", "path"):
                cells = []
                for lo, hi in ranges:
                    sel = (rpm >= lo - 1e-9) & (rpm <= hi + 1e-9)
                    ratios = []
                    for p in range(args.paths):
                        allowed = np.minimum(lim[p][..., sel], cap)
                        seg_len = np.full(args.segments, length[p])
                        ch = choose_configurations(allowed, rz, rpm[sel], seg_len,
                                                   max_rz_rate_deg_per_mm=args.max_rz_rate,
                                                   depth_rule=rule)  # fmt: skip
                        fx = fixed_configuration(allowed, rz, rpm[sel], seg_len, depth_rule=rule)
                        ratios.append(ch.score / fx["score"] if fx["score"] > 0 else np.nan)
                    ratios = np.array(ratios)
                    cells.append(f"{np.nanmean(ratios):.2f} ({np.nanquantile(ratios, 0.9):.2f}; "
                                 f"{np.mean(ratios >= 1.3):.2f})")  # fmt: skip
                    summary.append((name, cap, rule, lo, hi, float(np.nanmean(ratios))))
                print(f"| {name} | {cap * 1e3:g} | {rule} | " + " | ".join(cells) + " |",
                      flush=True)  # fmt: skip
    best = max(summary, key=lambda s: s[-1])
    print(f"\nlargest mean oracle ratio: {best[-1]:.2f} ({best[0]}, cap {best[1] * 1e3:g} mm, "
          f"{best[2]} depth, {best[3]:g}-{best[4]:g} rpm); settings with mean >= 1.3: "
          f"{sum(s[-1] >= 1.3 for s in summary)} of {len(summary)}")  # fmt: skip

    if args.check_time_domain:
        from dataclasses import replace

        from robovib.sim import simulated_stability_limit

        robot = VirtualRobot.variant(None)
        print("\n## ZOA of the truth vs its regenerative time-domain simulation (thesis robot)")
        print("| x [mm] | y [mm] | Rz [deg] | speed [rpm] | ZOA [mm] | time domain [mm] |")
        print("|---|---|---|---|---|---|")
        for _ in range(args.check_time_domain):
            pose = np.array([[rng.uniform(x0, x1), rng.uniform(y0, y1), rng.uniform(0, 180)]])
            n = float(rng.uniform(1000, 3500))
            zoa = truth_limits(robot, pose, [n], tool, cond, coef, 250.0)[0, 0]
            c = np.column_stack([pose[:, :2] / 1e3, pose[:, 2]])
            mx, my = robot.workspace.modes(c, "x").at(0), robot.workspace.modes(c, "y").at(0)
            try:
                lo, hi = simulated_stability_limit(
                    mx, my, tool, replace(cond, spindle_rpm=n), coef, (2e-4, 6e-2),
                    n_bisections=5, steps_per_tooth=40, n_tooth_periods=int(4.0 * n * 2 / 60),
                )  # fmt: skip
                td = f"{0.5e3 * (lo + hi):.2f} ({lo * 1e3:.2f}-{hi * 1e3:.2f})"
            except ValueError:
                td = "> 60"
            print(f"| {pose[0, 0]:.0f} | {pose[0, 1]:.0f} | {pose[0, 2]:.0f} | {n:.0f} | "
                  f"{zoa * 1e3:.2f} | {td} |", flush=True)  # fmt: skip
    print(f"\ntotal {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
