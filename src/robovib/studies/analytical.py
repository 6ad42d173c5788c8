"""Analytical model vs measurements (thesis §3.4.2, Fig. 11) and GP inputs: Cartesian vs joints.

:func:`compare_with_table_a1` solves IK for the 60 Table A1 poses (tool axis down, Rz about it,
Z = 325 mm), evaluates the analytical translational modes, and sets the analytical
directional stiffness and natural frequency beside the measured pose means. The analytical
frequency of a direction is that of the translational mode whose shape points most along it.

:func:`gp_input_comparison` fits the chapter-3 GP with (X, Y, Rz) or with the six IK joint
angles as inputs and scores both on Table A2 (external validation).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from ..datasets import load_table_a1, load_table_a2, modal_output_columns
from ..gp.regressor import BatchedGPRegressor
from ..gp.validation import external_validation
from ..robot.dynamics import TABLE_4_JOINT_STIFFNESS, cartesian_modes
from ..robot.kinematics import KR500, tool_down_orientation

__all__ = [
    "AnalyticalComparison",
    "GPInputComparison",
    "compare_with_table_a1",
    "comparison_summary",
    "gp_input_comparison",
    "plot_comparison",
    "workspace_joints",
]


@dataclass(frozen=True)
class AnalyticalComparison:
    """Analytical vs measured fn [Hz] and stiffness [N/m] per Table A1 pose (thesis Fig. 11).

    ``table`` has one row per pose (``test, x_m, y_m, rz_deg, extension_m`` and per direction
    ``fn_<d>_{analytical,measured}_hz``, ``stiffness_<d>_{analytical,measured}_n_per_m``,
    ``*_rel_error`` = analytical / measured - 1).

    Attributes
    ----------
    table
        The per-pose table described above.
    """

    table: pd.DataFrame

    def to_frame(self) -> pd.DataFrame:
        """A copy of the per-pose table.

        Returns
        -------
        pandas.DataFrame
            One row per pose.
        """
        return self.table.copy()

    def summary(self) -> dict[str, dict[str, float]]:
        """Mean, min and max relative error of fn and stiffness per direction.

        Returns
        -------
        dict
            See :func:`comparison_summary`.
        """
        return comparison_summary(self.table)

    def to_dict(self) -> dict:
        """JSON-ready: summary and one record per pose (units in the keys).

        Returns
        -------
        dict
            The comparison as plain JSON types.
        """
        return {"summary": self.summary(), "poses": self.table.to_dict(orient="records")}


@dataclass(frozen=True)
class GPInputComparison:
    """Table A2 errors of the chapter-3 GP on Cartesian vs joint-angle inputs (thesis units).

    Attributes
    ----------
    table
        One row per (inputs, output): ``rmse`` (output units) and ``mean_relative_error``.
    """

    table: pd.DataFrame

    def to_frame(self) -> pd.DataFrame:
        """One row per (inputs, output): ``rmse`` (output units) and ``mean_relative_error``.

        Returns
        -------
        pandas.DataFrame
            The table.
        """
        return self.table.copy()

    def to_dict(self) -> dict:
        """JSON-ready records.

        Returns
        -------
        dict
            The table as plain JSON types.
        """
        return {"rows": self.table.to_dict(orient="records")}


_Z_M = 0.325


def workspace_joints(robot: KR500, x_m, y_m, rz_deg) -> np.ndarray:
    """IK joint angles [deg] (n, 6) of chapter-3 poses, each started from the previous one.

    Parameters
    ----------
    robot : KR500
        The kinematic model.
    x_m, y_m, rz_deg : array_like
        (n,) poses [m, m, deg].

    Returns
    -------
    numpy.ndarray
        (n, 6) joint angles [deg].
    """
    out = []
    ref = np.array([0.0, -30.0, 70.0, 0.0, 50.0, 0.0])
    for x, y, rz in zip(np.atleast_1d(x_m), np.atleast_1d(y_m), np.atleast_1d(rz_deg), strict=True):
        q = robot.ik(np.array([x, y, _Z_M]), tool_down_orientation(rz), reference_deg=ref)
        out.append(q)
    return np.array(out)


def compare_with_table_a1(
    robot: KR500 | None = None, k_theta=TABLE_4_JOINT_STIFFNESS
) -> AnalyticalComparison:
    """Per Table A1 pose: measured vs analytical fn [Hz] and stiffness [N/m] per direction.

    Parameters
    ----------
    robot : KR500, optional
        The kinematic model (default :class:`~robovib.robot.KR500`).
    k_theta : array_like
        (6,) joint stiffnesses [N m/rad] (default: thesis Table 4).

    Returns
    -------
    AnalyticalComparison
        One row per pose.
    """
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
    return AnalyticalComparison(pd.DataFrame(rows))


def comparison_summary(
    table: AnalyticalComparison | pd.DataFrame,
) -> dict[str, dict[str, float]]:
    """Mean, min and max relative error per quantity and direction of :func:`compare_with_table_a1`.

    Parameters
    ----------
    table : AnalyticalComparison or pandas.DataFrame
        The comparison (or its table).

    Returns
    -------
    dict
        ``{"fn_x": {"mean_rel_error", "min", "max"}, "stiffness_x": ..., ...}`` (fractions).
    """
    if isinstance(table, AnalyticalComparison):
        table = table.table
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


def plot_comparison(table: AnalyticalComparison | pd.DataFrame, ax=None):
    """Relative errors (analytical / measured - 1) vs arm extension, like thesis Fig. 11.

    Parameters
    ----------
    table : AnalyticalComparison or pandas.DataFrame
        Result of :func:`compare_with_table_a1` (or its ``to_frame()``): columns
        ``extension_m`` and ``fn_<d>_rel_error``, ``stiffness_<d>_rel_error`` for d in x, y, z.
    ax : sequence of two matplotlib.axes.Axes, optional
        Axes for the natural-frequency and stiffness panels; a new figure when omitted.

    Returns
    -------
    matplotlib.figure.Figure
        The figure (saving is the caller's: ``robovib.io.save_figure``).
    """
    if isinstance(table, AnalyticalComparison):
        table = table.table
    import matplotlib.pyplot as plt

    if ax is None:
        fig, axes = plt.subplots(1, 2, figsize=(10, 4), sharex=True)
    else:
        axes = list(ax)
        if len(axes) != 2:
            raise ValueError(f"ax must be two Axes (frequency, stiffness), got {len(axes)}")
        fig = axes[0].figure
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
    return fig


def gp_input_comparison(robot: KR500 | None = None, rng: int = 0) -> GPInputComparison:
    """External-validation (Table A2) errors of GPs on Cartesian vs joint-angle inputs.

    Parameters
    ----------
    robot : KR500, optional
        The kinematic model for the joint angles (default :class:`~robovib.robot.KR500`).
    rng : int
        Seed of the GP fits.

    Returns
    -------
    GPInputComparison
        Errors per input set and output.
    """
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
    return GPInputComparison(pd.DataFrame(rows))
