"""Cold vs warm-started 5-fold CV of the chapter-3 ARD GP (Table A1, no mode switch).

Run: ``python benchmarks/bench_cv_warm_start.py``. Prints best-of-3 times, their ratio and the
mean / largest per-output change of R² and RMSE (warm - cold), plain and grouped by test.
"""

from __future__ import annotations

import time

import numpy as np

from robovib.gp import BatchedGPRegressor
from robovib.gp.validation import cross_validate
from robovib.studies.chapter3 import _training_data


def main() -> None:
    a1, X, Y, mask = _training_data("corrected")
    groups = a1["test"].to_numpy()
    cross_validate(BatchedGPRegressor(kernel="ard", rng=0), X, Y, mask=mask, rng=0)  # warm-up
    for label, kw in (("plain", {}), ("grouped", {"groups": groups})):
        res = {}
        for warm in (False, True):
            times = []
            for _ in range(3):
                t0 = time.perf_counter()
                cv = cross_validate(BatchedGPRegressor(kernel="ard", rng=0), X, Y, mask=mask,
                                    rng=0, warm_start=warm, **kw)  # fmt: skip
                times.append(time.perf_counter() - t0)
            res[warm] = (min(times), cv)
        (t_cold, cold), (t_warm, warm_cv) = res[False], res[True]
        d_r2, d_rmse = warm_cv.r2 - cold.r2, warm_cv.rmse / cold.rmse - 1
        print(f"{label:8s} cold {t_cold:.3f} s  warm {t_warm:.3f} s  speed-up {t_cold / t_warm:.2f}x  "
              f"mean R2 {np.mean(cold.r2):.4f} -> {np.mean(warm_cv.r2):.4f}  "
              f"max |dR2| {np.max(np.abs(d_r2)):.4f}  max |dRMSE| {100 * np.max(np.abs(d_rmse)):.1f} %")  # fmt: skip


if __name__ == "__main__":
    main()
