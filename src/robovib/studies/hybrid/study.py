"""The chapter-5 study on the virtual robot: EMA calibration, OMA updating, validation.

Thesis Table 12 (FRF RMSE before/after updating), §5.4.1 (dominant-mode peak errors) and
Table 13 (optimiser iterations) analogues, over several simulator seeds.

1. EMA: hammer tests (X, Y, Z) at three poses along the path (thesis: 0, 0.585, 1.235 m).
2. OMA: a milling pass from 0.635 m to 1.235 m (Acetal, 25.4 mm two-flute tool, ae = ap = 6 mm,
   2700 rpm; feed per tooth 0.3 mm instead of the thesis' 0.85 mm so that 50 mm segments
   last ~1.9 s at 1 kHz, enough for Welch averaging), split into 50 mm segments, the 50 mm
   around the validation pose left out. The cut's broadband force content is set by
   ``background_noise_rel`` (x the spread of the periodic force; see
   :data:`BACKGROUND_EVIDENCE`).
3. Validation: an EMA FRF at the validation pose (thesis Fig. 35: hammer-test FRF vs model) and
   the simulator's true FRF there.
4. Models: EMA only ("ema"); updated by "robust" (the default update: bias check, rejection,
   OMA noise by marginal likelihood), "posterior", "warm" (thesis), and full retraining.

Each seed draws the milling pass, every hammer test and the GP restarts from
``numpy.random.default_rng(seed)``: a seed reproduces its row exactly (wall times aside).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from ...frf.impact import impact_frf
from ...hybrid.model import FRFPoseModel
from ...hybrid.oma import oma_frfs
from ...milling.forces import ACETAL, CuttingConditions, MillingTool
from ...sim import (
    PATH_LENGTH_M,
    LinearMove,
    VirtualRobot,
    simulate_hammer_test,
    simulate_milling,
)

__all__ = [
    "BACKGROUND_EVIDENCE",
    "MODELS",
    "HybridStudyResult",
    "StudyData",
    "ema_frf_on_grid",
    "hybrid_study",
    "study_data",
]


MODELS = ("ema", "robust", "robust_warm", "posterior", "warm", "retrain")

#: Why the default background force of the study is what it is (issue 17, item 3).
BACKGROUND_EVIDENCE = (
    "Evidence for the broadband force content: the thesis gives no amplitude (Figure 33 is a "
    "plot; §5.2.2 says only that OMA works 'when there is sufficient background noise "
    "excitation', citing [58-60, 68]). The author's OMA paper on the same cell (Nguyen & "
    "Melkote, Procedia Manufacturing 48 (2020) 154-158, doi:10.1016/j.promfg.2020.05.032) "
    "reports that the periodic milling forces were accompanied by background white noise "
    "exciting the robot across its spectrum, and OMA FRFs agreed well with hammer FRFs; the "
    "thesis then used 131 bins in all three directions. So the measured condition is: most "
    "bins between the harmonics had coherent force-response content. In the virtual cell "
    "that needs a background of the order of the periodic force's spread "
    "(background_noise_rel ~ 1, the study's default); at the simulator's generic 0.15 most Z "
    "bins fail coherence, oma_frfs warns (OMAQualityWarning) and the robust update uses what "
    "passes. The 1.0 is a stated condition for OMA, not a measured property of acetal milling."
)


def ema_frf_on_grid(
    robot: VirtualRobot, s_m, direction: str, grid_hz: np.ndarray, rng, domain: str = "path"
) -> np.ndarray:
    """Compliance FRF [m/N] of a virtual hammer test on ``grid_hz``.

    ``s_m`` is the path coordinate [m] (``domain="path"``) or a workspace pose
    ``(x_m, y_m, rz_deg)`` (``domain="workspace"``).

    Parameters
    ----------
    robot : VirtualRobot
        The virtual robot.
    s_m : float or tuple of float
        The pose (see above).
    direction : {"x", "y", "z"}
        Hit and response direction.
    grid_hz : numpy.ndarray
        Frequencies [Hz].
    rng : int or numpy.random.Generator
        Seed of the hammer test's noise.
    domain : {"path", "workspace"}
        How ``s_m`` is read.

    Returns
    -------
    numpy.ndarray
        Complex compliance [m/N] on ``grid_hz``.
    """
    rec = simulate_hammer_test(
        robot,
        s_m,
        direction,
        domain=domain,
        n_hits=3,
        sample_rate_hz=2048.0,
        duration_s=4.0,
        rng=rng,
    )
    frf = impact_frf(
        rec.forces, rec.responses, rec.sample_rate_hz, f_max_hz=float(grid_hz[-1]) + 5
    ).frf.to_compliance(1.0)
    return frf.interpolate(grid_hz).values


@dataclass(frozen=True)
class HybridStudyResult:
    """Rows of (seed, direction, model) with errors at the validation pose.

    Row keys: ``seed, direction, model, rmse_um_per_n`` (vs the validation hammer test, as
    Table 12), ``rmse_vs_truth_um_per_n`` (vs the simulator's true FRF), ``peak_error_pct``
    (|H| error at the dominant-mode bin of the hammer FRF, as §5.4.1), ``peak_error_vs_truth_pct``,
    ``n_bins, n_oma_segments, flagged_fraction, rejected_fraction, held_back_all`` (the
    robust update kept EMA alone for that direction), ``iterations_mean, iterations_total``
    (quasi-Newton iterations per GP of the call that made the model: the EMA fit for
    ``"ema"``, the update for the others; 0 = hyperparameters kept, none re-optimised),
    ``wall_time_s``.

    Attributes
    ----------
    rows
        The rows (keys above).
    settings
        Settings of the run.
    """

    rows: tuple[dict, ...]
    settings: dict = field(default_factory=dict)

    def to_frame(self):
        """One row per (seed, direction, model) (pandas DataFrame).

        Returns
        -------
        pandas.DataFrame
            The rows.
        """
        import pandas as pd

        return pd.DataFrame(list(self.rows))

    def summary(self):
        """Per direction and model: mean/std over seeds, and the change vs EMA alone [%].

        ``change_pct`` is computed per seed on the RMSE vs truth and then averaged;
        ``worst_change_pct`` is the worst seed.

        Returns
        -------
        pandas.DataFrame
            One row per (direction, model).
        """
        df = self.to_frame()
        base = df[df.model == "ema"].set_index(["seed", "direction"])["rmse_vs_truth_um_per_n"]
        df = df.join(base.rename("ema_rmse"), on=["seed", "direction"])
        df["change_pct"] = 100 * (df.rmse_vs_truth_um_per_n / df.ema_rmse - 1)
        agg = df.groupby(["direction", "model"], sort=False).agg(
            rmse_um_per_n=("rmse_um_per_n", "mean"),
            rmse_vs_truth_um_per_n=("rmse_vs_truth_um_per_n", "mean"),
            rmse_vs_truth_std=("rmse_vs_truth_um_per_n", "std"),
            change_pct=("change_pct", "mean"),
            worst_change_pct=("change_pct", "max"),
            peak_error_pct=("peak_error_pct", "mean"),
            peak_error_vs_truth_pct=("peak_error_vs_truth_pct", "mean"),
            rejected_fraction=("rejected_fraction", "mean"),
            iterations_mean=("iterations_mean", "mean"),
            wall_time_s=("wall_time_s", "mean"),
        )
        return agg.reset_index()

    def rule_met(self, model: str = "robust") -> bool:
        """Issue 17's rule: X and Z improve >= 20 % (mean over seeds), no direction worse
        than EMA alone by > 5 % (mean over seeds).

        Parameters
        ----------
        model : str
            The model judged (``"robust"``: the robust update).

        Returns
        -------
        bool
            Whether the rule holds.
        """
        s = self.summary().set_index(["direction", "model"])["change_pct"]
        dirs = sorted({r["direction"] for r in self.rows})
        ok = all(s[(d, model)] <= 5.0 for d in dirs)
        return ok and all(s[(d, model)] <= -20.0 for d in ("x", "z") if d in dirs)

    def to_dict(self) -> dict:
        """JSON-friendly: settings, rows and the per-direction summary.

        Returns
        -------
        dict
            The result as plain JSON types.
        """
        return {
            "settings": dict(self.settings),
            "rows": [dict(r) for r in self.rows],
            "summary": self.summary().to_dict(orient="records"),
        }


def _score(pred, val, truth) -> dict:
    peak = int(np.argmax(np.abs(val)))
    peak_t = int(np.argmax(np.abs(truth)))
    return {
        "rmse_um_per_n": float(np.sqrt(np.mean(np.abs(pred - val) ** 2)) * 1e6),
        "rmse_vs_truth_um_per_n": float(np.sqrt(np.mean(np.abs(pred - truth) ** 2)) * 1e6),
        "peak_error_pct": float(100 * abs(abs(pred[peak]) - abs(val[peak])) / abs(val[peak])),
        "peak_error_vs_truth_pct": float(
            100 * abs(abs(pred[peak_t]) - abs(truth[peak_t])) / abs(truth[peak_t])
        ),
    }


@dataclass(frozen=True)
class StudyData:
    """One (seed, direction) of the study: EMA, OMA and validation FRFs on the OMA grid.

    Attributes
    ----------
    seed, direction
        The simulator seed and the direction.
    frequency_hz
        (n_f,) the OMA grid [Hz].
    ema_s_m, ema_m_per_n
        EMA path coordinates [m] and their complex FRFs (3, n_f) [m/N].
    oma_s_m, oma_m_per_n
        OMA segment coordinates [m] and their complex FRFs (n_seg, n_f) [m/N].
    oma_mask
        (n_seg, n_f) bool, True = usable bin.
    oma_error_m_per_n
        (n_seg, n_f) H1 random error [m/N].
    validation_m_per_n, truth_m_per_n
        (n_f,) hammer FRF and true FRF at the validation pose [m/N].
    """

    seed: int
    direction: str
    frequency_hz: np.ndarray  #: (n_f,) [Hz]
    ema_s_m: np.ndarray  #: (3,) [m]
    ema_m_per_n: np.ndarray  #: (3, n_f) complex
    oma_s_m: np.ndarray  #: (n_seg,) [m]
    oma_m_per_n: np.ndarray  #: (n_seg, n_f) complex
    oma_mask: np.ndarray  #: (n_seg, n_f) bool, True = usable
    oma_error_m_per_n: np.ndarray  #: (n_seg, n_f) H1 random error
    validation_m_per_n: np.ndarray  #: (n_f,) complex hammer FRF at the validation pose
    truth_m_per_n: np.ndarray  #: (n_f,) complex true FRF there


def study_data(
    robot=None,
    seed: int = 0,
    *,
    ema_s_m=(0.0, 0.585, 1.235),
    validation_s_m: float = 0.91,
    directions=("x", "y", "z"),
    oma_kwargs=None,
    f_range_hz=(2.0, 40.0),
    background_noise_rel: float = 1.0,
):
    """Yield :class:`StudyData` per direction for one seed (the data every model sees).

    Parameters
    ----------
    robot : VirtualRobot, optional
        The virtual robot (default :class:`~robovib.sim.VirtualRobot`).
    seed : int
        Simulator seed.
    ema_s_m : sequence of float
        EMA path coordinates [m].
    validation_s_m : float
        Validation path coordinate [m].
    directions : sequence of str
        Directions.
    oma_kwargs : dict, optional
        OMA estimator settings.
    f_range_hz : tuple of float
        Frequency band [Hz].
    background_noise_rel : float
        Background force of the milling pass relative to the cutting force RMS.

    Yields
    ------
    StudyData
        One per direction.
    """
    robot = robot or VirtualRobot()
    oma_kwargs = oma_kwargs or {}
    gen = np.random.default_rng(seed)
    tool = MillingTool()
    cond = CuttingConditions(2700.0, 0.3e-3, 6e-3, 6e-3)
    run = simulate_milling(
        robot, LinearMove("path", (0.635,), (1.235,)), tool, cond, ACETAL,
        background_noise_rel=background_noise_rel, rng=gen,
    )  # fmt: skip
    for d in directions:
        segs = oma_frfs(
            run.time_s, run.force_n, run.displacement_m, run.coords, direction=d,
            f_min_hz=f_range_hz[0], f_max_hz=f_range_hz[1], spindle_rpm=cond.spindle_rpm,
            exclude_s_m=(validation_s_m - 0.025, validation_s_m + 0.025), **oma_kwargs,
        )  # fmt: skip
        grid = segs[0].frf.frequency_hz
        ema_x = np.array(ema_s_m, float)
        ema_h = np.array([ema_frf_on_grid(robot, s, d, grid, gen) for s in ema_x])
        yield StudyData(
            seed, d, grid, ema_x, ema_h,
            np.array([sg.s_mid_m for sg in segs]), np.array([sg.frf.values for sg in segs]),
            ~np.array([sg.flagged for sg in segs]),
            np.array([sg.random_error_m_per_n for sg in segs]),
            ema_frf_on_grid(robot, validation_s_m, d, grid, gen),
            robot.path.modes(validation_s_m, d).compliance(grid)[0],
        )  # fmt: skip


def _one_seed(
    robot, seed, *, ema_s_m, validation_s_m, directions, oma_kwargs, f_range_hz, background, models
):
    rows = []
    for sd in study_data(
        robot, seed, ema_s_m=ema_s_m, validation_s_m=validation_s_m, directions=directions,
        oma_kwargs=oma_kwargs, f_range_hz=f_range_hz, background_noise_rel=background,
    ):  # fmt: skip
        d, grid = sd.direction, sd.frequency_hz
        ema_x, ema_h, oma_x, oma_h = sd.ema_s_m, sd.ema_m_per_n, sd.oma_s_m, sd.oma_m_per_n
        oma_mask, oma_err = sd.oma_mask, sd.oma_error_m_per_n
        val, truth = sd.validation_m_per_n, sd.truth_m_per_n
        common = {"seed": seed, "direction": d, "n_bins": int(grid.size),
                  "n_oma_segments": len(oma_x), "flagged_fraction": float(1 - oma_mask.mean())}  # fmt: skip
        for name in models:
            t0 = time.perf_counter()
            rejected, iters, total, held_all = 0.0, 0.0, 0, False
            if name == "retrain":
                m = FRFPoseModel(grid, rng=seed).fit(
                    np.concatenate([ema_x, oma_x]),
                    np.vstack([ema_h, oma_h]),
                    mask=np.vstack([np.ones_like(ema_h, bool), oma_mask]),
                    groups=np.r_[np.zeros(len(ema_x), int), np.ones(len(oma_x), int)],
                )
                rep = m.last_report_
            else:
                m = FRFPoseModel(grid, rng=seed).fit(ema_x, ema_h)
                rep = m.last_report_
                if name != "ema":
                    t0 = time.perf_counter()
                    mode = "robust" if name == "robust_warm" else name
                    rep = m.update(oma_x, oma_h, mask=oma_mask, mode=mode, noise_std=oma_err,
                                   reoptimize=name == "robust_warm")  # fmt: skip
                    rejected = rep.rejected_fraction
                    held_all = bool(rep.held_back_all)
            iters, total = rep.iterations_mean_per_gp, rep.iterations_total
            wall = time.perf_counter() - t0
            rows.append({**common, "model": name, **_score(m.predict([validation_s_m])[0], val, truth),
                         "rejected_fraction": rejected, "held_back_all": held_all,
                         "iterations_mean": iters,
                         "iterations_total": total, "wall_time_s": wall})  # fmt: skip
    return rows


def hybrid_study(
    robot: VirtualRobot | None = None,
    *,
    seeds=(0,),
    ema_s_m=(0.0, 0.585, 1.235),
    validation_s_m: float = 0.91,
    directions=("x", "y", "z"),
    nperseg: int = 1024,
    noverlap: int | None = None,
    window: str = "hann",
    segment_length_m: float = 0.05,
    f_range_hz=(2.0, 40.0),
    background_noise_rel: float = 1.0,
    models=MODELS,
) -> HybridStudyResult:
    """Run the study for each seed (Table 12 / 13 analogues).

    Parameters
    ----------
    robot
        The virtual robot (default :class:`robovib.sim.VirtualRobot`).
    seeds
        Simulator/GP seeds; one full run (milling pass, hammer tests, GPs) per seed.
    directions
        Directions studied.
    ema_s_m, validation_s_m
        EMA and validation path coordinates [m] (thesis: 0, 0.585, 1.235; validation 1.040).
    nperseg, noverlap, window, segment_length_m
        OMA estimator settings (samples, samples, SciPy window, m). Default 1024 samples
        (0.98 Hz at 1 kHz, 2 Welch averages per 50 mm segment): across 5 seeds it beats 512
        in every direction (see :func:`oma_settings_study`).
    f_range_hz
        Model band [Hz].
    background_noise_rel
        Broadband force content of the cut (see :data:`BACKGROUND_EVIDENCE`).
    models
        Subset of ``("ema", "robust", "posterior", "warm", "retrain")``.

    Returns
    -------
    HybridStudyResult

    Raises
    ------
    ValueError
        Unknown model, validation pose off the path.
    """
    unknown = set(models) - set(MODELS)
    if unknown:
        raise ValueError(f"unknown models {sorted(unknown)}; expected a subset of {MODELS}")
    if "ema" not in models:
        models = ("ema", *models)
    if not 0.0 <= validation_s_m <= PATH_LENGTH_M:
        raise ValueError(
            f"validation_s_m={validation_s_m} m is off the path [0, {PATH_LENGTH_M}] m"
        )
    robot = robot or VirtualRobot()
    oma_kwargs = {"nperseg": nperseg, "noverlap": noverlap, "window": window,
                  "segment_length_m": segment_length_m}  # fmt: skip
    rows = []
    for seed in seeds:
        rows += _one_seed(
            robot, int(seed), ema_s_m=ema_s_m, validation_s_m=validation_s_m, directions=directions,
            oma_kwargs=oma_kwargs, f_range_hz=f_range_hz, background=background_noise_rel, models=models,
        )  # fmt: skip
    settings = {"seeds": [int(s) for s in seeds], "ema_s_m": list(ema_s_m),
                "validation_s_m": validation_s_m, "nperseg": nperseg, "noverlap": noverlap,
                "window": window, "segment_length_m": segment_length_m,
                "f_range_hz": list(f_range_hz), "background_noise_rel": background_noise_rel}  # fmt: skip
    return HybridStudyResult(tuple(rows), settings)
