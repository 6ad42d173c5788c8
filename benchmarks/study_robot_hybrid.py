"""Study: pure GP vs hybrid (analytical KR500 model as the mean, GP on the residual).

Run from the repository root (about 10 s)::

    python benchmarks/study_robot_hybrid.py [--repeats 5]

Prints the Table A2 RMSE (Hz, MN/m) of fn and stiffness per direction against the number of
Table A1 training poses, averaged over random pose subsets, and the hybrid/pure ratio.
"""

from __future__ import annotations

import argparse

from robovib.robot.compare import hybrid_learning_curve


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    df = hybrid_learning_curve(n_repeats=args.repeats)
    table = df.groupby(["output", "model", "n_poses"]).rmse.mean().unstack("n_poses")
    print("Table A2 RMSE (fn in Hz, stiffness in MN/m) vs number of Table A1 training poses")
    print(table.round(3).to_string())
    ratio = table.xs("hybrid", level="model") / table.xs("pure GP", level="model")
    print("\nhybrid / pure GP RMSE ratio (< 1: the analytical mean helps)")
    print(ratio.round(2).to_string())


if __name__ == "__main__":
    main()
