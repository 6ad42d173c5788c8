"""Benchmark: campaign processing, seconds per recording and the process-pool speed-up.

Run from the repository root::

    python benchmarks/bench_campaign.py [--poses 12] [--workers N]

A virtual campaign (``robovib.sim.simulate_campaign``: poses x 3 directions, the four file
layouts, 3 hits of 4 s at 2048 Hz per recording) is processed twice in the same run: in one
process (the reference) and with a process pool of ``--workers`` (default: all CPU cores).
Printed: seconds per recording for both and the speed-up (ideal: the number of workers, less
the pool start-up and the serial write of the outputs).
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

import numpy as np

from robovib.campaign import process_campaign
from robovib.sim import simulate_campaign


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--poses", type=int, default=12)
    ap.add_argument("--workers", type=int, default=os.cpu_count() or 1)
    args = ap.parse_args()
    rng = np.random.default_rng(0)
    n = args.poses
    poses = np.column_stack(
        [rng.uniform(2100, 2550, n), rng.uniform(-300, 600, n), rng.uniform(0, 180, n)]
    )
    with tempfile.TemporaryDirectory() as tmp:
        sim = simulate_campaign(poses, tmp, rng=1, n_hits=3, duration_s=4.0,
                                sample_rate_hz=2048.0, n_truth=0)  # fmt: skip
        n_rec = len(sim.recordings)
        t0 = time.perf_counter()
        serial = process_campaign(sim.manifest, Path(tmp) / "serial", n_workers=1)
        t_serial = time.perf_counter() - t0
        t0 = time.perf_counter()
        pooled = process_campaign(sim.manifest, Path(tmp) / "pool", n_workers=args.workers)
        t_pool = time.perf_counter() - t0
        same = np.allclose(serial.table["fn_hz"], pooled.table["fn_hz"], rtol=0, atol=0)
    print(f"{n_rec} recordings ({n} poses x 3 directions, 4 layouts, 3 hits x 4 s at 2048 Hz)")
    print(f"one process : {t_serial / n_rec:.3f} s per recording ({t_serial:.1f} s)")
    print(f"{args.workers} workers   : {t_pool / n_rec:.3f} s per recording ({t_pool:.1f} s)")
    print(f"speed-up    : {t_serial / t_pool:.2f}x with {args.workers} workers "
          f"(os.cpu_count() = {os.cpu_count()}); identical results: {same}")  # fmt: skip


if __name__ == "__main__":
    main()
