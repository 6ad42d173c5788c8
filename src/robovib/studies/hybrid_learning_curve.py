"""Learning curve: pure GP vs hybrid (analytical KR500 mean + GP residual) (beyond thesis §3.4).

``python benchmarks/study_robot_hybrid.py`` prints it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from ..datasets import load_table_a1, load_table_a2
from ..gp.regressor import BatchedGPRegressor
from ..robot.dynamics import cartesian_modes
from ..robot.kinematics import KR500
from .analytical import compare_with_table_a1, workspace_joints

__all__ = ["HybridLearningCurve", "hybrid_learning_curve"]


@dataclass(frozen=True)
class HybridLearningCurve:
    """Table A2 RMSE per (n_poses, repeat, model, output); fn in Hz, stiffness in MN/m.

    Attributes
    ----------
    table
        Long table: ``n_poses, repeat, model, output, rmse``.
    settings
        Settings of the run.
    """

    table: pd.DataFrame
    settings: dict

    def to_frame(self) -> pd.DataFrame:
        """Long table: ``n_poses, repeat, model, output, rmse``.

        Returns
        -------
        pandas.DataFrame
            A copy of the table.
        """
        return self.table.copy()

    def mean_rmse(self) -> pd.DataFrame:
        """RMSE averaged over repeats: index (output, model), one column per n_poses.

        Returns
        -------
        pandas.DataFrame
            Mean RMSE.
        """
        return self.table.groupby(["output", "model", "n_poses"]).rmse.mean().unstack("n_poses")

    def ratio(self) -> pd.DataFrame:
        """Hybrid / pure-GP mean RMSE (< 1: the analytical mean helps).

        Returns
        -------
        pandas.DataFrame
            The ratio per output and n_poses.
        """
        t = self.mean_rmse()
        return t.xs("hybrid", level="model") / t.xs("pure GP", level="model")

    def to_dict(self) -> dict:
        """JSON-ready: settings, units and the long table.

        Returns
        -------
        dict
            The study as plain JSON types.
        """
        return {
            "settings": dict(self.settings),
            "units": {"fn": "Hz", "stiffness": "MN/m"},
            "rows": self.table.to_dict(orient="records"),
        }


def hybrid_learning_curve(
    n_poses=(5, 10, 20, 40, 60),
    n_repeats: int = 5,
    robot: KR500 | None = None,
    rng: int = 0,
) -> HybridLearningCurve:
    """Pure GP vs hybrid (analytical mean + GP on the residual) vs number of training poses.

    Outputs: natural frequency and stiffness in X, Y, Z (the quantities the analytical model
    predicts). The hybrid models ``log(y) - log(y_analytical)`` (multiplicative correction of
    the analytical model), the pure GP ``log(y)``; both ARD, constant mean. For each size,
    ``n_repeats`` random subsets of Table A1 poses (all replicates of a chosen pose) are drawn;
    the score is the RMSE on Table A2 in the thesis' units (Hz, MN/m), averaged over repeats.
    The ~63 Hz X-mode rows are left out of the X outputs (Table A2 has no such pose).

    Parameters
    ----------
    n_poses : sequence of int
        Training-set sizes (poses).
    n_repeats : int
        Random subsets per size.
    robot : KR500, optional
        The kinematic model of the analytical mean (default :class:`~robovib.robot.KR500`).
    rng : int
        Seed of the subsets and the GP fits.

    Returns
    -------
    HybridLearningCurve
        RMSE per size, repeat, model and output.
    """
    robot = robot or KR500()
    a1 = load_table_a1(units="thesis")
    a2 = load_table_a2(units="thesis")
    outs = [f"{q}_{d}" for d in "xyz" for q in ("fn", "stiffness")]
    comp1 = compare_with_table_a1(robot).table.set_index("test")
    x1 = a1[["x_mm", "y_mm", "rz_deg"]].to_numpy()
    x2 = a2[["x_mm", "y_mm", "rz_deg"]].to_numpy()
    unit = {"fn": ("hz", 1.0), "stiffness": ("mn_per_m", 1e-6)}

    def analytical_a1(name):
        q, d = name.split("_")
        col = f"{q}_{d}_analytical_{'hz' if q == 'fn' else 'n_per_m'}"
        return comp1.loc[a1["test"], col].to_numpy() * unit[q][1]

    joints2 = workspace_joints(robot, a2["x_mm"] / 1e3, a2["y_mm"] / 1e3, a2["rz_deg"])
    modes2 = [cartesian_modes(robot, q) for q in joints2]

    def analytical_a2(name):
        q, d = name.split("_")
        i = "xyz".index(d)
        if q == "stiffness":
            return np.array([m.directional_stiffness()[i] for m in modes2]) * 1e-6
        return np.array(
            [m.natural_frequencies_hz[int(np.argmax(np.abs(m.directions[i])))] for m in modes2]
        )

    y1 = np.column_stack(
        [a1[f"{n.split('_')[0]}_{n.split('_')[1]}_{unit[n.split('_')[0]][0]}"] for n in outs]
    )
    y2 = np.column_stack(
        [a2[f"{n.split('_')[0]}_{n.split('_')[1]}_{unit[n.split('_')[0]][0]}"] for n in outs]
    )
    base1 = np.column_stack([analytical_a1(n) for n in outs])
    base2 = np.column_stack([analytical_a2(n) for n in outs])
    mask_all = np.isfinite(y1)
    mask_all[a1["x_high_mode"].to_numpy(), :2] = False
    tests = a1["test"].unique()
    gen = np.random.default_rng(rng)
    rows = []
    for n in n_poses:
        for rep in range(n_repeats if n < len(tests) else 1):
            chosen = gen.choice(tests, size=min(n, len(tests)), replace=False)
            sel = np.isin(a1["test"], chosen)
            mask = mask_all[sel]
            if np.any(mask.sum(axis=0) < 3):
                continue
            for name, target, offset in (
                ("pure GP", np.log(y1[sel]), 0.0),
                ("hybrid", np.log(y1[sel]) - np.log(base1[sel]), None),
            ):
                if np.any(np.nanstd(np.where(mask, target, np.nan), axis=0) == 0):
                    continue
                model = BatchedGPRegressor(kernel="ard", rng=rng).fit(
                    x1[sel], np.where(mask, target, 0.0), mask=mask
                )
                pred = model.predict(x2)
                pred = np.exp(pred if offset is not None else pred + np.log(base2))
                rmse = np.sqrt(np.mean((pred - y2) ** 2, axis=0))
                for o, r in zip(outs, rmse, strict=True):
                    rows.append(
                        {
                            "n_poses": int(n),
                            "repeat": rep,
                            "model": name,
                            "output": o,
                            "rmse": float(r),
                        }
                    )
    return HybridLearningCurve(
        pd.DataFrame(rows),
        {"n_poses": [int(n) for n in n_poses], "n_repeats": int(n_repeats), "seed": rng},
    )
