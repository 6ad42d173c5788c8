"""The chapter-5 study on the virtual robot: EMA calibration, OMA updating, validation.

1. EMA: hammer tests (X, Y, Z) at three poses along the path (thesis: 0, 0.585, 1.235 m).
2. OMA: a milling pass from 0.635 m to 1.235 m (Acetal, 25.4 mm two-flute tool, ae = ap = 6 mm,
   2700 rpm; feed per tooth 0.3 mm instead of the thesis' 0.85 mm so that 50 mm segments
   last ~1.9 s at 1 kHz, enough for Welch averaging), split into 50 mm segments, the 50 mm
   around the validation pose left out. The cut's broadband force content is set by
   ``background_noise_rel`` (default 1: as large as the spread of the periodic force); with
   the simulator's default 0.15 most OMA bins fail the coherence check in this virtual cell.
3. Validation: an EMA FRF at the validation pose (thesis Fig. 35: hammer-test FRF vs model).
4. Models: EMA only ("before"); updated by (a) posterior only, (b) warm-started
   re-optimisation, (c) full retraining — Table 12 / 13 analogues.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from ..frf.impact import impact_frf
from ..milling.forces import ACETAL, CuttingConditions, MillingTool
from ..sim import LinearMove, VirtualRobot, simulate_hammer_test, simulate_milling
from .model import FRFPoseModel
from .oma import oma_frfs

__all__ = ["ema_frf_on_grid", "hybrid_study"]


def ema_frf_on_grid(
    robot: VirtualRobot, s_m: float, direction: str, grid_hz: np.ndarray, rng
) -> np.ndarray:
    """Compliance FRF of a virtual hammer test at path coordinate ``s_m``, on ``grid_hz``."""
    rec = simulate_hammer_test(
        robot,
        s_m,
        direction,
        domain="path",
        n_hits=3,
        sample_rate_hz=2048.0,
        duration_s=4.0,
        rng=rng,
    )
    frf = impact_frf(
        rec.forces, rec.responses, rec.sample_rate_hz, f_max_hz=float(grid_hz[-1]) + 5
    ).frf.to_compliance(1.0)
    return frf.interpolate(grid_hz).values


def hybrid_study(
    robot: VirtualRobot | None = None,
    *,
    ema_s_m=(0.0, 0.585, 1.235),
    validation_s_m: float = 0.91,
    directions=("x", "y", "z"),
    nperseg: int = 512,
    f_range_hz=(2.0, 40.0),
    background_noise_rel: float = 1.0,
    rng: int = 0,
) -> dict:
    """Run the study; returns per-direction RMSE [um/N], peak errors, iterations and times."""
    robot = robot or VirtualRobot()
    gen = np.random.default_rng(rng)
    tool = MillingTool()
    cond = CuttingConditions(2700.0, 0.3e-3, 6e-3, 6e-3)
    run = simulate_milling(
        robot, LinearMove("path", (0.635,), (1.235,)), tool, cond, ACETAL,
        background_noise_rel=background_noise_rel, rng=gen,
    )  # fmt: skip
    results = {}
    for d in directions:
        segs = oma_frfs(
            run.time_s, run.force_n, run.displacement_m, run.coords, direction=d, nperseg=nperseg,
            f_min_hz=f_range_hz[0], f_max_hz=f_range_hz[1], spindle_rpm=cond.spindle_rpm,
            exclude_s_m=(validation_s_m - 0.025, validation_s_m + 0.025),
        )  # fmt: skip
        grid = segs[0].frf.frequency_hz
        ema_x = np.array(ema_s_m)
        ema_h = np.array([ema_frf_on_grid(robot, s, d, grid, gen) for s in ema_x])
        oma_x = np.array([sg.s_mid_m for sg in segs])
        oma_h = np.array([sg.frf.values for sg in segs])
        oma_mask = ~np.array([sg.flagged for sg in segs])
        val = ema_frf_on_grid(robot, validation_s_m, d, grid, gen)
        truth = robot.path.modes(validation_s_m, d).compliance(grid)[0]

        def score(model, val=val, truth=truth):
            pred = model.predict([validation_s_m])[0]
            peak = int(np.argmax(np.abs(val)))
            return {
                "rmse_um_per_n": float(np.sqrt(np.mean(np.abs(pred - val) ** 2)) * 1e6),
                "rmse_vs_truth_um_per_n": float(np.sqrt(np.mean(np.abs(pred - truth) ** 2)) * 1e6),
                "peak_error_pct": float(
                    100 * abs(abs(pred[peak]) - abs(val[peak])) / abs(val[peak])
                ),
            }

        before = FRFPoseModel(grid, rng=rng).fit(ema_x, ema_h)
        row = {"n_bins": int(grid.size), "n_oma_segments": len(segs), "flagged_fraction": float(1 - oma_mask.mean()),
               "before": score(before)}  # fmt: skip
        for mode in ("posterior", "warm"):
            m = FRFPoseModel(grid, rng=rng).fit(ema_x, ema_h)
            rep = m.update(oma_x, oma_h, mask=oma_mask, mode=mode)
            row[mode] = {
                **score(m),
                "iterations_mean": rep.iterations_mean_per_gp,
                "wall_time_s": rep.wall_time_s,
            }
        x_all = np.concatenate([ema_x, oma_x])
        h_all = np.vstack([ema_h, oma_h])
        mask_all = np.vstack([np.ones_like(ema_h, bool), oma_mask])
        src = np.concatenate([np.zeros(len(ema_x), int), np.ones(len(oma_x), int)])
        t0 = time.perf_counter()
        full = FRFPoseModel(grid, rng=rng).fit(x_all, h_all, mask=mask_all, sources=src)
        row["retrain"] = {**score(full), "iterations_mean": full.last_report_.iterations_mean_per_gp,
                          "wall_time_s": time.perf_counter() - t0}  # fmt: skip
        results[d] = row
    return results


@dataclass(frozen=True)
class NextPoses:
    """Proposed hammer-test path coordinates from a virtual EMA at the tested ones."""

    tested_s_m: np.ndarray  #: (n,) [m]
    next_s_m: np.ndarray  #: (k,) [m]
    candidates_s_m: np.ndarray  #: (m,) [m] fine grid along the path
    integrated_variance: np.ndarray  #: (m,) [(um/N)^2] of the model before the picks


def propose_next_poses(tested_s_m, k: int = 3, direction: str = "x", rng=0) -> NextPoses:
    """Where to hammer next along the chapter-4 path: largest integrated predictive variance.

    Virtual EMA FRFs (2-40 Hz, 1 Hz grid) at ``tested_s_m`` [m] train an
    :class:`FRFPoseModel`; :meth:`FRFPoseModel.next_poses` picks ``k`` of 50 candidates.

    Raises
    ------
    ValueError
        Bad direction, ``k`` or path coordinates.
    """
    from ..sim import PATH_LENGTH_M

    tested = np.asarray(tested_s_m, float).ravel()
    robot = VirtualRobot()
    grid = np.arange(2.0, 40.0, 1.0)
    gen = np.random.default_rng(rng)
    frfs = np.array([ema_frf_on_grid(robot, s, direction, grid, gen) for s in tested])
    model = FRFPoseModel(grid, rng=rng).fit(tested, frfs)
    picks = model.next_poses(np.linspace(0, PATH_LENGTH_M, 50), k=k)[:, 0]
    cand = np.linspace(0, PATH_LENGTH_M, 200)
    return NextPoses(tested, picks, cand, model.integrated_variance(cand))


def plot_next_poses(result: NextPoses, ax=None):
    """Integrated predictive variance along the path with tested and proposed poses.

    Returns
    -------
    matplotlib.figure.Figure
    """
    import matplotlib.pyplot as plt

    if ax is None:
        fig, ax = plt.subplots(figsize=(7, 3.5))
    else:
        fig = ax.figure
    ax.plot(
        result.candidates_s_m,
        result.integrated_variance,
        color="C0",
        label="integrated predictive variance",
    )
    for i, s_t in enumerate(result.tested_s_m):
        ax.axvline(s_t, color="k", lw=1, label="tested" if i == 0 else None)
    for i, s_p in enumerate(result.next_s_m):
        ax.axvline(s_p, color="C3", ls="--", lw=1, label="proposed" if i == 0 else None)
    ax.set_xlabel("distance along the path s [m]")
    ax.set_ylabel("sum over bins of var [(um/N)^2]")
    ax.legend(fontsize=8)
    fig.tight_layout()
    return fig
