"""Study: pure GP vs hybrid (analytical KR500 model as the mean, GP on the residual).

Run from the repository root (about 10 s)::

    python benchmarks/study_robot_hybrid.py [--repeats 5]

Prints the Table A2 RMSE (Hz, MN/m) of fn and stiffness per direction against the number of
Table A1 training poses, averaged over random pose subsets, and the hybrid/pure ratio.
"""

from __future__ import annotations

import argparse

from robovib.studies.hybrid_learning_curve import hybrid_learning_curve


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    result = hybrid_learning_curve(n_repeats=args.repeats)
    print("Table A2 RMSE (fn in Hz, stiffness in MN/m) vs number of Table A1 training poses")
    print(result.mean_rmse().round(3).to_string())
    print("\nhybrid / pure GP RMSE ratio (< 1: the analytical mean helps)")
    print(result.ratio().round(2).to_string())


if __name__ == "__main__":
    main()
