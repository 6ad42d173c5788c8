"""Analytical model vs measurements (thesis §3.4.2, Fig. 11) and GP inputs: Cartesian vs joints.

:func:`compare_with_table_a1` solves IK for the 60 Table A1 poses (tool axis down, Rz about it,
Z = 325 mm), evaluates the analytical translational modes, and sets the analytical
directional stiffness and natural frequency beside the measured pose means. The analytical
frequency of a direction is that of the translational mode whose shape points most along it.

:func:`gp_input_comparison` fits the chapter-3 GP with (X, Y, Rz) or with the six IK joint
angles as inputs and scores both on Table A2 (external validation).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from ..datasets import load_table_a1, load_table_a2, modal_output_columns
from ..gp.regressor import BatchedGPRegressor
from ..gp.validation import external_validation
from .dynamics import TABLE_4_JOINT_STIFFNESS, cartesian_modes
from .kinematics import KR500, tool_down_orientation

__all__ = [
    "compare_with_table_a1",
    "gp_input_comparison",
    "hybrid_learning_curve",
    "plot_comparison",
    "workspace_joints",
]

_Z_M = 0.325


def workspace_joints(robot: KR500, x_m, y_m, rz_deg) -> np.ndarray:
    """IK joint angles [deg] (n, 6) of chapter-3 poses, each started from the previous one."""
    out = []
    ref = np.array([0.0, -30.0, 70.0, 0.0, 50.0, 0.0])
    for x, y, rz in zip(np.atleast_1d(x_m), np.atleast_1d(y_m), np.atleast_1d(rz_deg), strict=True):
        q = robot.ik(np.array([x, y, _Z_M]), tool_down_orientation(rz), reference_deg=ref)
        out.append(q)
    return np.array(out)


def compare_with_table_a1(
    robot: KR500 | None = None, k_theta=TABLE_4_JOINT_STIFFNESS
) -> pd.DataFrame:
    """Per Table A1 pose: measured vs analytical fn [Hz] and stiffness [N/m] per direction."""
    robot = robot or KR500()
    a1 = load_table_a1(units="si")
    means = a1.groupby("test").mean(numeric_only=True)
    joints = workspace_joints(robot, means["x_m"], means["y_m"], means["rz_deg"])
    rows = []
    for (test, row), q in zip(means.iterrows(), joints, strict=True):
        modes = cartesian_modes(robot, q, k_theta)
        k_dir = modes.directional_stiffness()
        rec = {"test": int(test), "x_m": row["x_m"], "y_m": row["y_m"], "rz_deg": row["rz_deg"],
               "extension_m": float(np.hypot(row["x_m"], row["y_m"]))}  # fmt: skip
        for i, d in enumerate("xyz"):
            mode = int(np.argmax(np.abs(modes.directions[i, :])))
            rec[f"fn_{d}_analytical_hz"] = modes.natural_frequencies_hz[mode]
            rec[f"fn_{d}_measured_hz"] = row[f"fn_{d}_hz"]
            rec[f"stiffness_{d}_analytical_n_per_m"] = k_dir[i]
            rec[f"stiffness_{d}_measured_n_per_m"] = row[f"stiffness_{d}_n_per_m"]
            rec[f"fn_{d}_rel_error"] = rec[f"fn_{d}_analytical_hz"] / rec[f"fn_{d}_measured_hz"] - 1
            rec[f"stiffness_{d}_rel_error"] = k_dir[i] / row[f"stiffness_{d}_n_per_m"] - 1
        rows.append(rec)
    return pd.DataFrame(rows)


def comparison_summary(table: pd.DataFrame) -> dict[str, dict[str, float]]:
    """Mean, min and max relative error per quantity and direction of :func:`compare_with_table_a1`.

    Returns
    -------
    dict
        ``{"fn_x": {"mean_rel_error", "min", "max"}, "stiffness_x": ..., ...}`` (fractions).
    """
    summary = {}
    for d in "xyz":
        for q in ("fn", "stiffness"):
            e = table[f"{q}_{d}_rel_error"]
            summary[f"{q}_{d}"] = {
                "mean_rel_error": float(e.mean()),
                "min": float(e.min()),
                "max": float(e.max()),
            }
    return summary


def plot_comparison(table: pd.DataFrame, path=None):
    """Relative errors (analytical / measured - 1) vs arm extension, like thesis Fig. 11."""
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(10, 4), sharex=True)
    for d, colour in zip("xyz", ("C0", "C1", "C2"), strict=True):
        axes[0].plot(
            table["extension_m"],
            100 * table[f"fn_{d}_rel_error"],
            "o",
            color=colour,
            label=d.upper(),
            ms=4,
        )
        axes[1].plot(
            table["extension_m"],
            100 * table[f"stiffness_{d}_rel_error"],
            "o",
            color=colour,
            label=d.upper(),
            ms=4,
        )
    for ax, name in zip(axes, ("natural frequency", "stiffness"), strict=True):
        ax.axhline(0, color="0.5", lw=0.8)
        ax.set_xlabel("distance of the tool tip from the A1 axis [m]")
        ax.set_ylabel(f"{name}: analytical / measured - 1 [%]")
        ax.legend()
    fig.tight_layout()
    if path is not None:
        from ..io.safe_write import save_figure

        save_figure(fig, path)
        plt.close(fig)
    return fig


def gp_input_comparison(robot: KR500 | None = None, rng: int = 0) -> pd.DataFrame:
    """External-validation (Table A2) errors of GPs on Cartesian vs joint-angle inputs."""
    robot = robot or KR500()
    a1 = load_table_a1(units="thesis")
    a2 = load_table_a2(units="thesis")
    cols = modal_output_columns("thesis")
    y1, y2 = a1[cols].to_numpy(), a2[cols].to_numpy()
    # Only the low (16-23 Hz) X mode is comparable across inputs; A2 has no ~63 Hz pose.
    mask = np.isfinite(y1)
    mask[a1["x_high_mode"].to_numpy(), :3] = False
    inputs = {
        "cartesian (X, Y, Rz)": (
            a1[["x_mm", "y_mm", "rz_deg"]].to_numpy(),
            a2[["x_mm", "y_mm", "rz_deg"]].to_numpy(),
        ),
        "joint angles (A1..A6)": (
            workspace_joints(robot, a1["x_mm"] / 1e3, a1["y_mm"] / 1e3, a1["rz_deg"]),
            workspace_joints(robot, a2["x_mm"] / 1e3, a2["y_mm"] / 1e3, a2["rz_deg"]),
        ),
    }
    rows = []
    for name, (x1, x2) in inputs.items():
        model = BatchedGPRegressor(kernel="ard", rng=rng).fit(x1, y1, mask=mask)
        ev = external_validation(model, x2, y2)
        for c, rmse, mre in zip(cols, ev.rmse, ev.mean_relative_error, strict=True):
            rows.append({"inputs": name, "output": c, "rmse": rmse, "mean_relative_error": mre})
    return pd.DataFrame(rows)


def hybrid_learning_curve(
    n_poses=(5, 10, 20, 40, 60),
    n_repeats: int = 5,
    robot: KR500 | None = None,
    rng: int = 0,
) -> pd.DataFrame:
    """Pure GP vs hybrid (analytical mean + GP on the residual) vs number of training poses.

    Outputs: natural frequency and stiffness in X, Y, Z (the quantities the analytical model
    predicts). The hybrid models ``log(y) - log(y_analytical)`` (multiplicative correction of
    the analytical model), the pure GP ``log(y)``; both ARD, constant mean. For each size,
    ``n_repeats`` random subsets of Table A1 poses (all replicates of a chosen pose) are drawn;
    the score is the RMSE on Table A2 in the thesis' units (Hz, MN/m), averaged over repeats.
    The ~63 Hz X-mode rows are left out of the X outputs (Table A2 has no such pose).
    """
    robot = robot or KR500()
    a1 = load_table_a1(units="thesis")
    a2 = load_table_a2(units="thesis")
    outs = [f"{q}_{d}" for d in "xyz" for q in ("fn", "stiffness")]
    comp1 = compare_with_table_a1(robot).set_index("test")
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
    return pd.DataFrame(rows)
