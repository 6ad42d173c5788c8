"""Calibrated bands of a pose model from grouped cross-validation (issue 24).

A GP whose hyperparameters maximise the marginal likelihood is often overconfident at a pose it
has not seen: on Table A1 the plain band covered 73-77 % of held-out hammer tests instead of
95 %. :class:`~robovib.gp.PoseModalModel` with ``calibrate=True`` therefore fits, per output and
mode, a Student-t predictive distribution to the out-of-fold errors of a *grouped*
cross-validation (every replicate of a pose held out together: a prediction at an unseen pose):

    y − μ_cv  ~  √((c σ_latent,cv)² + σ_noise,cv²) · t_ν

``c`` (scale of the latent std: the GP's confidence between measured poses; the test-to-test
scatter σ_noise is measured by the replicates themselves) and ``ν`` (tail weight, from
``DOF_GRID``; ``inf`` = Gaussian) maximise the out-of-fold log predictive density. ``ν >= 3`` keeps the variance finite: every band
has a standard deviation, and sampled modal parameters (P(stable), robust control) stay
physical. The same predictive density chooses the covariance
family per output (``covariance="auto"``: SE, Matérn 5/2, Matérn 3/2). Where a mode has fewer
than ``MIN_Z`` out-of-fold errors, the band keeps the Gaussian shape and is only widened
(``c >= 1``): too little evidence to narrow it or to fit tails.

The figures stored with the model (coverage at 50/90/95 %, NLPD, RMSE, PIT values) are those of
the same out-of-fold predictions after calibration, so they are in-sample for the two
calibration numbers of each output; ``benchmarks/study_calibration.py`` reports the fully
nested figures (calibration refitted inside every outer fold).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..files.h5format import as_text
from .bands import ModalPredictive, _t_logpdf

__all__ = [
    "DOF_GRID",
    "LEVELS",
    "UNCALIBRATED_NOTE",
    "BandCalibration",
    "calibration_status",
    "fit_student_t",
    "grouped_folds",
    "read_calibration",
    "write_calibration",
]

#: Student-t degrees of freedom tried (``inf``: Gaussian).
DOF_GRID = (3.0, 4.0, 6.0, 10.0, 30.0, np.inf)
#: Probability levels at which coverage is reported.
LEVELS = (0.5, 0.9, 0.95)
#: Fewest out-of-fold errors of a mode for a fitted scale and tail.
MIN_Z = 10
#: Fewest out-of-fold observations of a mode for a calibration of its own.
MIN_MODE_OBSERVATIONS = 3
#: What a band of a model without calibration is (text and JSON say "uncalibrated").
UNCALIBRATED_NOTE = (
    "uncalibrated: the model has no band calibration (no /calibration in its file), so its "
    "bands are the plain GP posterior, not checked against held-out poses and typically too "
    "narrow; refit it with `robovib model fit` for calibrated bands"
)
#: Shapes of the band over the poses tried: ``σ → σ_ref^(1-γ) σ^γ`` (1: the GP's own).
GAMMA_GRID = (0.5, 1.0)


def grouped_folds(X: np.ndarray, n_folds: int, rng=0) -> np.ndarray:
    """(n,) fold of each row: rows with identical inputs (one pose) share a fold.

    Parameters
    ----------
    X : numpy.ndarray
        (n, d) inputs.
    n_folds : int
        Number of folds.
    rng : int or numpy.random.Generator
        Seed of the pose shuffle.

    Returns
    -------
    numpy.ndarray
        (n,) fold index of each row.

    Raises
    ------
    ValueError
        Fewer distinct poses than 2 folds need.
    """
    _, pose = np.unique(np.round(np.asarray(X, float), 9), axis=0, return_inverse=True)
    pose = np.ravel(pose)
    n_pose = int(pose.max()) + 1
    k = min(int(n_folds), n_pose)
    if k < 2:
        raise ValueError(f"grouped cross-validation needs at least 2 distinct poses, got {n_pose}")
    order = np.random.default_rng(rng).permutation(n_pose)
    fold_of_pose = np.empty(n_pose, int)
    fold_of_pose[order] = np.arange(n_pose) % k
    return fold_of_pose[pose]


def fit_student_t(errors, latent_std=1.0, noise_std=0.0) -> tuple[float, float, float]:
    """Maximum-likelihood (dof, c) of ``errors ~ √((c σ_latent)² + σ_noise²) · t_ν``.

    Parameters
    ----------
    errors
        (m,) out-of-fold errors ``y − μ`` (non-finite values ignored).
    latent_std, noise_std
        (m,) or scalars: the GP's latent and noise std of each prediction (same units).

    Returns
    -------
    dof, scale, mean_log_density
        ``dof`` from :data:`DOF_GRID`; with fewer than :data:`MIN_Z` errors a Gaussian that is
        only widened: ``(inf, max(1, c_ML), ...)``.
    """
    from scipy.optimize import minimize_scalar

    e = np.asarray(errors, float)
    lat = np.broadcast_to(np.asarray(latent_std, float), e.shape)
    noi = np.broadcast_to(np.asarray(noise_std, float), e.shape)
    ok = np.isfinite(e) & np.isfinite(lat) & np.isfinite(noi) & (np.hypot(lat, noi) > 0)
    e, lat, noi = e[ok], lat[ok], noi[ok]
    if e.size == 0:
        return np.inf, 1.0, float("nan")

    def mean_log_density(log_c, dof):
        s = np.sqrt((np.exp(log_c) * lat) ** 2 + noi**2)
        return float(np.mean(_t_logpdf(e / s, dof) - np.log(s)))

    grid = DOF_GRID if e.size >= MIN_Z else (np.inf,)
    best = (-np.inf, np.inf, 0.0)
    for dof in grid:
        r = minimize_scalar(
            lambda log_c, dof=dof: -mean_log_density(log_c, dof),
            bounds=(-6.0, 6.0),
            method="bounded",
        )
        if -r.fun > best[0]:
            best = (-r.fun, dof, float(r.x))
    dof, log_c = best[1], best[2]
    if e.size < MIN_Z:
        log_c = max(log_c, 0.0)
    return dof, float(np.exp(log_c)), mean_log_density(log_c, dof)


@dataclass(frozen=True)
class BandCalibration:
    """The calibration of a pose model's bands and its grouped-CV scores.

    Attributes
    ----------
    output_names
        Outputs, in model order.
    covariance
        (n_outputs,) covariance family chosen per output.
    scale, dof
        (n_outputs, 2) calibration factor and Student-t dof per [low, high] mode.
    gamma, ref_std
        (n_outputs, 2) shape of the band over the poses and its reference latent std (SI).
    mode_logit
        (n_outputs, 2) Platt scaling ``(a, b)`` of the high-mode probability (NaN: none).
    n_folds, n_poses
        Folds of the grouped CV and distinct poses.
    n
        (n_outputs,) held-out observations per output.
    coverage
        (n_outputs, len(LEVELS)) fraction of held-out measurements inside the calibrated
        measurement set at each level of :data:`LEVELS`.
    coverage_uncalibrated
        The same for the plain GP (latent ± z σ_latent, as robovib printed before).
    nlpd, rmse
        (n_outputs,) mean negative log predictive density (measurement, SI units) and RMSE of
        the point prediction.
    lpd_by_covariance
        Family -> (n_outputs,) mean out-of-fold log predictive density after calibration.
    pit
        (n_rows, n_outputs) out-of-fold PIT values (NaN where not observed).
    levels
        Central levels the coverage is reported at.
    """

    output_names: tuple[str, ...]
    covariance: tuple[str, ...]
    scale: np.ndarray
    dof: np.ndarray
    gamma: np.ndarray
    ref_std: np.ndarray
    mode_logit: np.ndarray
    n_folds: int
    n_poses: int
    n: np.ndarray
    coverage: np.ndarray
    coverage_uncalibrated: np.ndarray
    nlpd: np.ndarray
    rmse: np.ndarray
    lpd_by_covariance: dict = field(default_factory=dict)
    pit: np.ndarray | None = None
    levels: tuple[float, ...] = LEVELS

    def table(self):
        """DataFrame, one row per output: coverage at each level, NLPD, RMSE, the choice.

        Returns
        -------
        pandas.DataFrame
            One row per output.
        """
        import pandas as pd

        rows = []
        for j, name in enumerate(self.output_names):
            row = {"output": name, "covariance": self.covariance[j], "n": int(self.n[j])}
            for i, lev in enumerate(self.levels):
                row[f"coverage_{round(100 * lev)}"] = float(self.coverage[j, i])
            row["coverage_95_uncalibrated"] = float(self.coverage_uncalibrated[j, -1])
            row["nlpd"] = float(self.nlpd[j])
            row["rmse"] = float(self.rmse[j])
            row["scale"] = float(self.scale[j, 0])
            row["gamma"] = float(self.gamma[j, 0])
            row["dof"] = float(self.dof[j, 0])
            rows.append(row)
        return pd.DataFrame(rows)

    def warnings(self, tolerance: float = 0.05) -> list[str]:
        """One line per output and level whose coverage is off by more than ``tolerance``.

        Parameters
        ----------
        tolerance : float
            Allowed |coverage - level|.

        Returns
        -------
        list of str
            The warnings (empty: calibrated).
        """
        out = []
        for j, name in enumerate(self.output_names):
            for i, lev in enumerate(self.levels):
                c = self.coverage[j, i]
                if np.isfinite(c) and abs(c - lev) > tolerance:
                    out.append(
                        f"{name}: the {100 * lev:.0f} % band covers {100 * c:.0f} % of held-out "
                        f"measurements in grouped CV"
                    )
        return out


def mode_index(Y: np.ndarray, thresholds: np.ndarray) -> np.ndarray:
    """(n, n_outputs) 1 where the observed indicator says the high mode, else 0."""
    n, n_out = Y.shape
    idx = np.zeros((n, n_out), int)
    for j in range(n_out):
        thr = thresholds[j]
        if np.isfinite(thr):
            fn = Y[:, 3 * (j // 3)]
            idx[:, j] = np.where(np.isfinite(fn) & (fn > thr), 1, 0)
    return idx


def _of_mode(a: np.ndarray, modes: np.ndarray) -> np.ndarray:
    return np.take_along_axis(a, modes[..., None], axis=-1)[..., 0]


def fit_mode_logit(p, labels) -> tuple[float, float]:
    """Platt scaling ``(a, b)`` of out-of-fold high-mode probabilities ``p`` against the
    observed modes ``labels`` (bool), by maximum likelihood with ``a >= 0``.

    As Platt (1999), the targets are smoothed to ``(N₊ + 1)/(N₊ + 2)`` and ``1/(N₋ + 2)``: with
    classes the out-of-fold probabilities separate perfectly, plain maximum likelihood runs to a
    step function, i.e. certainty no finite data can give.

    Returns ``(nan, nan)`` (no recalibration) where the labels hold one mode only.
    """
    from scipy.optimize import minimize

    p = np.clip(np.asarray(p, float), 1e-12, 1 - 1e-12)
    y = np.asarray(labels, bool)
    if y.all() or not y.any():
        return float("nan"), float("nan")
    x = np.log(p / (1 - p))
    n_pos, n_neg = int(y.sum()), int((~y).sum())
    t = np.where(y, (n_pos + 1.0) / (n_pos + 2.0), 1.0 / (n_neg + 2.0))

    def nll(ab):
        z = ab[0] * x + ab[1]
        return float(np.sum(np.logaddexp(0.0, -z) * t + np.logaddexp(0.0, z) * (1.0 - t)))

    r = minimize(nll, np.array([1.0, 0.0]), method="L-BFGS-B", bounds=[(0.0, 50.0), (-50, 50)])
    return float(r.x[0]), float(r.x[1])


def calibrate_mode_probabilities(pred: ModalPredictive, Y: np.ndarray, thresholds) -> np.ndarray:
    """(n_outputs, 2) Platt ``(a, b)`` per output (the direction's; NaN without a switch)."""
    out = np.full((Y.shape[1], 2), np.nan)
    modes = mode_index(Y, thresholds)
    for j in range(0, Y.shape[1], 3):
        if not np.isfinite(thresholds[j]):
            continue
        seen = np.isfinite(Y[:, j])
        out[j : j + 3] = fit_mode_logit(pred.high_probability[seen, j], modes[seen, j] == 1)
    return out


def calibrate_predictions(pred: ModalPredictive, Y: np.ndarray, thresholds: np.ndarray):
    """Fit (scale, dof, gamma, ref_std) per output and mode on out-of-fold predictions.

    Each observation is scored against the component of the mode it shows (by the direction's
    threshold); for each shape ``γ`` of :data:`GAMMA_GRID` the latent std becomes
    ``σ_ref^(1-γ) σ^γ`` (``σ_ref``: the median out-of-fold latent std of that output and mode),
    ``(c, ν)`` are fitted by :func:`fit_student_t`, and the ``γ`` of the highest out-of-fold log
    predictive density is kept. A mode observed fewer than :data:`MIN_MODE_OBSERVATIONS`
    times takes the other mode's calibration: a high mode seen at one or two poses leaves
    folds without it, whose "high" component is the low one, and scoring against that would
    blow its band up to nonsense (negative frequencies).

    Returns
    -------
    scale, dof, gamma, ref_std : ndarray (n_outputs, 2)
    """
    modes = mode_index(Y, thresholds)
    err = Y - _of_mode(pred.mean, modes)
    lat, noi = _of_mode(pred.latent_std, modes), _of_mode(pred.noise_std, modes)
    n_out = Y.shape[1]
    scale = np.ones((n_out, 2))
    dof = np.full((n_out, 2), np.inf)
    gamma = np.ones((n_out, 2))
    ref = np.ones((n_out, 2))
    for j in range(n_out):
        for c in (0, 1):
            sel = np.isfinite(Y[:, j]) & (modes[:, j] == c)
            if not sel.any():
                continue
            ref[j, c] = float(np.median(lat[sel, j])) if np.any(lat[sel, j] > 0) else 1.0
            best = -np.inf
            for g in GAMMA_GRID:
                shaped = ref[j, c] * (np.maximum(lat[sel, j], 1e-300) / ref[j, c]) ** g
                v, s, lpd = fit_student_t(err[sel, j], shaped, noi[sel, j])
                if lpd > best:
                    best, dof[j, c], scale[j, c], gamma[j, c] = lpd, v, s, g
        if np.sum(np.isfinite(Y[:, j]) & (modes[:, j] == 1)) < MIN_MODE_OBSERVATIONS:
            dof[j, 1], scale[j, 1], gamma[j, 1], ref[j, 1] = (
                dof[j, 0],
                scale[j, 0],
                gamma[j, 0],
                ref[j, 0],
            )
    return scale, dof, gamma, ref


def scores(pred: ModalPredictive, Y: np.ndarray) -> dict:
    """Coverage per level, NLPD, RMSE and PIT of predictions ``pred`` of observations ``Y``."""
    obs = np.isfinite(Y)
    n = obs.sum(axis=0)
    cov = np.full((Y.shape[1], len(LEVELS)), np.nan)
    for i, lev in enumerate(LEVELS):
        inside = pred.contains(np.where(obs, Y, 0.0), lev, "measurement")
        cov[:, i] = np.sum(inside & obs, axis=0) / np.maximum(n, 1)
    lp = pred.logpdf(np.where(obs, Y, 0.0), "measurement")
    nlpd = -np.sum(np.where(obs, lp, 0.0), axis=0) / np.maximum(n, 1)
    err = np.where(obs, pred.point() - Y, 0.0)
    rmse = np.sqrt(np.sum(err**2, axis=0) / np.maximum(n, 1))
    pit = np.where(obs, pred.cdf(np.where(obs, Y, 0.0), "measurement"), np.nan)
    return {"n": n, "coverage": cov, "nlpd": nlpd, "rmse": rmse, "pit": pit}


def uncalibrated_coverage(pred: ModalPredictive, Y: np.ndarray) -> np.ndarray:
    """Coverage of the plain latent band ``point ± z σ`` (the band robovib printed before)."""
    from .bands import t_quantile

    obs = np.isfinite(Y)
    n = np.maximum(obs.sum(axis=0), 1)
    hi = pred.high_probability > 0.5
    s = np.where(hi, pred.latent_std[..., 1], pred.latent_std[..., 0])
    out = np.empty((Y.shape[1], len(LEVELS)))
    for i, lev in enumerate(LEVELS):
        q = float(t_quantile(0.5 + 0.5 * lev, np.inf))
        inside = obs & (np.abs(np.where(obs, Y, 0.0) - pred.point()) <= q * s)
        out[:, i] = inside.sum(axis=0) / n
    return out


_CAL_ARRAYS = {
    "scale": "1 (factor on the GP std)",
    "dof": "1 (Student-t degrees of freedom; inf = Gaussian)",
    "gamma": "1 (shape of the band over the poses)",
    "ref_std": "SI output units (reference latent std)",
    "mode_logit": "1 (Platt a, b of the high-mode probability; NaN: none)",
    "n": "1",
    "coverage": "1 (fraction)",
    "coverage_uncalibrated": "1 (fraction)",
    "nlpd": "nats, density in SI output units",
    "rmse": "SI output units",
    "pit": "1",
}


def write_calibration(group, cal) -> None:
    """Store a :class:`~robovib.gp.calibration.BandCalibration` (arrays with units).

    Parameters
    ----------
    group : h5py.Group
        Open group to write into.
    cal : BandCalibration
        The calibration.
    """
    group.attrs["output_names"] = list(cal.output_names)
    group.attrs["covariance"] = list(cal.covariance)
    group.attrs["n_folds"] = int(cal.n_folds)
    group.attrs["n_poses"] = int(cal.n_poses)
    group.attrs["levels"] = np.asarray(cal.levels, float)
    group.attrs["method"] = (
        "grouped-by-pose CV; Student-t scale and dof per output and mode by maximum "
        "out-of-fold log predictive density (robovib.gp.calibration)"
    )
    for name, unit in _CAL_ARRAYS.items():
        value = getattr(cal, name)
        if value is not None:
            group.create_dataset(name, data=np.asarray(value, float)).attrs["units"] = unit
    lpd = group.create_group("lpd_by_covariance")
    lpd.attrs["units"] = "nats per held-out measurement"
    for family, v in cal.lpd_by_covariance.items():
        lpd.create_dataset(family, data=np.asarray(v, float))


def read_calibration(group):
    """Inverse of :func:`write_calibration`.

    Parameters
    ----------
    group : h5py.Group
        The group written by :func:`write_calibration`.

    Returns
    -------
    BandCalibration
        The calibration.
    """
    a = group.attrs
    d = {k: group[k][()] for k in _CAL_ARRAYS if k in group}
    return BandCalibration(
        output_names=tuple(as_text(v) for v in a["output_names"]),
        covariance=tuple(as_text(v) for v in a["covariance"]),
        scale=d["scale"],
        dof=d["dof"],
        gamma=d.get("gamma", np.ones_like(d["scale"])),
        ref_std=d.get("ref_std", np.ones_like(d["scale"])),
        mode_logit=d.get("mode_logit", np.full_like(d["scale"], np.nan)),
        n_folds=int(a["n_folds"]),
        n_poses=int(a["n_poses"]),
        n=d["n"].astype(int),
        coverage=d["coverage"],
        coverage_uncalibrated=d["coverage_uncalibrated"],
        nlpd=d["nlpd"],
        rmse=d["rmse"],
        lpd_by_covariance={k: v[()] for k, v in group["lpd_by_covariance"].items()},
        pit=d.get("pit"),
        levels=tuple(float(v) for v in a["levels"]),
    )


def calibration_status(model) -> dict:
    """Whether a pose model's bands are calibrated, for text and JSON outputs (issue 38).

    Parameters
    ----------
    model : object
        A pose model (``calibration_``: a :class:`BandCalibration` or None).

    Returns
    -------
    dict
        ``{"calibrated": bool, "bands": str}``: ``bands`` says how (grouped CV, folds, poses)
        or :data:`UNCALIBRATED_NOTE`.

    Examples
    --------
    >>> from robovib.gp.calibration import calibration_status
    >>> class Plain:
    ...     calibration_ = None
    >>> calibration_status(Plain())["bands"].startswith("uncalibrated")
    True
    """
    cal = getattr(model, "calibration_", None)
    if cal is None:
        return {"calibrated": False, "bands": UNCALIBRATED_NOTE}
    return {
        "calibrated": True,
        "bands": f"calibrated on a {cal.n_folds}-fold cross-validation grouped by pose "
        f"({cal.n_poses} poses)",
    }
