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

from ..campaign.plot import plot_next_poses
from ..campaign.selection import NextPoses
from ..frf.impact import impact_frf
from ..hybrid.model import FRFPoseModel
from ..hybrid.oma import oma_frfs
from ..milling.forces import ACETAL, CuttingConditions, MillingTool
from ..sim import (
    PATH_LENGTH_M,
    LinearMove,
    VirtualRobot,
    simulate_hammer_test,
    simulate_milling,
)

__all__ = [
    "BACKGROUND_EVIDENCE",
    "HybridStudyResult",
    "NextPoses",
    "OMASettingsResult",
    "StudyData",
    "WorkspaceStudyResult",
    "background_study",
    "background_table",
    "ema_frf_on_grid",
    "hybrid_study",
    "oma_settings_study",
    "parse_backgrounds",
    "parse_seeds",
    "plot_next_poses",
    "propose_next_poses",
    "study_data",
    "workspace_study",
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


def parse_seeds(text: str) -> list[int]:
    """Simulator seeds from ``"0-4"`` (inclusive range) or ``"0,1,2"``.

    Parameters
    ----------
    text : str
        The seeds as typed.

    Returns
    -------
    list of int
        The seeds.

    Raises
    ------
    ValueError
        Anything else, naming the accepted forms.
    """
    try:
        if "-" in text.strip("-"):
            a, b = text.split("-", 1)
            seeds = list(range(int(a), int(b) + 1))
        else:
            seeds = [int(v) for v in text.split(",")]
    except ValueError:
        raise ValueError(f"seeds must look like 0-4 or 0,1,2, got {text!r}") from None
    if not seeds:
        raise ValueError(f"no seeds in {text!r} (a range must run upwards, e.g. 0-4)")
    return seeds


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


@dataclass(frozen=True)
class OMASettingsResult:
    """RMSE (robust update, vs truth) and bin count per OMA estimator setting.

    Attributes
    ----------
    rows
        One dict per setting.
    """

    rows: tuple[dict, ...]

    def to_frame(self):
        import pandas as pd

        return pd.DataFrame(list(self.rows))

    def to_dict(self) -> dict:
        return {"rows": [dict(r) for r in self.rows]}


def oma_settings_study(
    settings=None, *, seeds=(0,), directions=("x", "y", "z"), **kwargs
) -> OMASettingsResult:
    """The study repeated over OMA estimator settings (issue 17 item 2).

    Parameters
    ----------
    settings
        Iterable of dicts with keys among ``nperseg, noverlap, window, segment_length_m,
        f_range_hz``. Default: nperseg 256/512/1024 (3.9/1.95/0.98 Hz) with 50 mm segments,
        Hann and boxcar, nperseg 1024/2048/4096 with 100/200/200 mm segments, and 1024 over
        2-130 Hz (131 bins, the thesis' count).
    seeds, directions, **kwargs
        Passed to :func:`hybrid_study`.

    Returns
    -------
    OMASettingsResult
        Rows: the settings, ``direction, n_bins, flagged_fraction, rmse_ema_um_per_n,
        rmse_robust_um_per_n, change_pct`` (means over seeds).
    """
    if settings is None:
        settings = [
            {"nperseg": 256},
            {"nperseg": 512},
            {"nperseg": 512, "window": "boxcar"},
            {"nperseg": 1024},
            {"nperseg": 1024, "noverlap": 768},
            {"nperseg": 1024, "window": "boxcar"},
            {"nperseg": 1024, "segment_length_m": 0.1},
            {"nperseg": 2048, "segment_length_m": 0.2},
            {"nperseg": 1024, "f_range_hz": (2.0, 130.0)},
            {"nperseg": 4096, "segment_length_m": 0.2},
        ]
    rows = []
    for st in settings:
        res = hybrid_study(seeds=seeds, directions=directions, models=("ema", "robust"),
                           **{**kwargs, **st})  # fmt: skip
        summ = res.summary().set_index(["direction", "model"])
        df = res.to_frame()
        for d in directions:
            sub = df[(df.direction == d) & (df.model == "robust")]
            rows.append({
                "nperseg": st.get("nperseg", 1024), "noverlap": st.get("noverlap"),
                "window": st.get("window", "hann"),
                "segment_length_m": st.get("segment_length_m", 0.05),
                "f_max_hz": float(st.get("f_range_hz", kwargs.get("f_range_hz", (2.0, 40.0)))[1]),
                "direction": d,
                "n_bins": int(sub.n_bins.iloc[0]), "n_oma_segments": int(sub.n_oma_segments.iloc[0]),
                "flagged_fraction": float(sub.flagged_fraction.mean()),
                "rmse_ema_um_per_n": float(summ.loc[(d, "ema"), "rmse_vs_truth_um_per_n"]),
                "rmse_robust_um_per_n": float(summ.loc[(d, "robust"), "rmse_vs_truth_um_per_n"]),
                "change_pct": float(summ.loc[(d, "robust"), "change_pct"]),
            })  # fmt: skip
    return OMASettingsResult(tuple(rows))


def propose_next_poses(tested_s_m, k: int = 3, direction: str = "x", rng=0) -> NextPoses:
    """Where to hammer next along the chapter-4 path: largest integrated variance reduction.

    Virtual EMA FRFs (2-40 Hz, 1 Hz grid) at ``tested_s_m`` [m] train an
    :class:`~robovib.hybrid.FRFPoseModel`; :meth:`~robovib.hybrid.FRFPoseModel.next_poses`
    (:func:`robovib.campaign.next_poses`) picks ``k`` of 50 candidates along the path. Draw
    the result with :func:`robovib.campaign.plot_next_poses`.

    Parameters
    ----------
    tested_s_m : array_like
        Tested path coordinates [m].
    k : int
        Poses to propose.
    direction : {"x", "y", "z"}
        Direction of the FRFs.
    rng : int
        Seed of the virtual EMA and the model.

    Returns
    -------
    NextPoses
        The proposed coordinates (``poses[:, 0]`` [m]), the candidates with their variance
        and the tested coordinates (``training_poses[:, 0]``).

    Raises
    ------
    ValueError
        Bad direction, ``k`` or path coordinates.
    """
    tested = np.asarray(tested_s_m, float).ravel()
    robot = VirtualRobot()
    grid = np.arange(2.0, 40.0, 1.0)
    gen = np.random.default_rng(rng)
    frfs = np.array([ema_frf_on_grid(robot, s, direction, grid, gen) for s in tested])
    model = FRFPoseModel(grid, rng=rng).fit(tested, frfs)
    return model.next_poses(np.linspace(0, PATH_LENGTH_M, 50), k=k)


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


def background_study(backgrounds, seeds=(0,), **kwargs) -> HybridStudyResult:
    """The study (EMA alone and the default robust update) at several background levels.

    Parameters
    ----------
    backgrounds
        Broadband force content levels of the cut (``background_noise_rel``), e.g.
        ``(0.05, 0.15, 0.5, 1, 2)``; each must be > 0.
    seeds
        Simulator seeds, each run at every background.
    **kwargs
        Passed to :func:`hybrid_study` (not ``models`` / ``background_noise_rel``).

    Returns
    -------
    HybridStudyResult
        Rows as :func:`hybrid_study`'s with a ``background`` key; scored against the
        simulator's true FRF (``rmse_vs_truth_um_per_n``, ``peak_error_vs_truth_pct``).

    Raises
    ------
    ValueError
        No background, or one that is not finite and > 0.
    """
    bgs = [float(b) for b in backgrounds]
    if not bgs or not all(np.isfinite(b) and b > 0 for b in bgs):
        raise ValueError(f"backgrounds must be finite and > 0, got {list(backgrounds)}")
    rows, settings = [], {}
    for b in bgs:
        res = hybrid_study(seeds=seeds, background_noise_rel=b, models=("ema", "robust"), **kwargs)
        rows += [{**r, "background": b} for r in res.rows]
        settings = dict(res.settings)
    settings["backgrounds"] = bgs
    return HybridStudyResult(tuple(rows), settings)


def background_table(result: HybridStudyResult) -> list[dict]:
    """Per background and direction: robust vs EMA alone, against the true FRF.

    Parameters
    ----------
    result
        From :func:`background_study`.

    Returns
    -------
    list of dict
        ``background, direction, rmse_change_mean_pct, rmse_change_worst_pct`` (relative
        change of the RMSE vs truth, per seed), ``peak_error_ema_pct, peak_error_robust_pct``
        (mean over seeds) and ``peak_change_worst_pts`` (worst seed, robust minus EMA, in
        percentage points of the dominant-peak |H| error), ``held_back_fraction`` (of the
        seeds where the evidence test held the whole direction back: EMA alone).
    """
    import pandas as pd

    df = pd.DataFrame(list(result.rows))
    key = ["background", "seed", "direction"]
    e = df[df.model == "ema"].set_index(key)
    r = df[df.model == "robust"].set_index(key)
    t = pd.DataFrame({
        "d_rmse": 100 * (r.rmse_vs_truth_um_per_n / e.rmse_vs_truth_um_per_n - 1),
        "pk_e": e.peak_error_vs_truth_pct, "pk_r": r.peak_error_vs_truth_pct,
        "held": r.held_back_all.astype(float),
    })  # fmt: skip
    t["d_pk"] = t.pk_r - t.pk_e
    g = t.groupby(level=["background", "direction"]).agg(
        rmse_change_mean_pct=("d_rmse", "mean"), rmse_change_worst_pct=("d_rmse", "max"),
        peak_error_ema_pct=("pk_e", "mean"), peak_error_robust_pct=("pk_r", "mean"),
        peak_change_worst_pts=("d_pk", "max"), held_back_fraction=("held", "mean"),
    )  # fmt: skip
    return [{k: (float(v) if k != "direction" else v) for k, v in row.items()}
            for row in g.reset_index().to_dict(orient="records")]  # fmt: skip


def parse_backgrounds(texts) -> list[float]:
    """Background levels from strings such as ``["0.05,0.15", "1"]`` (commas or spaces).

    Parameters
    ----------
    texts
        Strings, each one or more numbers separated by commas or spaces.

    Returns
    -------
    list of float

    Raises
    ------
    ValueError
        Something that is not a number, or a level that is not finite and > 0.
    """
    out = []
    for t in texts:
        for v in str(t).replace(",", " ").split():
            try:
                b = float(v)
            except ValueError:
                raise ValueError(f"background must be a number, got {v!r}") from None
            if not (np.isfinite(b) and b > 0):
                raise ValueError(f"background must be finite and > 0, got {v!r}")
            out.append(b)
    if not out:
        raise ValueError("no background level given")
    return out
