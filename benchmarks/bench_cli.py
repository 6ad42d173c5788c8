"""End-to-end time of CLI commands (process start to exit), against ``robovib --help``.

Targets (issue 14): ``robovib gpr predict`` <= 1 s on one core. Issue 27: every single-pose
command (``mill predict``, ``mill lobes --method zoa``, ``control gains``, ``model next-poses``)
<= 1 s and within 2x of ``robovib --help``; ``robovib demo`` <= 5 s on one core. Each command
runs as a fresh process, pinned with ``taskset`` to one core when it exists and with one
BLAS/OpenMP thread, several times; the table gives the
median wall and CPU (user + system) seconds and the ratio of the wall median to the same run's
``robovib --help`` (the floor: Python, NumPy, Typer and Rich starting). Wall times on a shared
machine grow with its load: the load average is printed before and after.

    python benchmarks/bench_cli.py [--repeats 7] [--demo-repeats 2] [--no-demo]
"""

from __future__ import annotations

import argparse
import os
import resource
import shutil
import statistics
import subprocess
import sys
import time

POSE = ["--x", "2400", "--y", "0", "--rz", "45"]


def _base_command() -> list[str]:
    exe = shutil.which("robovib")
    return [exe] if exe else [sys.executable, "-m", "robovib.cli"]


def _run(args: list[str], cores: str | None) -> tuple[float, float]:
    """(wall s, CPU s) of one process running ``robovib args``."""
    cmd = _base_command() + args
    if cores is not None and shutil.which("taskset"):
        cmd = ["taskset", "-c", cores, *cmd]
    env = {**os.environ, "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1",
           "MKL_NUM_THREADS": "1"}  # fmt: skip
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    done = subprocess.run(cmd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if done.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed: {done.stderr.decode()[-2000:]}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=7, help="runs of each quick command")
    ap.add_argument("--demo-repeats", type=int, default=2, help="runs of robovib demo")
    ap.add_argument("--no-demo", action="store_true", help="skip robovib demo")
    opts = ap.parse_args(argv)

    from robovib.datasets import example_path
    from robovib.gp.chapter3_model import chapter3_model_path

    next_poses = ["model", "next-poses", "--model", str(chapter3_model_path()),
                  "--candidates", str(example_path("poses.csv")), "--k", "5", "--json"]  # fmt: skip
    cases = [  # (label, args, cores, target wall s or None)
        ("robovib --help", ["--help"], "0", None),
        ("robovib --version", ["--version"], "0", None),
        ("robovib gpr predict --json", ["gpr", "predict", *POSE, "--json"], "0", 1.0),
        ("mill predict --json", ["mill", "predict", *POSE, "--json"], "0", 1.0),
        ("mill lobes --method zoa --json",
         ["mill", "lobes", "--method", "zoa", *POSE, "--json"], "0", 1.0),
        ("mill lobes --method sdm --json",
         ["mill", "lobes", "--method", "sdm", *POSE, "--json"], "0", None),
        ("control gains --json", ["control", "gains", *POSE, "--json"], "0", 1.0),
        ("model next-poses --json", next_poses, "0", 1.0),
    ]  # fmt: skip
    if not opts.no_demo:
        cases.append(("robovib demo --json", ["demo", "--json"], "0", 5.0))
    load0 = os.getloadavg()
    print(f"command: {' '.join(_base_command())}; taskset: {bool(shutil.which('taskset'))}")
    print(f"load average before: {load0[0]:.2f} {load0[1]:.2f} {load0[2]:.2f} "
          f"(cores: {os.cpu_count()})")  # fmt: skip
    results = {}
    # Interleave the quick commands so that load changes hit all of them alike.
    quick = [c for c in cases if c[0] != "robovib demo --json"]
    for _ in range(opts.repeats):
        for label, args, cores, _target in quick:
            results.setdefault(label, []).append(_run(args, cores))
    for label, args, cores, _target in cases:
        if label == "robovib demo --json":
            results[label] = [_run(args, cores) for _ in range(opts.demo_repeats)]
    floor = statistics.median(w for w, _ in results["robovib --help"])
    print(f"\n{'command':32s} {'cores':>5s} {'runs':>4s} {'wall s':>8s} {'cpu s':>7s} "
          f"{'x --help':>8s}  target")  # fmt: skip
    ok = True
    for label, _args, cores, target in cases:
        runs = results[label]
        wall = statistics.median(w for w, _ in runs)
        cpu = statistics.median(c for _, c in runs)
        verdict = ""
        if target is not None:
            meets = wall <= target
            ok &= meets
            verdict = f"<= {target:g} s: {'yes' if meets else 'NO'}"
            if target <= 1.0:  # single-pose commands: also within 2x of --help (issue 27)
                near = wall <= 2.0 * floor
                ok &= near
                verdict += f", <= 2x --help: {'yes' if near else 'NO'}"
        n_cores = len(cores.split(","))
        print(f"{label:32s} {n_cores:5d} {len(runs):4d} {wall:8.3f} {cpu:7.3f} "
              f"{wall / floor:8.2f}  {verdict}")  # fmt: skip
    load1 = os.getloadavg()
    print(f"\nload average after: {load1[0]:.2f} {load1[1]:.2f} {load1[2]:.2f}")
    print("all targets met" if ok else "some targets NOT met (see the load average)")


if __name__ == "__main__":
    main()
