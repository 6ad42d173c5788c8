"""Issue 39: the MRR oracle bound from the truth's multi-mode SDM limits, beside the ZOA one.

``study_plan_bound.py`` fed the planner's optimiser the truth's zero-order (ZOA) limits. The
ZOA misses the flip lobes of this low-immersion cut and differs from the time-domain truth by
-22 to +24 % point by point, so that bound is one of the zero-order physics only. Here the same
optimiser (:func:`robovib.milling.planning.choose_configurations`, Rz and speed jointly per
segment under the Rz-rate limit) and its fixed comparison
(:func:`~robovib.milling.planning.fixed_configuration`, the best single Rz and speed under the
same depth rule) are fed the truth's *semi-discretization* limits: all five modes of the
virtual robot's truth at every segment midpoint, Rz and speed, by the compiled deterministic
chart (:func:`robovib.milling.sdm_kernel.sdm_limits`, the options of ``sdm_lobes``: 40 steps
per period at least, 12 per vibration of the highest mode, its own depth range and warm start),
capped at ``--max-depth-mm``. The ZOA oracle is recomputed on the same grid, so both columns
see the same paths, Rz and speeds. Ratio:

    (mean MRR of the best plan) / (mean MRR of the best fixed Rz and speed)

for both depth rules (``segment``: each segment as deep as allowed; ``path``: one depth).

A third oracle, ``--time-domain``, uses the limits of the regenerative time-domain simulation
itself (what ``study_plan.py`` checks the planned cuts with: 6 s cuts, 40 steps per tooth,
full-depth entry): at every pair the cut is simulated at ``TD_FACTORS`` / ``TD_ABOVE`` x the
SDM limit (capped) by :func:`~robovib.milling.time_domain.time_domain_limit_ratios` (top-down,
persistent onset), and the deepest stable factor is the allowed depth.

Paths: ``--paths`` straight paths of ``--segments`` segments with random ends from ``--seed``,
as ``study_plan_bound.py`` draws them (``--seed 101 --paths 40`` are its paths; ``--skip-paths
K`` leaves out the first K), or with ``--study-seed S`` the three paths ``study_plan.py --seed
S`` plans (same draws). The limits are computed in ``--jobs`` processes (chunks of poses; one
core: ~0.09-0.1 s per pose for the SDM at 50 speeds, ~0.03 s more for the time domain);
``--save-limits`` / ``--load-limits`` keep them for a re-analysis. ``--check-time-domain N``
compares ZOA and SDM with ``simulated_stability_limit`` (as ``study_plan_bound.py
--check-time-domain``) at N random (pose, speed) points of 1000-3500 rpm.

    nice python benchmarks/study_plan_bound_sdm.py --study-seed 7 --time-domain --jobs 2  # ~2.5 min CPU
    python benchmarks/study_plan_bound_sdm.py --seed 101 --paths 20 --time-domain --jobs 16
    nice python benchmarks/study_plan_bound_sdm.py --study-seed 7 --segments 1 --rz-step 90 \
        --check-time-domain 60                                                    # ~5 s

Measured (twelfth session, thesis robot, 50 speeds 300-6000 rpm, Rz step 10 deg, mean oracle
ratio over paths ZOA / SDM / time domain, 60 mm cap, one depth per path, 1000-3500 rpm): seed
101's first 20 paths 1.05 / 1.22 / 1.04; ``--study-seed 7`` 1.05 / 1.16 / 1.04; fresh
``--study-seed 13`` 1.05 / 1.44 / 1.05 (Rz step 5: 1.05 / 1.35 / 1.07). Every other cell
(20 mm cap, segment depth, the other ranges) is <= 1.20 (ZOA, 1000-2000 rpm) / 1.14 (SDM), and
the time-domain oracle is <= 1.13 everywhere. The SDM's larger ratios come from a few paths
(1 in 3-5; up to 2.66) where, at 3300-3500 rpm and Rz 70-90 deg, the multi-mode SDM has a
pocket (limit 40-47 mm, the critical multiplier at |mu| 0.992-0.994 from 25 to 44 mm) that
closes at some segments: one depth at one fixed Rz must stay under 15-20 mm there, a plan that
reorients keeps ~40 mm. The time-domain truth has no such pocket: it chatters from ~30 mm
there (saturated, 0.5-1.7 x the feed per tooth; with a 186-period ramped entry, 120 steps per
tooth or 12 s cuts too). SDM / time domain pointwise (``--check-time-domain 60``): median
1.11, 0.71-1.80, log sd 0.21 (ZOA: median 1.18, 0.73-3.19, log sd 0.34).
"""

from __future__ import annotations

import argparse
import itertools
import time
from concurrent.futures import ProcessPoolExecutor

import numpy as np
from study_plan_bound import REGIONS, parse_ranges, truth_limits

STUDY_X_MM, STUDY_Y_MM = (2150.0, 2650.0), (-250.0, 550.0)  # study_plan.py's X_MM, Y_MM


def _setup():
    from robovib.milling import ALUMINIUM_7075, CuttingConditions, MillingTool

    return MillingTool(), CuttingConditions(1750.0, 0.058e-3, 1e-3, 6e-3), ALUMINIUM_7075


def truth_structures(robot, poses_mm_deg):
    """The truth's (modes_x, modes_y) at each (x [mm], y [mm], Rz [deg]) pose."""
    c = np.column_stack([poses_mm_deg[:, :2] / 1e3, poses_mm_deg[:, 2]])
    mx, my = robot.workspace.modes(c, "x"), robot.workspace.modes(c, "y")
    return [(mx.at(i), my.at(i)) for i in range(c.shape[0])]


#: The time-domain oracle: factors of the SDM limit (capped) simulated, below and above it.
TD_FACTORS = (0.3, 0.4, 0.5, 0.6, 0.7, 0.75, 0.8, 0.85, 0.9, 0.95, 1.0)
TD_ABOVE = (1.05, 1.1, 1.15, 1.2, 1.3, 1.4, 1.5, 1.7, 2.0)


def sdm_chunk(task):
    """Limits [m] (n, j) of the thesis robot's truth at a chunk of poses (a worker): the SDM,
    and with ``cap`` the time-domain one (else None), with the CPU seconds of each."""
    poses, rpm, cap, td_kw = task
    from robovib.milling.sdm_kernel import sdm_limits
    from robovib.sim import VirtualRobot

    tool, cond, coef = _setup()
    structs = truth_structures(VirtualRobot.variant(None), poses)
    t0 = time.process_time()
    a, _, ev = sdm_limits(structs, tool, cond, coef, rpm)
    t1 = time.process_time()
    td = None
    if cap is not None:
        td = td_limits(structs, rpm, np.minimum(a, cap), cap, **td_kw)
    return a, td, int(ev.sum()), t1 - t0, time.process_time() - t1


def td_limits(structs, rpm, ref, cap, seconds=6.0, steps_per_tooth=40):
    """The deepest depth [m] <= ``cap`` found stable in the regenerative time-domain simulation
    below the onset of persistent chatter, searched at ``TD_FACTORS`` / ``TD_ABOVE`` x ``ref``
    (:func:`~robovib.milling.time_domain.time_domain_limit_ratios`, top-down), each speed
    simulated for ``seconds`` as ``study_plan.py``'s truth (full-depth entry, 40 steps per
    tooth at least). Where even the lowest factor chatters: half of it."""
    from robovib.milling.time_domain import time_domain_limit_ratios

    tool, cond, coef = _setup()
    out = np.empty_like(ref)
    for j, n in enumerate(rpm):
        low, _ = time_domain_limit_ratios(
            structs, tool, cond, coef, [n], ref[:, j : j + 1], factors=TD_FACTORS,
            above=TD_ABOVE, steps_per_tooth=steps_per_tooth,
            n_tooth_periods=int(seconds * n * tool.n_flutes / 60),
        )  # fmt: skip
        out[:, j] = np.minimum(low[:, 0] * ref[:, j], cap)
    return out


def truth_oracle_limits(poses, rpm, jobs, cap=None, td_kw=None, chunk=40):
    """SDM (and time-domain) limits of the truth at every pose and speed, in ``jobs`` processes."""
    chunks = [(poses[i : i + chunk], rpm, cap, td_kw or {})
              for i in range(0, poses.shape[0], chunk)]  # fmt: skip
    if jobs > 1:
        with ProcessPoolExecutor(jobs) as ex:
            out = list(ex.map(sdm_chunk, chunks))
    else:
        out = [sdm_chunk(c) for c in chunks]
    sdm = np.concatenate([o[0] for o in out])
    td = None if cap is None else np.concatenate([o[1] for o in out])
    return sdm, td, sum(o[2] for o in out), sum(o[3] for o in out), sum(o[4] for o in out)


def load_limits(path, rpm, rz, mid, length):
    """The limits saved by ``--save-limits`` (checked against this run's grids and paths)."""
    with np.load(path, allow_pickle=False) as f:
        for name, want in (("rpm", rpm), ("rz_deg", rz), ("midpoints_mm", mid),
                           ("length_mm", length)):  # fmt: skip
            if f[name].shape != want.shape or not np.allclose(f[name], want, rtol=1e-9):
                raise ValueError(f"{path}: {name} differs from this run's (other options?)")
        limits = {k.upper(): f[k].astype(float) for k in ("zoa", "sdm", "td") if k in f}
    td = limits.get("TD")
    return limits, None if td is None else td.reshape(-1, rpm.size)


def make_paths(args):
    """(P, m, 2) midpoints [mm] and (P, m) segment lengths [mm]."""
    from robovib.milling.planning import path_segments

    if args.study_seed is not None:
        rng = np.random.default_rng(args.study_seed)  # study_plan.py draws its paths first
        ends = [np.array([[rng.uniform(*STUDY_X_MM), rng.uniform(*STUDY_Y_MM)],
                          [rng.uniform(*STUDY_X_MM), rng.uniform(*STUDY_Y_MM)]])
                for _ in range(3)]  # fmt: skip
        label = f"study_plan.py --seed {args.study_seed}'s 3 paths"
    else:
        rng = np.random.default_rng(args.seed)
        (x0, x1), (y0, y1) = REGIONS[args.region]
        ends = list(rng.uniform([x0, y0], [x1, y1], (args.paths, 2, 2)))[args.skip_paths :]
        label = f"{args.paths} paths ({args.region} region, seed {args.seed})"
        if args.skip_paths:
            label += f" less the first {args.skip_paths}"
    segs = [path_segments(e, args.segments) for e in ends]
    return np.array([s[0] for s in segs]), np.array([s[1] for s in segs]), label


def oracle_ratios(lim, rz, rpm, length, sel, cap, rule, rate):
    """Per path: the oracle ratio and (fixed Rz, fixed speed, plan's mean speed, Rz span)."""
    from robovib.milling.planning import choose_configurations, fixed_configuration

    ratios, info = [], []
    for p in range(lim.shape[0]):
        allowed = np.minimum(lim[p][..., sel], cap)
        ch = choose_configurations(allowed, rz, rpm[sel], length[p],
                                   max_rz_rate_deg_per_mm=rate, depth_rule=rule)  # fmt: skip
        fx = fixed_configuration(allowed, rz, rpm[sel], length[p], depth_rule=rule)
        ratios.append(ch.score / fx["score"] if fx["score"] > 0 else np.nan)
        prz = rz[ch.rz_index]
        info.append((fx["rz_deg"], fx["spindle_rpm"], float(np.mean(rpm[sel][ch.speed_index])),
                     float(prz.min()), float(prz.max())))  # fmt: skip
    return np.array(ratios), info


def check_time_domain(n, rng, jobs):
    from robovib.sim import VirtualRobot

    robot = VirtualRobot.variant(None)
    pts = [(np.array([[rng.uniform(*STUDY_X_MM), rng.uniform(*STUDY_Y_MM), rng.uniform(0, 180)]]),
            float(rng.uniform(1000, 3500))) for _ in range(n)]  # fmt: skip
    tool, cond, coef = _setup()
    zoa = [truth_limits(robot, p, [s], tool, cond, coef, 250.0)[0, 0] for p, s in pts]
    sdm = [sdm_chunk((p, np.array([s]), None, {}))[0][0, 0] for p, s in pts]
    if jobs > 1:
        with ProcessPoolExecutor(jobs) as ex:
            td = list(ex.map(td_point, pts))
    else:
        td = [td_point(t) for t in pts]
    print("\n## ZOA and SDM of the truth vs its regenerative time-domain simulation (thesis robot)")
    print("| x [mm] | y [mm] | Rz [deg] | speed [rpm] | ZOA [mm] | SDM [mm] | time domain [mm] | "
          "SDM / TD | ZOA / TD |")  # fmt: skip
    print("|---|---|---|---|---|---|---|---|---|")
    rs, rz_ = [], []
    for (pose, s), z, d, t in zip(pts, zoa, sdm, td, strict=True):
        if t is None:
            cells = "> 60 | | "
        else:
            mid = 0.5 * (t[0] + t[1])
            rs.append(d / mid)
            rz_.append(z / mid)
            cells = (f"{mid * 1e3:.2f} ({t[0] * 1e3:.2f}-{t[1] * 1e3:.2f}) | {d / mid:.2f} | "
                     f"{z / mid:.2f}")  # fmt: skip
        print(f"| {pose[0, 0]:.0f} | {pose[0, 1]:.0f} | {pose[0, 2]:.0f} | {s:.0f} | "
              f"{z * 1e3:.2f} | {d * 1e3:.2f} | {cells} |")  # fmt: skip
    if rs:
        for name, r in (("SDM", rs), ("ZOA", rz_)):
            lr = np.log(r)
            print(f"{name} / time domain: median {np.exp(np.median(lr)):.2f}, range "
                  f"{min(r):.2f}-{max(r):.2f}, log sd {np.std(lr):.2f} ({len(r)} points)")  # fmt: skip


def td_point(item):
    from dataclasses import replace

    from robovib.sim import VirtualRobot, simulated_stability_limit

    pose, n = item
    tool, cond, coef = _setup()
    (mx, my), = truth_structures(VirtualRobot.variant(None), pose)  # fmt: skip
    try:
        return simulated_stability_limit(
            mx, my, tool, replace(cond, spindle_rpm=n), coef, (2e-4, 6e-2),
            n_bisections=5, steps_per_tooth=40, n_tooth_periods=int(4.0 * n * 2 / 60),
        )  # fmt: skip
    except ValueError:
        return None


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--paths", type=int, default=40)
    ap.add_argument("--segments", type=int, default=20)
    ap.add_argument("--seed", type=int, default=101, help="paths as study_plan_bound.py")
    ap.add_argument("--skip-paths", type=int, default=0, help="leave out the first K paths")
    ap.add_argument("--study-seed", type=int, default=None,
                    help="instead: the 3 paths of study_plan.py --seed S")  # fmt: skip
    ap.add_argument("--region", choices=tuple(REGIONS), default="study")
    ap.add_argument("--rpm-ranges", default="1000-3500,300-3500,1000-2000,1000-6000")
    ap.add_argument("--speeds-per-1000-rpm", type=float, default=8.0)
    ap.add_argument("--rz-step", type=float, default=10.0, help="Rz grid step over 0-180 deg")
    ap.add_argument("--max-rz-rate", type=float, default=1.0, help="deg per mm of path")
    ap.add_argument("--max-depth-mm", default="20,60", help="depth caps [mm] (the tool)")
    ap.add_argument("--jobs", type=int, default=1, help="processes for the SDM")
    ap.add_argument("--check-time-domain", type=int, default=0)
    ap.add_argument("--check-seed", type=int, default=5)
    ap.add_argument(
        "--time-domain",
        action="store_true",
        help="also the time-domain oracle (the regenerative simulation's limits)",
    )
    ap.add_argument("--td-seconds", type=float, default=6.0, help="study_plan.py's --seconds")
    ap.add_argument("--td-steps", type=int, default=40, help="study_plan.py's --steps")
    ap.add_argument("--save-limits", default="", help="write the limits to this .npz")
    ap.add_argument("--load-limits", default="",
                    help="analyse the limits of this .npz (--save-limits) instead")  # fmt: skip
    args = ap.parse_args(argv)

    from robovib.sim import VirtualRobot

    t0 = time.perf_counter()
    c0 = time.process_time()
    tool, cond, coef = _setup()
    ranges = parse_ranges(args.rpm_ranges)
    caps = [float(v) * 1e-3 for v in args.max_depth_mm.split(",")]
    lo_all, hi_all = min(r[0] for r in ranges), max(r[1] for r in ranges)
    n_rpm = round((hi_all - lo_all) / 1000 * args.speeds_per_1000_rpm) + 1
    rpm = np.unique(np.concatenate([np.linspace(lo_all, hi_all, n_rpm),
                                    [v for r in ranges for v in r]]))  # fmt: skip
    rz = np.arange(0.0, 180.0, args.rz_step)
    mid, length, label = make_paths(args)
    n_p, n_m = mid.shape[:2]
    poses = np.column_stack([np.repeat(mid.reshape(-1, 2), rz.size, axis=0),
                             np.tile(rz, n_p * n_m)])  # fmt: skip
    print(f"# study_plan_bound_sdm: {label}, {n_m} segments, Rz 0-{rz[-1]:g} step "
          f"{args.rz_step:g} deg, Rz rate <= {args.max_rz_rate:g} deg/mm, {rpm.size} speeds "
          f"{lo_all:g}-{hi_all:g} rpm, 2-flute tool, ae 6 mm, thesis robot's truth (5 modes)")  # fmt: skip
    if args.load_limits:
        limits, td = load_limits(args.load_limits, rpm, rz, mid, length)
        print(f"limits loaded from {args.load_limits}: {', '.join(limits)}")
    else:
        robot = VirtualRobot.variant(None)
        zoa = truth_limits(robot, poses, rpm, tool, cond, coef).reshape(n_p, n_m, rz.size,
                                                                         rpm.size)  # fmt: skip
        td_cap = max(caps) if args.time_domain else None
        td_kw = {"seconds": args.td_seconds, "steps_per_tooth": args.td_steps}
        sdm, td, n_eval, sdm_cpu, td_cpu = truth_oracle_limits(poses, rpm, args.jobs, td_cap,
                                                               td_kw)  # fmt: skip
        limits = {"ZOA": zoa, "SDM": sdm.reshape(zoa.shape)}
        print(f"SDM limits: {poses.shape[0]} poses x {rpm.size} speeds, {n_eval} monodromy "
              f"evaluations, {sdm_cpu:.0f} s CPU in the workers", end="")  # fmt: skip
        if td is not None:
            limits["TD"] = td.reshape(zoa.shape)
            floor = np.mean(td <= TD_FACTORS[0] * 0.5 * np.minimum(sdm, td_cap) * (1 + 1e-9))
            print(f"; time-domain limits {td_cpu:.0f} s CPU (chatter at {TD_FACTORS[0]:g} x the "
                  f"SDM at {floor:.1%} of the pairs: limit put at half that)", end="")  # fmt: skip
        print(f" ({args.jobs} processes, {time.perf_counter() - t0:.0f} s wall)")
    if args.save_limits:
        np.savez_compressed(args.save_limits, rpm=rpm, rz_deg=rz, midpoints_mm=mid,
                            length_mm=length,
                            **{k.lower(): v.astype(np.float32) for k, v in limits.items()})  # fmt: skip

    top = 0.06
    edges = [300, 1000, 1500, 2000, 2500, 3000, 3500, 4500, 6000.1]
    pairs = [("SDM", "ZOA")] + ([("TD", "SDM"), ("TD", "ZOA")] if td is not None else [])
    for num, den in pairs:
        print(f"\n{num} / {den} limit of the truth (both capped at {top * 1e3:g} mm) per speed "
              "band: median (5th-95th percentile; fraction < 0.9)")  # fmt: skip
        r = np.minimum(limits[num], top) / np.minimum(limits[den], top)
        for lo_b, hi_b in itertools.pairwise(edges):
            s = (rpm >= lo_b) & (rpm < hi_b)
            if s.any():
                v = r[..., s].ravel()
                print(f"  {lo_b:g}-{min(hi_b, hi_all):g} rpm: {np.median(v):.2f} "
                      f"({np.quantile(v, 0.05):.2f}-{np.quantile(v, 0.95):.2f}; "
                      f"{np.mean(v < 0.9):.2f})")  # fmt: skip

    names = list(limits)
    print(f"\noracle ratio = best plan's mean MRR / best fixed Rz+speed's from the truth's "
          f"{' / '.join(names)} limits: mean over paths (fraction of paths >= 1.3)")  # fmt: skip
    head = " | ".join(f"{lo:g}-{hi:g} rpm" for lo, hi in ranges)
    print(f"\n| depth cap [mm] | depth rule | {head} |")
    print("|---|---|" + "---|" * len(ranges))
    summary, details = [], []
    for cap in caps:
        for rule in ("segment", "path"):
            cells = []
            for lo, hi in ranges:
                sel = (rpm >= lo - 1e-9) & (rpm <= hi + 1e-9)
                means, frac = {}, {}
                for name, lim in limits.items():
                    v, info = oracle_ratios(lim, rz, rpm, length, sel, cap, rule,
                                            args.max_rz_rate)  # fmt: skip
                    means[name] = float(np.nanmean(v))
                    frac[name] = float(np.mean(v >= 1.3))
                    if name != "ZOA":
                        details.append((name, cap, rule, lo, hi, v, info))
                cells.append(" / ".join(f"{means[k]:.2f} ({frac[k]:.2f})" for k in names))
                summary.append((cap, rule, lo, hi, means))
            print(f"| {cap * 1e3:g} | {rule} | " + " | ".join(cells) + " |", flush=True)
    for name in names:
        best = max(summary, key=lambda v, k=name: v[-1][k])
        print(f"largest mean {name}-oracle ratio: {best[-1][name]:.2f} (cap {best[0] * 1e3:g} "
              f"mm, {best[1]} depth, {best[2]:g}-{best[3]:g} rpm); settings with mean >= 1.3: "
              f"{sum(v[-1][name] >= 1.3 for v in summary)} of {len(summary)}")  # fmt: skip

    print("\nper path: ratio (best fixed Rz [deg] @ speed [rpm]; plan's mean speed [rpm], "
          "Rz range [deg])")  # fmt: skip
    for name, cap, rule, lo, hi, v, info in details:
        items = "; ".join(f"{r:.2f} ({a:g}@{b:.0f}; {c:.0f}, {d:g}-{e:g})" for r, (a, b, c, d, e) in
                          zip(v[:6], info[:6], strict=True))  # fmt: skip
        more = " ..." if v.size > 6 else ""
        print(f"  {name} {cap * 1e3:g} mm {rule} {lo:g}-{hi:g}: {items}{more}")

    if args.check_time_domain:
        check_time_domain(args.check_time_domain, np.random.default_rng(args.check_seed),
                          args.jobs)  # fmt: skip
    print(f"\ntotal {time.perf_counter() - t0:.0f} s wall, {time.process_time() - c0:.0f} s CPU "
          "in the main process (+ the workers')")  # fmt: skip


if __name__ == "__main__":
    main()
