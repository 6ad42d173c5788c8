"""Issue 25: the robustness table of the milling controllers on a real cut.

Every controller x every disturbance at its realistic level and at 2x, at both positions, plus
all disturbances combined at the realistic levels. Prints the summary table (mean / worst RMS
reduction in X and Z, unstable runs, cuts amplified > 5 %) and writes the per-cut rows as CSV.

    OMP_NUM_THREADS=1 python benchmarks/study_control_robustness.py [--cuts 1,4,5,8] [--out rows.csv]
"""

from __future__ import annotations

import argparse
import sys
import time

import pandas as pd

from robovib.studies.control import TABLE_10_CONDITIONS
from robovib.studies.control_robustness import (
    ROBUSTNESS_CONTROLLERS,
    robustness_study,
    summarize_robustness,
)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cuts", default="1,2,3,4,5,6,7,8", help="Table 10 tests (1-8) to run")
    ap.add_argument("--controllers", default=",".join(ROBUSTNESS_CONTROLLERS))
    ap.add_argument("--out", default=None, help="CSV of the per-cut rows")
    a = ap.parse_args()
    conds = [TABLE_10_CONDITIONS[int(i) - 1] for i in a.cuts.split(",")]
    t0 = time.perf_counter()
    rows = robustness_study(
        a.controllers.split(","), conditions=conds,
        progress=lambda s: print(f"[{time.perf_counter() - t0:6.0f} s] {s}", file=sys.stderr, flush=True),
    )  # fmt: skip
    summary = pd.DataFrame(summarize_robustness(rows))
    pd.set_option("display.width", 250)
    print(summary.round(1).to_string(index=False))
    if a.out:
        pd.DataFrame(rows).to_csv(a.out, index=False)
    print(f"{time.perf_counter() - t0:.0f} s", file=sys.stderr)


if __name__ == "__main__":
    main()
