"""Regenerate the shipped chapter-3 pose model (``src/robovib/datasets/data/chapter3_model.h5``).

Fits :func:`robovib.gp.fit_chapter3_model` with its defaults (ARD kernel, mode switch detected,
corrected stiffness reading, seed 0) on Table A1, cross-validates it grouped by pose (5 folds,
all replicates of a pose held out together) and writes the model with the CV figures and
provenance. ``tests/gp/test_chapter3_model.py`` checks the file against a fresh fit.

    python scripts/build_chapter3_model.py [--no-cv]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from sklearn.base import clone

from robovib.gp import fit_chapter3_model
from robovib.gp.chapter3_model import chapter3_training_data
from robovib.gp.validation import cross_validate

TARGET = Path(__file__).resolve().parents[1] / "src/robovib/datasets/data/chapter3_model.h5"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--no-cv", action="store_true", help="skip the grouped cross-validation")
    parser.add_argument("-o", "--output", type=Path, default=TARGET)
    args = parser.parse_args()
    model = fit_chapter3_model()
    X, Y, tests = chapter3_training_data()
    cv = None
    if not args.no_cv:
        res = cross_validate(
            clone(model), X, Y, n_splits=5, mask=np.isfinite(Y), groups=tests, rng=0
        )
        cv = {"r2": res.r2, "r2_corr": res.r2_corr, "rmse": res.rmse, "grouped": True,
              "n_splits": 5, "rmse_units": "SI, per output (see output_units)"}  # fmt: skip
    provenance = {
        "source": "thesis Table A1 (robovib.datasets.load_table_a1, stiffness_reading=corrected)",
        "script": "scripts/build_chapter3_model.py",
        "function": "robovib.gp.fit_chapter3_model()",
        "settings": "kernel=ard, mode_switch=auto, rng=0, rz_symmetric=True",
    }
    model.save(args.output, cv=cv, provenance=provenance)
    print(f"wrote {args.output}")
    for d, s in model.mode_switches_.items():
        print(f"  mode switch {d}: {s.reason}")
    if cv is not None:
        for name, r2, rmse in zip(model.output_names_, cv["r2"], cv["rmse"], strict=True):
            print(f"  grouped CV {name:28s} R2 = {r2:5.2f}  RMSE = {rmse:.4g}")


if __name__ == "__main__":
    main()
