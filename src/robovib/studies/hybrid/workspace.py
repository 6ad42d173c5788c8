"""The whole-workspace FRF model (EMA at poses + OMA along a path) at unseen poses."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...hybrid.model import FRFPoseModel
from ...hybrid.oma import oma_frfs
from ...milling.forces import ACETAL, CuttingConditions, MillingTool
from ...sim import (
    LinearMove,
    VirtualRobot,
    simulate_milling,
)
from .study import ema_frf_on_grid

__all__ = [
    "WorkspaceStudyResult",
    "workspace_study",
]


@dataclass(frozen=True)
class WorkspaceStudyResult:
    """Whole-workspace FRF model (EMA at poses + OMA along a path) checked at unseen poses.

    Attributes
    ----------
    model
        The fitted and updated model (inputs ``x_m, y_m, rz_deg``).
    report
        :class:`~robovib.hybrid.UpdateReport` of the OMA update.
    test_poses
        (m, 3) unseen poses.
    truth_m_per_n
        (m, n_f) complex true compliance [m/N].
    ema_only_m_per_n, predicted_m_per_n
        (m, n_f) predictions of the EMA-only and the updated model [m/N].
    std_m_per_n
        (m, n_f) predictive std after the update [m/N].
    """

    model: FRFPoseModel  #: fitted and updated model, inputs ("x_m", "y_m", "rz_deg")
    report: object  #: UpdateReport of the OMA update
    test_poses: np.ndarray  #: (m, 3) unseen poses (x_m, y_m, rz_deg)
    truth_m_per_n: np.ndarray  #: (m, n_f) complex true compliance
    ema_only_m_per_n: np.ndarray  #: (m, n_f) complex prediction of the EMA-only model
    predicted_m_per_n: np.ndarray  #: (m, n_f) complex prediction after the update
    std_m_per_n: np.ndarray  #: (m, n_f) predictive std after the update

    def relative_rmse(self, which: str = "updated") -> np.ndarray:
        """(m,) RMSE over the grid / max |truth| at each test pose.

        Parameters
        ----------
        which : {"updated", "ema"}
            The updated model's prediction or the EMA-only one.

        Returns
        -------
        numpy.ndarray
            (m,) relative RMSE.
        """
        pred = self.predicted_m_per_n if which == "updated" else self.ema_only_m_per_n
        rmse = np.sqrt(np.mean(np.abs(pred - self.truth_m_per_n) ** 2, axis=1))
        return rmse / np.abs(self.truth_m_per_n).max(axis=1)

    def band_coverage(self, k: float = 2.0) -> float:
        """Fraction of (pose, bin) where |prediction - truth| <= k std.

        Parameters
        ----------
        k : float
            Band half-width in standard deviations.

        Returns
        -------
        float
            The fraction.
        """
        return float(
            np.mean(np.abs(self.predicted_m_per_n - self.truth_m_per_n) <= k * self.std_m_per_n)
        )

    def to_dict(self) -> dict:
        return {
            "test_poses": self.test_poses.tolist(),
            "relative_rmse_updated": self.relative_rmse().tolist(),
            "relative_rmse_ema_only": self.relative_rmse("ema").tolist(),
            "band_coverage_2sigma": self.band_coverage(),
            "update": self.report.to_dict(),
        }

    def to_frame(self):
        import pandas as pd

        return pd.DataFrame({
            "x_m": self.test_poses[:, 0], "y_m": self.test_poses[:, 1], "rz_deg": self.test_poses[:, 2],
            "relative_rmse_ema_only": self.relative_rmse("ema"),
            "relative_rmse_updated": self.relative_rmse(),
        })  # fmt: skip


def workspace_study(
    *,
    direction: str = "y",
    ema_poses=None,
    oma_start=(2.2, -0.2, 45.0),
    oma_end=(2.6, 0.5, 45.0),
    test_poses=((2.45, 0.05, 45.0), (2.3, 0.3, 45.0)),
    f_range_hz=(2.0, 40.0),
    nperseg: int = 512,
    background_noise_rel: float = 1.0,
    seed: int = 0,
) -> WorkspaceStudyResult:
    """EMA at workspace poses + OMA along a straight cut -> FRF at unseen poses (issue 17.4).

    The thesis' future work (§5.5): the per-bin GP over the workspace pose
    ``(x_m, y_m, rz_deg)`` with an ARD kernel, fed by virtual hammer tests at ``ema_poses``
    (default: a 3 x 3 grid over X 2.1-2.7 m, Y -0.3-0.6 m at Rz = 45°) and OMA FRFs from a
    milling pass from ``oma_start`` to ``oma_end`` (50 mm segments, robust update), predicted
    with a band at ``test_poses`` and compared with the simulator's true FRF.

    Parameters
    ----------
    direction : {"x", "y", "z"}
        Direction of the FRFs.
    ema_poses : array_like, optional
        (n, 3) hammer-test poses ``(x_m, y_m, rz_deg)``.
    oma_start, oma_end : tuple of float
        Ends of the milling pass.
    test_poses : sequence of tuple
        Unseen poses the model is checked at.
    f_range_hz : tuple of float
        Frequency band [Hz].
    nperseg : int
        OMA segment length [samples].
    background_noise_rel : float
        Background force relative to the cutting force RMS.
    seed : int
        Simulator seed.

    Returns
    -------
    WorkspaceStudyResult
    """
    robot = VirtualRobot()
    gen = np.random.default_rng(seed)
    if ema_poses is None:
        ema_poses = [(x, y, 45.0) for x in (2.1, 2.4, 2.7) for y in (-0.3, 0.15, 0.6)]
    ema_poses = np.asarray(ema_poses, float)
    cond = CuttingConditions(2700.0, 0.3e-3, 6e-3, 6e-3)
    run = simulate_milling(
        robot, LinearMove("workspace", tuple(oma_start), tuple(oma_end)), MillingTool(), cond,
        ACETAL, background_noise_rel=background_noise_rel, rng=gen,
    )  # fmt: skip
    segs = oma_frfs(
        run.time_s, run.force_n, run.displacement_m, run.coords, direction=direction,
        nperseg=nperseg, f_min_hz=f_range_hz[0], f_max_hz=f_range_hz[1],
        spindle_rpm=cond.spindle_rpm,
    )  # fmt: skip
    grid = segs[0].frf.frequency_hz
    ema_h = np.array(
        [ema_frf_on_grid(robot, p, direction, grid, gen, domain="workspace") for p in ema_poses]
    )
    names = ("x_m", "y_m", "rz_deg")
    ema_only = FRFPoseModel(grid, kernel="ard", input_names=names, rng=seed).fit(ema_poses, ema_h)
    model = FRFPoseModel(grid, kernel="ard", input_names=names, rng=seed).fit(ema_poses, ema_h)
    rep = model.update(
        np.array([sg.pose_mid for sg in segs]), np.array([sg.frf.values for sg in segs]),
        mask=~np.array([sg.flagged for sg in segs]),
        noise_std=np.array([sg.random_error_m_per_n for sg in segs]),
    )  # fmt: skip
    tp = np.asarray(test_poses, float)
    truth = np.array([robot.workspace.modes(p[None], direction).compliance(grid)[0] for p in tp])
    pred, std = model.predict(tp, return_std=True)
    return WorkspaceStudyResult(model, rep, tp, truth, ema_only.predict(tp), pred, std)
