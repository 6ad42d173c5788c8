"""Issue 39: a chart's P(stable) before and after 5 test cuts at its pose (``mill lobes --cuts``).

A well-specified check of :mod:`robovib.milling.cut_forecast`: the "truth" is a structure of the
CLI's default pose model drawn from another seed (so not one of the 64 weighted structures);
5 cuts at the chart's pose, random speeds, depths 0.6-1.4 x the truth's limit, are labelled by
it; the Brier score of P(stable) over every speed x 11 depths (0.5-1.5 x the truth's limit) is
compared before and after, at the chart's pose and at a pose 100 mm / 150 mm / 20 deg away.
(``benchmarks/study_plan.py`` is the study on the virtual robot, with simulated, detected cuts.)

Run: ``python benchmarks/study_cut_forecast.py [--truths 20]`` (a few seconds).
"""

from __future__ import annotations

import argparse

import numpy as np

from robovib.gp.chapter3_model import workspace_predictor
from robovib.io.cuts import MeasuredCuts
from robovib.milling import ALUMINIUM_7075, CuttingConditions, MillingTool
from robovib.milling.cut_forecast import forecast_with_cuts
from robovib.milling.structures import sample_structures


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--truths", type=int, default=20)
    args = ap.parse_args(argv)
    tool, cond = MillingTool(), CuttingConditions(1750.0, 0.058e-3, 1e-3, 6e-3)
    model = workspace_predictor(None, seed=0, require_inputs=("x_mm", "y_mm", "rz_deg"))
    pose = np.array([2400.0, 125.0, 90.0])
    poses = np.stack([pose, pose + np.array([100.0, 150.0, 20.0])])
    rpm = np.linspace(1000, 3500, 60)
    truth = sample_structures(model, args.truths, rng=99).limits(poses, rpm, tool, cond,
                                                                 ALUMINIUM_7075)  # fmt: skip
    gen = np.random.default_rng(5)
    scale = np.linspace(0.5, 1.5, 11)
    rows = []
    for t in range(args.truths):
        j = gen.choice(rpm.size, 5, replace=False)
        depth = truth[t, 0, j] * gen.uniform(0.6, 1.4, 5)
        cuts = MeasuredCuts(rpm[j], depth, depth >= truth[t, 0, j], np.tile(pose, (5, 1)))
        fc = forecast_with_cuts(model, poses, rpm, cuts, tool, cond, ALUMINIUM_7075,
                                n_samples=64, rng=0)  # fmt: skip
        ev = truth[t][:, :, None] * scale  # (2 poses, speeds, depths)
        stable = scale < 1.0
        brier = [
            [np.mean((np.stack([fc.p_stable(ev[..., k], post)[i] for k in range(scale.size)], -1)
                      - stable) ** 2) for i in range(2)]
            for post in (False, True)
        ]  # fmt: skip
        rows.append((*brier[0], *brier[1], fc.update.effective_sample_size))
    r = np.array(rows)
    print("| where | Brier before | Brier after | truths improved |")
    print("|---|---|---|---|")
    for i, where in enumerate(("the chart's pose", "100 mm, 150 mm, 20 deg away")):
        print(f"| {where} | {r[:, i].mean():.3f} | {r[:, 2 + i].mean():.3f} | "
              f"{int(np.sum(r[:, 2 + i] < r[:, i]))}/{args.truths} |")  # fmt: skip
    print(f"effective sample size after the cuts: median {np.median(r[:, 4]):.1f} of 64")


if __name__ == "__main__":
    main()
