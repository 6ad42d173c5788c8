"""Benchmark: multi-mode campaign processing (``--modes-band``) against the dominant-mode one.

Target (issue 37 item 6): ``campaign process --modes-band 5,100`` takes <= 2x the time of the
same campaign processed for its dominant mode only.

Run from the repository root::

    python benchmarks/bench_campaign_modes.py [--poses 36] [--band 5,100] [--repeats 1]

A virtual campaign (``robovib.sim.simulate_campaign``: poses x 3 directions, the four file
layouts, 3 hits of 4 s at 2048 Hz per recording, as ``bench_campaign.py``) is processed in one
process (``n_workers=1``) with the default settings and with ``modes_band_hz`` set, alternately
``--repeats`` times; the medians of the CPU time (all threads of this process) and their ratio
are printed, with the wall times and the number of modes fitted. BLAS runs with the
environment's threads: set ``OMP_NUM_THREADS=1`` to see the single-thread figure.
"""

from __future__ import annotations

import argparse
import os
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np

from robovib.campaign import ProcessingSettings, process_campaign
from robovib.sim import simulate_campaign


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--poses", type=int, default=36)
    ap.add_argument("--band", default="5,100", help="LO,HI of --modes-band [Hz]")
    ap.add_argument("--repeats", type=int, default=1)
    args = ap.parse_args(argv)
    band = tuple(float(v) for v in args.band.split(","))
    rng = np.random.default_rng(0)
    n = args.poses
    poses = np.column_stack(
        [rng.uniform(2100, 2550, n), rng.uniform(-300, 600, n), rng.uniform(0, 180, n)]
    )
    print(f"load average before: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    times: dict[str, list[float]] = {"dominant": [], "modes": []}
    walls: dict[str, list[float]] = {"dominant": [], "modes": []}
    with tempfile.TemporaryDirectory() as tmp:
        sim = simulate_campaign(poses, tmp, rng=1, n_hits=3, duration_s=4.0,
                                sample_rate_hz=2048.0, n_truth=0)  # fmt: skip
        n_rec = len(sim.recordings)
        for i in range(args.repeats):
            t0, w0 = time.process_time(), time.perf_counter()
            process_campaign(sim.manifest, Path(tmp) / f"dominant{i}", n_workers=1)
            times["dominant"].append(time.process_time() - t0)
            walls["dominant"].append(time.perf_counter() - w0)
            t0, w0 = time.process_time(), time.perf_counter()
            process_campaign(
                sim.manifest, Path(tmp) / f"modes{i}", n_workers=1,
                settings=ProcessingSettings(modes_band_hz=band),
            )  # fmt: skip
            times["modes"].append(time.process_time() - t0)
            walls["modes"].append(time.perf_counter() - w0)
        modes_csv = Path(tmp) / "modes0" / "modes.csv"
        n_modes = sum(1 for _ in modes_csv.open()) - 1 if modes_csv.exists() else 0
    dom, modes = (statistics.median(times[k]) for k in ("dominant", "modes"))
    w_dom, w_modes = (statistics.median(walls[k]) for k in ("dominant", "modes"))
    print(f"{n_rec} recordings ({n} poses x 3 directions), one process, CPU seconds (median "
          f"of {args.repeats})")  # fmt: skip
    print(f"dominant mode        : {dom:7.2f} s ({dom / n_rec:.3f} s per recording; "
          f"wall {w_dom:.2f} s)")  # fmt: skip
    print(f"--modes-band {args.band:8s}: {modes:7.2f} s ({modes / n_rec:.3f} s per recording, "
          f"{n_modes} modes; wall {w_modes:.2f} s)")  # fmt: skip
    ratio = modes / dom
    print(f"ratio: {ratio:.2f} (target <= 2): {'yes' if ratio <= 2 else 'NO'}")
    print(f"load average after: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")


if __name__ == "__main__":
    main()
