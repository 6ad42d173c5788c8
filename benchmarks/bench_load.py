"""CPU time of ``robovib demo`` on a busy machine against a quiet one (issue 37 item 5).

Target: under a load of four busy numerical processes (Python processes multiplying matrices
with NumPy's default BLAS threads) ``robovib demo`` takes <= 2x its quiet CPU time. Multi-threaded
BLAS on small matrices spins waiting for threads that the load keeps off the cores, so its CPU
time grows with the load; robovib runs its small-matrix work with one BLAS thread
(:func:`robovib._threads.single_blas_thread`) so that it does not.

Unlike ``bench_cli.py``, ``robovib demo`` runs here with the environment's default BLAS threads
(``OMP_NUM_THREADS``, ``OPENBLAS_NUM_THREADS`` and ``MKL_NUM_THREADS`` removed), as a user would
run it. The quiet runs come first, then the script starts the four load processes, runs the demo
again, and stops them (they also stop themselves after ``--load-timeout`` seconds). CPU time is
user + system of the demo process and its children; the wall time is printed for reference.

    python benchmarks/bench_load.py [--repeats 2] [--load 4]
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

_BUSY = """
import sys, time
import numpy as np
rng = np.random.default_rng(0)
a = rng.standard_normal((400, 400))
stop = time.monotonic() + float(sys.argv[1])
while time.monotonic() < stop:
    a = np.tanh(a @ a.T / 400.0)
"""

_THREAD_VARS = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")


def _default_threads_env() -> dict[str, str]:
    return {k: v for k, v in os.environ.items() if k not in _THREAD_VARS}


def _demo_command() -> list[str]:
    exe = shutil.which("robovib")
    return (
        [exe, "demo", "--json"] if exe else [sys.executable, "-m", "robovib.cli", "demo", "--json"]
    )


def _run_demo() -> tuple[float, float]:
    """(wall s, CPU s) of one ``robovib demo --json`` process."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    done = subprocess.run(
        _demo_command(),
        env=_default_threads_env(),
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
    )
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if done.returncode != 0:
        raise SystemExit(f"robovib demo failed: {done.stderr.decode()[-2000:]}")
    return wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=2, help="demo runs, quiet and loaded each")
    ap.add_argument("--load", type=int, default=4, help="busy numerical processes")
    ap.add_argument(
        "--load-timeout",
        type=float,
        default=600.0,
        help="seconds after which a load process stops by itself",
    )
    opts = ap.parse_args(argv)

    print(f"command: {' '.join(_demo_command())} (default BLAS threads); cores: {os.cpu_count()}")
    print(f"load average before: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    quiet = [_run_demo() for _ in range(opts.repeats)]

    busy = [
        subprocess.Popen(
            [sys.executable, "-c", _BUSY, str(opts.load_timeout)],
            env=_default_threads_env(),
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        for _ in range(opts.load)
    ]
    try:
        time.sleep(2.0)  # let the load processes import NumPy and start multiplying
        if any(p.poll() is not None for p in busy):
            raise SystemExit("a load process exited early")
        loaded = [_run_demo() for _ in range(opts.repeats)]
    finally:
        for p in busy:
            p.terminate()
        for p in busy:
            try:
                p.wait(timeout=10)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()

    cpu_quiet = statistics.median(c for _, c in quiet)
    cpu_loaded = statistics.median(c for _, c in loaded)
    wall_quiet = statistics.median(w for w, _ in quiet)
    wall_loaded = statistics.median(w for w, _ in loaded)
    ratio = cpu_loaded / cpu_quiet
    print(f"\n{'robovib demo':22s} {'runs':>4s} {'wall s':>8s} {'cpu s':>7s}")
    print(f"{'quiet':22s} {len(quiet):4d} {wall_quiet:8.2f} {cpu_quiet:7.2f}")
    print(
        f"{f'{opts.load} busy processes':22s} {len(loaded):4d} {wall_loaded:8.2f} {cpu_loaded:7.2f}"
    )
    print(f"\nloaded / quiet CPU time: {ratio:.2f} (target <= 2): {'yes' if ratio <= 2 else 'NO'}")
    print(f"load average after: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")


if __name__ == "__main__":
    main()
