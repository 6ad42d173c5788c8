"""Benchmark: writing a hammer recording to UFF 58 is linear in the number of hits.

Run from the repository root::

    python benchmarks/bench_uff_write.py [--samples 8192]

robovib formats every record in memory and writes the file once (temporary file + rename);
the reference, measured in the same run, is pyuff's ``UFF.write_sets``, which re-reads the
whole file after each record (quadratic). Printed: seconds per hit at 10, 20 and 40 hits
for both, and the ratio of the per-hit time at 40 hits to that at 10 hits (1.0 = linear).
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from robovib.io import HammerRecording, read_recording, write_recording_uff


def _recording(n_hits: int, n: int) -> HammerRecording:
    rng = np.random.default_rng(0)
    return HammerRecording(rng.normal(size=(n_hits, n)), rng.normal(size=(n_hits, n)), 2048.0,
                           "acceleration", "x")  # fmt: skip


def _pyuff_write(path: Path, rec: HammerRecording) -> None:
    import pyuff

    x = np.arange(rec.forces.shape[1]) / rec.sample_rate_hz
    sets = []
    for h in range(rec.n_hits):
        for data, spec, label in ((rec.forces[h], 13, "N"), (rec.responses[h], 12, "m/s^2")):
            sets.append(pyuff.prepare_58(
                binary=0, func_type=1, load_case_id=h, rsp_node=1, rsp_dir=1, ref_node=1,
                ref_dir=1, ordinate_spec_data_type=spec, ordinate_axis_units_lab=label,
                orddenom_spec_data_type=0, abscissa_spacing=1, data=data, x=x))  # fmt: skip
    pyuff.UFF(str(path)).write_sets(sets, mode="add")


def _best(fn, repeats: int = 3) -> float:
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=8192, help="samples per record")
    ap.add_argument("--skip-pyuff", action="store_true", help="robovib's writer only")
    args = ap.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for n_hits in (10, 20, 40):
            rec = _recording(n_hits, args.samples)
            ours = Path(tmp) / f"ours{n_hits}.uff"
            t_ours = _best(lambda rec=rec, ours=ours: write_recording_uff(ours, rec))
            assert read_recording(ours, segment="never").n_hits == n_hits
            t_ref = np.nan
            if not args.skip_pyuff:
                ref = Path(tmp) / f"ref{n_hits}.uff"

                def run(ref=ref, rec=rec):
                    ref.unlink(missing_ok=True)
                    _pyuff_write(ref, rec)

                t_ref = _best(run, repeats=1)
            rows.append((n_hits, t_ours / n_hits, t_ref / n_hits))
    print(f"UFF 58 write, {args.samples} samples per record, 2 records per hit")
    print(f"{'hits':>5} {'robovib s/hit':>14} {'pyuff s/hit':>12} {'pyuff/robovib':>14}")
    for n_hits, ours, ref in rows:
        print(f"{n_hits:5d} {ours:14.4f} {ref:12.4f} {ref / ours:14.1f}")
    print(f"per-hit time at 40 vs 10 hits: robovib {rows[-1][1] / rows[0][1]:.2f}x, "
          f"pyuff {rows[-1][2] / rows[0][2]:.2f}x (1.0 = linear)")  # fmt: skip


if __name__ == "__main__":
    main()
