"""Pose-dependent model of the whole FRF: one GP per frequency bin (thesis §5.2.3-5.2.4).

What is modelled: the **real and imaginary parts** of the compliance in each bin, two GPs per
bin (all bins and parts fitted in one batched call). The compliance is linear in the modal
residues and the H1 estimation error is close to complex Gaussian, so a Gaussian model of
Re/Im is consistent with both the physics and the noise; it keeps the phase (needed to
convolve forces, §3.5.2). A GP of |H| would lose the phase, and a GP of log|H| turns additive
noise into a biased multiplicative one near anti-resonances.

The pose inputs are whatever ``input_names`` says: the path coordinate ``("s_m",)`` (thesis
ch. 5) or workspace poses such as ``("x_mm", "y_mm", "rz_deg")`` or joint angles (the thesis'
future work, §5.5); use ``kernel="ard"`` for several inputs of different units.

Sources: EMA (hammer, group 0) and OMA (milling, group 1) have separate noise
hyperparameters (§5.2.4: different sensors). Updating with OMA FRFs (:meth:`FRFPoseModel.update`):

* ``"robust"`` (default) — *bias-aware* update, beyond the thesis. The OMA FRFs are checked
  against the current (EMA) model's predictive distribution before they are used:

  0. the window bias at the EMA dominant peak: a Hann-windowed Welch estimate is the FRF
     averaged over the window's spectral weight, which flattens a sharp peak; the expected
     ratio E[H1]/H per bin and segment comes from a one-mode fit to the EMA prediction at
     the segment's pose (resolution = grid step) and the OMA FRFs are divided by it;
  1. a complex scale of the OMA source (sensor-to-tool transfer, force-sensor gain, the
     Bussgang gain of a displacement quantised coarser than the vibration): per bin by
     weighted least squares on the predictive check, pooled by a weighted median; applied
     when it is off 1 by > 10 % and by more than its spread over the bins (std of the pooled
     estimate), if that spread is < 25 % of it; off 1 but less precise, the source gain is
     ambiguous and the direction is held back (neither 1 nor the estimate is established);
  2. per bin: the mean standardised residual over the OMA segments (a systematic offset in
     that bin: leakage at a sharp peak, a sensor resonance, a harmonic); bins whose bias
     test exceeds ``chi2_reject`` are rejected for OMA;
  3. per observation: bins of single segments whose standardised residual exceeds
     ``chi2_reject`` are rejected (outliers);
  4. the OMA noise of every bin (Re and Im) by maximising the marginal likelihood (Eq. 33)
     of all kept data with the EMA kernel hyperparameters fixed, floored by the H1 random
     error when ``noise_std`` is given (Bendat & Piersol ``sqrt((1 - γ²) / (2 n_d γ²))``
     with the coherence debiased for few averages, :func:`robovib.hybrid.h1_random_error`);
  5. the dominant peak of the EMA model: where the window bias exceeds 5 % (about
     (1/3)(1.5 df / B_r)^2 for Hann, B_r the half-power bandwidth) the OMA noise of the
     peak band is at least that bias x the peak |H|, and the dominant peak bin itself is
     kept from the EMA model (the OMA data there are held back);
  6. evidence: two folds of alternate OMA segments along the pose; each fold is predicted by
     the EMA model plus the other fold and by the EMA model alone; the whole direction is
     held back unless the held-out log predictive density summed over the bins gains
     > ln(number of bins tested) (one bin in many passes 1 nat by chance); then each bin
     keeps its posterior (weighted by its OMA noise) unless its held-out segments are
     predicted > 1 nat *worse* with OMA (evidence against OMA there: that bin is held
     back); the report says so in words (:meth:`UpdateReport.describe`);
  7. the posterior (Eq. 9-10) with those hyperparameters.

  The kernel hyperparameters stay those of the EMA fit, so OMA data can sharpen the
  prediction between EMA poses but cannot reshape the prior (the failure of ``"warm"`` on
  the Y direction of the study). What was rejected is in the :class:`UpdateReport`.
* ``"posterior"`` — hyperparameters kept, Eq. 9-10 with the enlarged data (OMA noise = EMA's);
* ``"warm"`` — hyperparameters re-optimised starting from the EMA optimum (the thesis' method);
* full retraining = a new :meth:`FRFPoseModel.fit` on all data from the default start.

Flagged OMA bins (harmonics, low coherence) enter as missing targets of those bins only.
"""

from __future__ import annotations

import time
import warnings
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
from sklearn.base import BaseEstimator
from sklearn.exceptions import NotFittedError

from ..campaign.selection import NextPoses, next_poses
from ..files.h5format import FRF_POSE_MODEL_FORMAT
from ..gp.regressor import BatchedGPRegressor, GPHyperparameters
from .frfs import frfs_on_grid

__all__ = ["FRFPoseModel", "UpdateReport", "frequency_grid"]


def frequency_grid(f_min_hz: float, f_max_hz: float, df_hz: float) -> np.ndarray:
    """The model's frequency grid ``f_min_hz, f_min_hz + df_hz, ... <= f_max_hz`` [Hz], checked.

    Parameters
    ----------
    f_min_hz
        First bin [Hz], >= 0.
    f_max_hz
        Upper end [Hz]; the last bin is the largest ``f_min_hz + i df_hz`` not above it.
    df_hz
        Bin spacing [Hz], > 0.

    Returns
    -------
    ndarray (n_f,)
        The bin frequencies [Hz], 2 <= n_f <= 100000.

    Raises
    ------
    ValueError
        Non-finite values, ``f_min_hz`` < 0 Hz, ``f_min_hz >= f_max_hz``, ``df_hz <= 0`` Hz, or a
        grid of fewer than 2 or more than 100000 bins.
    """
    from .._checks import check_number

    lo = check_number("f_min_hz", f_min_hz, "Hz", lo=0.0)
    hi = check_number("f_max_hz", f_max_hz, "Hz", lo=0.0, lo_open=True)
    df = check_number("df_hz", df_hz, "Hz", lo=0.0, lo_open=True)
    if lo >= hi:
        raise ValueError(f"f_min_hz={lo:g} Hz must be below f_max_hz={hi:g} Hz")
    n = int(np.floor((hi - lo) / df + 1e-9)) + 1
    if not 2 <= n <= 100_000:
        raise ValueError(
            f"grid {lo:g}-{hi:g} Hz in steps of {df:g} Hz has {n} bins; need 2 to 100000"
        )
    return lo + df * np.arange(n)


#: Units of the datasets of a saved model (compliance targets scaled to um/N).
_DATASET_UNITS = {
    "frequency_hz": "Hz", "X_train": "input units (input_names)", "Y_train": "um/N", "mask": "1",
    "groups": "1 (0=EMA, 1=OMA)", "theta": "1 (log hyperparameters, scaled)",
    "x_loc": "input units", "x_scale": "input units", "y_loc": "um/N", "y_scale": "um/N",
    "pose_lo": "input units", "pose_hi": "input units",
}  # fmt: skip
_FORMAT = FRF_POSE_MODEL_FORMAT
_VERSION = 2
_SCALE = 1e6  # m/N -> um/N: O(1) numbers inside the GPs
_MIN_GAIN_NATS = 1.0  # held-out log-density gain OMA must bring (per bin, per direction)
_SCALE_PRECISION = 0.25  # a source gain off 1 is applied when known to this relative std
UPDATE_MODES = ("robust", "posterior", "warm")


@dataclass(frozen=True)
class UpdateReport:
    """What a :meth:`FRFPoseModel.fit` / :meth:`FRFPoseModel.update` did.

    Attributes
    ----------
    mode
        ``"fit"``, ``"robust"``, ``"posterior"`` or ``"warm"``.
    iterations_total, iterations_mean_per_gp
        Quasi-Newton iterations (Eq. 34-36) over all 2 n_f GPs, and their mean.
    wall_time_s
        Wall time of the call [s].
    n_observations
        New (segment, bin) observations offered, unflagged.
    n_rejected
        Of those, rejected by the bias check (robust mode only).
    rejected_bins_hz
        Bins rejected for the new source as a whole (systematic bias) [Hz].
    scale, scale_std
        Complex scale of the new source relative to the model (1 = unbiased) and its std.
    scale_applied
        Whether the new FRFs were divided by ``scale`` (significant scale bias).
    noise_median_um_per_n
        Median over bins of the new source's noise std (Re/Im) used in the posterior [um/N].
    held_back_bins_hz
        Bins whose OMA data were held back: their held-out OMA segments were predicted
        > 1 nat worse with OMA data than by the model alone [Hz].
    held_back_all
        Whether the whole update was held back (the direction as a whole gained
        < ln(number of bins tested) nat, or its source gain is ambiguous).
    heldout_log_density_gain
        Held-out log predictive density, with OMA minus EMA alone, summed over bins [nat].
    reasons
        What was held back or down-weighted and why, in plain words.
    """

    mode: str
    iterations_total: int
    iterations_mean_per_gp: float
    wall_time_s: float
    n_observations: int = 0
    n_rejected: int = 0
    rejected_bins_hz: tuple[float, ...] = ()
    scale: complex = 1.0 + 0.0j
    scale_std: float = 0.0
    scale_applied: bool = False
    noise_median_um_per_n: float | None = None
    held_back_bins_hz: tuple[float, ...] = ()
    held_back_all: bool = False
    heldout_log_density_gain: float | None = None
    reasons: tuple[str, ...] = ()

    @property
    def rejected_fraction(self) -> float:
        return self.n_rejected / self.n_observations if self.n_observations else 0.0

    def describe(self) -> str:
        """One line on what the bias check rejected (robust mode) for a person to read.

        Returns
        -------
        str
            Rejected OMA bins (count and percent), whole bins rejected [Hz], the source scale
            and whether it was applied, then the ``reasons``, joined by ``"; "``.
        """
        bins = ", ".join(f"{f:.2f}" for f in self.rejected_bins_hz)
        whole = f"whole bins rejected at {bins} Hz" if bins else "no whole bin rejected"
        applied = "applied" if self.scale_applied else "not applied"
        line = (
            f"rejected {self.n_rejected} of {self.n_observations} OMA bins "
            f"({100 * self.rejected_fraction:.0f} %); {whole}; source scale "
            f"{abs(self.scale):.3f} ({applied})"
        )
        return "; ".join((line, *self.reasons))

    def to_dict(self) -> dict:
        """The report as a JSON-friendly dict.

        Returns
        -------
        dict
            Every field, with the complex ``scale`` split into ``scale_real`` and
            ``scale_imag``, tuples as lists, and ``rejected_fraction`` added.
        """
        d = asdict(self)
        d["scale_real"], d["scale_imag"] = float(self.scale.real), float(self.scale.imag)
        del d["scale"]
        d["rejected_bins_hz"] = list(self.rejected_bins_hz)
        d["held_back_bins_hz"] = list(self.held_back_bins_hz)
        d["reasons"] = list(self.reasons)
        d["rejected_fraction"] = self.rejected_fraction
        return d


def _gp_add(gp: BatchedGPRegressor, x, y, mask, groups, reoptimize: bool) -> None:
    """Add observations through the house's updating name (``update``)."""
    gp.update(x, y, mask=mask, groups=groups, mode="warm" if reoptimize else "posterior")


def _hann_bias_ratio(
    f: np.ndarray, h: np.ndarray, band: np.ndarray, df: float | None = None
) -> np.ndarray:
    """(n_f,) complex ratio E[H1] / H of a Hann-windowed Welch estimate, in the ``band`` bins.

    The expected H1 with a white force is the FRF averaged over the window's spectral
    weight |W(f)|^2 (Bendat & Piersol §9.1.4): at a sharp peak it falls below the peak. H
    between the grid bins comes from a one-mode fit (Levy's linearised least squares of
    ``(b0 + b1 s) / (s^2 + a1 s + a0)``) to ``h`` over the band +- 2 bins; ``df`` is the
    resolution of the estimate [Hz] (default the grid step). 1 outside the band and where
    the fit is no resonance.
    """
    ratio = np.ones(f.size, complex)
    idx = np.flatnonzero(band)
    lo, hi = max(idx[0] - 2, 0), min(idx[-1] + 3, f.size)
    fb, hb = f[lo:hi], h[lo:hi]
    sb = 2j * np.pi * fb
    a = np.column_stack([hb * sb, hb, -np.ones_like(hb), -sb])
    rhs = -hb * sb**2
    sol, *_ = np.linalg.lstsq(np.vstack([a.real, a.imag]), np.concatenate([rhs.real, rhs.imag]))
    a1, a0, b0, b1 = sol
    if not (a1 > 0 and a0 > 0):
        return ratio
    df = float(np.median(np.diff(f))) if df is None else float(df)
    u = np.arange(-4.0, 4.0 + 1e-9, 1.0 / 32)
    w = (0.5 * np.sinc(u) + 0.25 * np.sinc(u - 1) + 0.25 * np.sinc(u + 1)) ** 2
    w /= w.sum()

    def model(freq):
        s_ = 2j * np.pi * freq
        return (b0 + b1 * s_) / (s_**2 + a1 * s_ + a0)

    for k in idx:
        ratio[k] = np.sum(w * model(f[k] - u * df)) / model(f[k])
    return ratio


def _weighted_median(values: np.ndarray, weights: np.ndarray) -> float:
    order = np.argsort(values)
    cw = np.cumsum(weights[order])
    return float(values[order][np.searchsorted(cw, 0.5 * cw[-1])])


class FRFPoseModel(BaseEstimator):
    """Per-bin GP model of the compliance over the pose (``fit`` / ``update`` / ``predict``).

    Parameters
    ----------
    frequency_hz
        The common frequency grid (n_f,) [Hz]: all FRFs must be given on it.
    kernel
        ``"isotropic"`` (thesis Eq. 7) or ``"ard"`` (one length scale per pose input).
    n_restarts, rng
        Passed to :class:`~robovib.gp.BatchedGPRegressor` (2 n_f outputs, 2 noise groups).
    input_names
        Names (with units) of the pose columns, e.g. ``("s_m",)`` or
        ``("x_mm", "y_mm", "rz_deg")``; poses must have ``len(input_names)`` columns.
    chi2_reject
        Threshold of the chi-square(2) bias tests of the robust update (default 13.8: p = 0.001).

    Examples
    --------
    >>> import numpy as np
    >>> f = np.linspace(2, 30, 15)
    >>> s = np.array([0.0, 0.6, 1.2])
    >>> h = 1e-6 / (1 - (f[None] / (10 - 2 * s[:, None])) ** 2 + 0.3j)
    >>> FRFPoseModel(f).fit(s, h).predict([0.3]).shape
    (1, 15)
    """

    def __init__(
        self,
        frequency_hz,
        kernel: str = "isotropic",
        n_restarts: int | None = 0,
        rng=0,
        input_names: tuple[str, ...] = ("s_m",),
        chi2_reject: float = 13.8,
    ) -> None:
        self.frequency_hz = frequency_hz
        self.kernel = kernel
        self.n_restarts = n_restarts
        self.rng = rng
        self.input_names = input_names
        self.chi2_reject = chi2_reject

    # ------------------------------------------------------------------ input checks
    def _targets(self, frfs, mask):
        h = np.asarray(frfs, complex)
        n_f = self.frequency_hz_.size
        if h.ndim != 2 or h.shape[1] != n_f:
            raise ValueError(
                f"FRFs must be (n_poses, {n_f}) on the model's frequency grid, got {h.shape}"
            )
        m = np.ones(h.shape, bool) if mask is None else np.asarray(mask, bool)
        if m.shape != h.shape:
            raise ValueError(f"mask must have the FRFs' shape {h.shape}, got {m.shape}")
        if not np.all(np.isfinite(h[m])):
            raise ValueError("FRFs contain NaN or inf at unmasked bins")
        y = np.hstack([np.where(m, h.real, 0.0), np.where(m, h.imag, 0.0)]) * _SCALE
        return y, np.hstack([m, m])

    def _poses(self, poses) -> np.ndarray:
        p = np.asarray(poses, float)
        p = p[:, None] if p.ndim == 1 else p
        n_in = len(self.input_names)
        if p.ndim != 2 or p.shape[1] != n_in:
            raise ValueError(
                f"poses must be (n, {n_in}) with columns {tuple(self.input_names)}, got shape {p.shape}"
            )
        if not np.all(np.isfinite(p)):
            raise ValueError("poses contain NaN or inf")
        return p

    # ------------------------------------------------------------------ FRF objects, checked
    def fit_frfs(self, frfs) -> FRFPoseModel:
        """Fit from FRF objects carrying their pose (:func:`robovib.hybrid.frf_pose`), checked.

        All FRFs must be measured (EMA or OMA; the source sets the noise group) compliances of
        one direction, stored as ``direction_`` and checked by :meth:`update_frfs`; bins
        outside an FRF's range are an error.

        Parameters
        ----------
        frfs
            Iterable of :class:`robovib.frf.FRF` compliances [m/N] of one direction, each with
            its pose (:func:`robovib.hybrid.frf_pose`).

        Returns
        -------
        FRFPoseModel
            ``self``, fitted.

        Raises
        ------
        ValueError
            Mixed directions, model-source FRFs, or see :func:`robovib.hybrid.frfs_on_grid`.
        """
        frfs = list(frfs)
        direction = _common_direction(frfs, None, "fit")
        groups = _groups_of(frfs)
        h, x, m, _ = frfs_on_grid(frfs, np.asarray(self.frequency_hz, float), self.input_names)
        self.fit(x, h, mask=m, groups=groups)
        self.direction_ = direction
        return self

    def update_frfs(
        self,
        frfs,
        *,
        mode: str = "robust",
        reoptimize: bool = False,
        expect_source: str | None = "OMA",
    ) -> UpdateReport:
        """Bayesian update from FRF objects, checked against the model (see :meth:`update`).

        Each FRF's direction must be the model's (``hybrid update model_x.h5 oma_y.h5`` fails)
        and, with ``expect_source`` (default ``"OMA"``), its source must be that one (EMA FRFs
        given as OMA are refused rather than fitted with the OMA noise level). Grid bins
        outside an FRF's range are missing; the FRFs' random errors floor the OMA noise.

        Parameters
        ----------
        frfs
            Iterable of :class:`robovib.frf.FRF` compliances [m/N] with their pose, in the
            model's direction.
        mode
            ``"robust"``, ``"posterior"`` or ``"warm"`` (see :meth:`update`).
        reoptimize
            Robust mode: re-optimise all hyperparameters after the checks (see :meth:`update`).
        expect_source
            Source every FRF must have (``"OMA"``, ``"EMA"``), or None for no check.

        Returns
        -------
        UpdateReport
            What the update did (also stored as ``last_report_``).

        Raises
        ------
        ValueError
            Direction or source mismatch, or see :func:`robovib.hybrid.frfs_on_grid`.
        """
        self._require_fitted()
        frfs = list(frfs)
        if expect_source is not None:
            for i, f in enumerate(frfs):
                if f.source != expect_source:
                    raise ValueError(
                        f"FRF {i} is a {f.source} FRF; this update expects {expect_source} FRFs "
                        f"(e.g. from `hybrid oma`)"
                    )
        _common_direction(frfs, getattr(self, "direction_", None), "update")
        groups = _groups_of(frfs)
        h, x, m, err = frfs_on_grid(frfs, self.frequency_hz_, self.input_names, partial=True)
        resolution = float(np.median([f.df_hz for f in frfs])) if frfs else None
        return self.update(
            x, h, mask=m, groups=groups, mode=mode, noise_std=err, reoptimize=reoptimize,
            oma_resolution_hz=resolution,
        )  # fmt: skip

    @staticmethod
    def _groups(groups, sources, default: int, n: int) -> np.ndarray:
        if sources is not None:
            warnings.warn(
                "sources= is deprecated; pass the noise groups as groups=",
                DeprecationWarning,
                stacklevel=3,
            )
            groups = sources if groups is None else groups
        g = np.full(n, default, int) if groups is None else np.asarray(groups, int)
        if g.shape != (n,):
            raise ValueError(f"groups must have shape ({n},), got {g.shape}")
        return g

    # ------------------------------------------------------------------ fitting
    def fit(self, poses, frfs, mask=None, groups=None, sources=None) -> FRFPoseModel:
        """Fit from scratch (hyperparameters by Eq. 33).

        Parameters
        ----------
        poses
            (n,) or (n, n_inputs) pose inputs in the units of ``input_names``.
        frfs
            (n, n_f) complex compliance [m/N] on ``frequency_hz``.
        mask
            (n, n_f) bool, True where a bin is observed.
        groups
            (n,) ints: 0 = EMA, 1 = OMA (default all EMA).
        sources
            Deprecated name of ``groups``.

        Returns
        -------
        FRFPoseModel
            ``self``, fitted.

        Raises
        ------
        ValueError
            Bad grid, shapes, NaN at observed bins.
        """
        grid = np.asarray(self.frequency_hz, float)
        if grid.ndim != 1 or grid.size == 0 or not np.all(np.isfinite(grid)):
            raise ValueError("frequency_hz must be a non-empty 1-D array of finite values [Hz]")
        self.frequency_hz_ = grid
        x = self._poses(poses)
        y, m = self._targets(frfs, mask)
        g = self._groups(groups, sources, 0, x.shape[0])
        t0 = time.perf_counter()
        self.gp_ = BatchedGPRegressor(
            kernel=self.kernel, n_restarts=self.n_restarts, n_noise_groups=2, rng=self.rng
        )
        self.gp_.fit(x, y, mask=m, groups=g)
        self.last_report_ = UpdateReport(
            "fit",
            int(self.gp_.n_iter_.sum()),
            float(self.gp_.n_iter_.mean()),
            time.perf_counter() - t0,
        )
        self.pose_range_ = (x.min(axis=0), x.max(axis=0))
        self.n_features_in_ = x.shape[1]
        return self

    def update(
        self,
        poses,
        frfs,
        mask=None,
        groups=None,
        sources=None,
        *,
        mode: str = "robust",
        noise_std=None,
        reoptimize: bool = False,
        oma_resolution_hz: float | None = None,
    ) -> UpdateReport:
        """Bayesian update with new FRFs (thesis §5.2.4; ``"robust"`` is beyond the thesis).

        Parameters
        ----------
        poses, frfs, mask
            As in :meth:`fit`: (n,) / (n, n_inputs), (n, n_f) complex [m/N], (n, n_f) bool.
        groups
            (n,) noise groups of the new data (default 1 = OMA).
        sources
            Deprecated name of ``groups``.
        mode
            ``"robust"`` (bias check, rejection, OMA noise by marginal likelihood, see the
            module docs), ``"posterior"`` or ``"warm"``.
        noise_std
            Optional (n, n_f) random-error std of each new FRF bin [m/N] (e.g.
            :attr:`robovib.hybrid.OMASegment.random_error_m_per_n`): a floor for the OMA
            noise in robust mode.
        reoptimize
            Robust mode only: after the checks, re-optimise all hyperparameters (Eq. 33)
            starting from the EMA kernel and the estimated OMA noise (a warm start on the
            cleaned data).
        oma_resolution_hz
            Robust mode: frequency resolution of the (Hann-windowed Welch) OMA estimates [Hz],
            which sets their window bias at a sharp peak (steps 0 and 5 of the module docs);
            default the model's grid step; 0 for FRFs without window bias (e.g. synthetic).

        Returns
        -------
        UpdateReport

        Raises
        ------
        ValueError
            Unknown mode, bad shapes, NaN at observed bins.
        """
        if mode not in UPDATE_MODES:
            raise ValueError(f"unknown update mode {mode!r}; expected one of {UPDATE_MODES}")
        if oma_resolution_hz is not None:
            from .._checks import check_number

            oma_resolution_hz = check_number("oma_resolution_hz", oma_resolution_hz, "Hz", lo=0.0)
        self._require_fitted()
        x = self._poses(poses)
        y, m = self._targets(frfs, mask)
        g = self._groups(groups, sources, 1, x.shape[0])
        n_obs = int(m[:, : self.frequency_hz_.size].sum())
        t0 = time.perf_counter()
        if mode == "robust":
            if np.any(g != 1):
                raise ValueError(
                    "mode='robust' checks a new source against the model: the new FRFs must all be "
                    "group 1 (OMA); use mode='posterior' or 'warm' to add EMA FRFs (group 0)"
                )
            report = self._robust_update(
                x, y, m, g, noise_std, n_obs, reoptimize, oma_resolution_hz
            )
            report = UpdateReport(**{**asdict(report), "wall_time_s": time.perf_counter() - t0})
        else:
            # The OMA noise is not identifiable from EMA data alone: start it at the EMA
            # noise (kept there by "posterior", re-optimised by "warm").
            if not np.any(self.gp_._active_groups == 1):
                self.gp_._theta[:, -1] = self.gp_._theta[:, -2]
            _gp_add(self.gp_, x, y, m, g, reoptimize=(mode == "warm"))
            report = UpdateReport(
                mode,
                int(self.gp_.n_iter_.sum()),
                float(self.gp_.n_iter_.mean()),
                time.perf_counter() - t0,
                n_observations=n_obs,
            )
        self.last_report_ = report
        self.pose_range_ = (
            np.minimum(self.pose_range_[0], x.min(axis=0)),
            np.maximum(self.pose_range_[1], x.max(axis=0)),
        )
        return report

    # ------------------------------------------------------------------ robust update
    def _robust_update(
        self, x, y, m, g, noise_std, n_obs, reoptimize=False, resolution_hz=None
    ) -> UpdateReport:
        n_f = self.frequency_hz_.size
        gp = self.gp_
        mu, s = gp.predict(x, return_std=True)  # (n, 2 n_f) um/N, latent std
        if noise_std is None:
            sig = np.zeros_like(y)
        else:
            ns = np.asarray(noise_std, float)
            if ns.shape != (x.shape[0], n_f):
                raise ValueError(
                    f"noise_std must be (n, n_f) = {(x.shape[0], n_f)}, got {ns.shape}"
                )
            ns = np.where(m[:, :n_f], ns, 0.0)
            if np.any(~np.isfinite(ns)) or np.any(ns < 0):
                raise ValueError("noise_std must be finite and >= 0 [m/N]")
            sig = np.hstack([ns, ns]) * _SCALE
        # EMA noise (measurement noise of the reference) also separates the two sources.
        hp = gp.hyperparameters_
        ema_noise = np.asarray(hp.noise_std)[:, 0]
        var = s**2 + sig**2 + ema_noise[None, :] ** 2
        mc = mu[:, :n_f] + 1j * mu[:, n_f:]
        yc = y[:, :n_f] + 1j * y[:, n_f:]
        vc = var[:, :n_f] + var[:, n_f:]
        obs = m[:, :n_f]
        # 0. the window bias of the OMA spectra at the EMA dominant peak, known from the
        # physics of the estimator (Hann window of one grid step resolution): corrected.
        peak0, _ = self._peak_band(mc, resolution_hz)
        win_corr = np.ones_like(mc)
        if np.any(peak0):
            win_corr = np.array(
                [_hann_bias_ratio(self.frequency_hz_, h, peak0, resolution_hz) for h in mc]
            )
            yc = yc / win_corr
            sig = sig / np.hstack([np.abs(win_corr), np.abs(win_corr)])
        yc0, sig0 = yc, sig
        keep = obs.copy()
        # Alternate 1-3 until the kept set settles (a biased bin must not bend the scale).
        for _ in range(4):
            yc, sig = yc0, sig0
            var = s**2 + sig**2 + ema_noise[None, :] ** 2
            vc = var[:, :n_f] + var[:, n_f:]
            # 1. complex scale of the source: per bin by weighted LS (the maximum of the
            # diagonal marginal likelihood), pooled by a weighted median across bins.
            w = np.where(keep, 1.0 / vc, 0.0)
            den_f = np.sum(w * np.abs(mc) ** 2, axis=0)
            ok_f = den_f > 0
            scale, scale_std, applied, ambiguous = 1.0 + 0.0j, 0.0, False, False
            if np.count_nonzero(ok_f) >= 3:
                a_f = np.sum(w * np.conj(mc) * yc, axis=0)[ok_f] / den_f[ok_f]
                var_f = 1.0 / den_f[ok_f]
                # Weights capped at 3 x their median: the per-bin precisions rest on the
                # coherence of 2-3 Welch averages; one bin must not decide the source gain.
                w_f = np.minimum(1 / var_f, 3 * np.median(1 / var_f))
                a = complex(_weighted_median(a_f.real, w_f), _weighted_median(a_f.imag, w_f))
                scale = a
                scale_std = float(1.4826 * np.median(np.abs(a_f - a)) / np.sqrt(a_f.size))
                # A property of the source (a sensor gain: e.g. a displacement quantised
                # coarser than the vibration has a Bussgang gain > 1): significant against
                # the spread of the per-bin estimates, not only against each bin's noise.
                significant = abs(a - 1) > max(0.1, scale_std)
                ambiguous = significant and scale_std > _SCALE_PRECISION * abs(a)
                if significant and not ambiguous:
                    applied = True
                    yc = yc / a
                    sig = sig / abs(a)
                    var = s**2 + sig**2 + ema_noise[None, :] ** 2
                    vc = var[:, :n_f] + var[:, n_f:]
            r = np.where(obs, yc - mc, 0.0)
            # 2. systematic bias per bin: mean residual over segments against the model's
            # uncertainty there (EMA errors are correlated along the path: mean var, not /K).
            n_seg = obs.sum(axis=0)
            with np.errstate(invalid="ignore", divide="ignore"):
                mean_r = r.sum(axis=0) / n_seg
                spread = np.where(obs, np.abs(r - mean_r) ** 2, 0.0).sum(axis=0) / np.maximum(
                    n_seg - 1, 1
                )
                mean_var = np.where(obs, vc, 0.0).sum(axis=0) / n_seg
                chi_bin = 2 * np.abs(mean_r) ** 2 / (mean_var + spread / n_seg)
                # 3. single outliers: residual against predictive + this bin's scatter.
                chi_obs = 2 * np.abs(r) ** 2 / (vc + spread[None, :])
            bad_bin = (n_seg > 0) & (chi_bin > self.chi2_reject)
            bad_obs = obs & (chi_obs > self.chi2_reject)
            new_keep = obs & ~bad_bin[None, :] & ~bad_obs
            if np.array_equal(new_keep, keep):
                break
            keep = new_keep
        n_rej = int(obs.sum() - keep.sum())
        y_new = np.hstack([yc.real, yc.imag])
        m_new = np.hstack([keep, keep])
        # 4. OMA noise per output by marginal likelihood with the EMA kernel fixed.
        noise_oma = self._ml_source_noise(x, y_new, m_new, g, sig)
        noise = np.column_stack([ema_noise, noise_oma])
        hp_new = GPHyperparameters(
            signal_std=np.asarray(hp.signal_std),
            length_scales=np.asarray(hp.length_scales),
            noise_std=noise,
            mean=np.asarray(hp.mean),
        )
        # 5. evidence: held-out OMA segments (2-fold, alternate segments along the pose) must
        # be predicted better (log predictive density) with the other half's OMA data than
        # by the EMA model alone, per bin and for the direction as a whole.
        reasons = []
        # 6. the dominant peak: a windowed OMA spectrum biases a sharp peak by about
        # -(1/3)(B_e/B_r)^2 (Bendat & Piersol, B_e = 1.5 df for Hann, B_r the half-power
        # bandwidth); where that exceeds 5 % the EMA model keeps the peak band.
        peak, bias = self._peak_band(mc, resolution_hz)
        if np.any(peak):
            # EMA's own confidence there: the OMA noise is at least the expected bias.
            allow = np.where(peak, bias * np.max(np.sqrt(np.mean(np.abs(mc) ** 2, axis=0))), 0.0)
            noise_oma = np.maximum(noise_oma, np.hstack([allow, allow]))
            hp_new = GPHyperparameters(
                signal_std=hp_new.signal_std,
                length_scales=hp_new.length_scales,
                noise_std=np.column_stack([ema_noise, noise_oma]),
                mean=hp_new.mean,
            )
            lo, hi = self.frequency_hz_[peak].min(), self.frequency_hz_[peak].max()
            reasons.append(
                f"dominant peak {lo:.2f}-{hi:.2f} Hz down-weighted: at this frequency "
                f"resolution the OMA spectra may underestimate it by ~{100 * bias:.0f} %"
            )
        peak_bin = None
        if np.any(peak):
            # The dominant peak bin itself stays the EMA model's: there the window bias (and
            # its correction) is largest and the hammer test is at its best coherence.
            peak_bin = int(np.argmax(np.mean(np.abs(mc) ** 2, axis=0)))
            m_new[:, [peak_bin, n_f + peak_bin]] = False
            reasons.append(
                f"dominant peak bin {self.frequency_hz_[peak_bin]:.2f} Hz kept from the EMA model; "
                f"OMA corrected there for the window bias (up to "
                f"{100 * float(np.max(np.abs(1 - win_corr[:, peak]))):.0f} %)"
            )
        gain_f = self._heldout_gain(x, y_new, m_new, g, hp_new, noise_oma)
        held_all = False
        tested = np.isfinite(gain_f)
        # The direction as a whole must gain at least ln(n_t) nat, n_t bins tested (prior
        # odds 1/n_t that OMA informs a bin: one bin in many passes 1 nat by chance). Given
        # that, each bin keeps its posterior, which already weighs the OMA data by their
        # noise (a bin with little information barely moves); a bin is held back only on
        # evidence against OMA there (held-out segments predicted worse by > 1 nat: a bias
        # the noise model misses). Requiring each bin to gain > 1 nat instead discards
        # weakly informative bins and selects bins on the noise of their held-out gain.
        thr_dir = max(_MIN_GAIN_NATS, float(np.log(max(np.count_nonzero(tested), 1))))
        hold = tested & (gain_f < -_MIN_GAIN_NATS)
        total_gain = float(np.nansum(gain_f)) if np.any(tested) else None
        if ambiguous:
            held_all = True
            reasons.append(
                f"update held back for this direction: the OMA source gain is ambiguous "
                f"({abs(scale):.2f} +- {scale_std:.2f} against the EMA model: neither 1 nor "
                "the estimate is established, so the OMA levels cannot be trusted)"
            )
            m_new = np.zeros_like(m_new)
        elif total_gain is not None and total_gain <= thr_dir:
            held_all = True
            reasons.append(
                "update held back for this direction: held-out OMA segments are predicted no "
                f"better with OMA data than by the EMA model alone (log density gain "
                f"{total_gain:.1f} nat, needs > {thr_dir:.1f})"
            )
            m_new = np.zeros_like(m_new)
        elif np.any(hold):
            reasons.append(
                f"{int(hold.sum())} of {int(tested.sum())} bins held back: there the held-out "
                "OMA segments are predicted more than 1 nat worse with OMA data than by the EMA "
                "model alone"
            )
            m_new = m_new & ~np.hstack([hold, hold])[None, :]
        X_all = np.vstack([gp.X_train_, x])
        Y_all = np.vstack([np.where(gp.mask_, gp.Y_train_, 0.0), np.where(m_new, y_new, 0.0)])
        M_all = np.vstack([gp.mask_, m_new])
        G_all = np.concatenate([gp._active_groups, g])
        new = BatchedGPRegressor(
            kernel=self.kernel,
            optimizer="bfgs" if reoptimize and not held_all else None,
            n_restarts=0,
            initial_hyperparameters=hp_new,
            n_noise_groups=2,
            rng=self.rng,
        )
        new.fit(X_all, Y_all, mask=M_all, groups=G_all)
        if not reoptimize or held_all:
            new.n_iter_ = np.zeros(2 * n_f, int)
        self.gp_ = new
        rej_hz = tuple(float(f) for f in self.frequency_hz_[bad_bin])
        hold_hz = tuple(float(f) for f in self.frequency_hz_[hold]) if not held_all else ()
        return UpdateReport(
            "robust",
            int(new.n_iter_.sum()),
            float(new.n_iter_.mean()),
            0.0,
            n_observations=n_obs,
            n_rejected=n_rej,
            rejected_bins_hz=rej_hz,
            scale=complex(scale),
            scale_std=float(scale_std),
            scale_applied=bool(applied),
            noise_median_um_per_n=float(np.median(noise_oma)),
            held_back_bins_hz=hold_hz,
            held_back_all=held_all,
            heldout_log_density_gain=total_gain,
            reasons=tuple(reasons),
        )

    def _peak_band(self, mc, resolution_hz=None) -> tuple[np.ndarray, float]:
        """Bins of the EMA dominant peak's half-power band (+1 bin each side) where the
        window bias of the OMA estimate, (1/3)(1.5 df / B_r)^2, exceeds 5 %."""
        f = self.frequency_hz_
        band = np.zeros(f.size, bool)
        if f.size < 3:
            return band, 0.0
        mag = np.sqrt(np.mean(np.abs(mc) ** 2, axis=0))
        k = int(np.argmax(mag))
        half = mag >= mag[k] / np.sqrt(2)
        lo = k
        while lo > 0 and half[lo - 1]:
            lo -= 1
        hi = k
        while hi < f.size - 1 and half[hi + 1]:
            hi += 1
        step = float(np.median(np.diff(f)))
        df = step if resolution_hz is None else float(resolution_hz)
        if df <= 0:
            return band, 0.0
        b_r = max(f[hi] - f[lo] + step, step)
        bias = min((1.5 * df / b_r) ** 2 / 3, 1.0)
        if bias > 0.05:
            band[max(lo - 1, 0) : hi + 2] = True
        return band, bias

    def _posterior(self, x, y, m, g, hp) -> BatchedGPRegressor:
        """The GP with hyperparameters ``hp`` (not re-optimised) on the given data."""
        sub = BatchedGPRegressor(
            kernel=self.kernel,
            optimizer=None,
            n_restarts=0,
            initial_hyperparameters=hp,
            n_noise_groups=2,
            rng=self.rng,
        )
        sub.fit(x, np.where(m, y, 0.0), mask=m, groups=g)
        return sub

    def _heldout_gain(self, x, y, m, g, hp_new, noise_oma) -> np.ndarray:
        """Per bin: held-out log predictive density of the OMA data, updated minus EMA-only.

        Two folds (alternate segments in pose order); each fold's observations are predicted
        by the EMA model plus the other fold's kept OMA data (hyperparameters ``hp_new``) and
        by the EMA model alone, both with the OMA noise ``noise_oma`` (Re/Im summed). NaN
        where a bin has no held-out observation or fewer than 4 OMA segments are kept.
        """
        gp = self.gp_
        n_f = self.frequency_hz_.size
        n = x.shape[0]
        gain = np.zeros(2 * n_f)
        count = np.zeros(2 * n_f)
        if n < 4:
            return np.full(n_f, np.nan)
        order = np.argsort(x[:, 0], kind="stable")
        fold = np.zeros(n, int)
        fold[order[1::2]] = 1
        mu0, s0 = gp.predict(x, return_std=True)
        nv = noise_oma[None, :] ** 2
        for k in (0, 1):
            tr, te = fold != k, fold == k
            sub = BatchedGPRegressor(
                kernel=self.kernel,
                optimizer=None,
                n_restarts=0,
                initial_hyperparameters=hp_new,
                n_noise_groups=2,
                rng=self.rng,
            )
            sub.fit(
                np.vstack([gp.X_train_, x[tr]]),
                np.vstack([np.where(gp.mask_, gp.Y_train_, 0.0), np.where(m[tr], y[tr], 0.0)]),
                mask=np.vstack([gp.mask_, m[tr]]),
                groups=np.concatenate([gp._active_groups, g[tr]]),
            )
            mu1, s1 = sub.predict(x[te], return_std=True)
            v0, v1 = s0[te] ** 2 + nv, s1**2 + nv
            yt = y[te]
            lp0 = -0.5 * (np.log(v0) + (yt - mu0[te]) ** 2 / v0)
            lp1 = -0.5 * (np.log(v1) + (yt - mu1) ** 2 / v1)
            mt = m[te]
            gain += np.where(mt, lp1 - lp0, 0.0).sum(axis=0)
            count += mt.sum(axis=0)
        g_f = gain[:n_f] + gain[n_f:]
        c_f = count[:n_f]
        return np.where(c_f > 0, g_f, np.nan)

    def _ml_source_noise(self, x_new, y_new, m_new, g_new, sig_floor) -> np.ndarray:
        """Noise std per output [um/N] of the new group maximising Eq. 33, kernel fixed.

        A log grid search (robust, no derivatives) over [1e-3, 1e3] x the output's signal std;
        the result is floored by the RMS of the given random errors of that output.
        """
        gp = self.gp_
        hp = gp.hyperparameters_
        X = np.vstack([gp.X_train_, x_new])
        Y = np.vstack([np.where(gp.mask_, gp.Y_train_, 0.0), y_new]).T  # (B, n)
        M = np.vstack([gp.mask_, m_new]).T
        G = np.concatenate([gp._active_groups, g_new])
        sf = np.asarray(hp.signal_std)
        ls = np.asarray(hp.length_scales)  # (B, d) data units
        d2 = (X[:, None, :] - X[None, :, :]) ** 2  # (n, n, d)
        dist = np.einsum("ijd,bd->bij", d2, 1.0 / ls**2)
        kf = sf[:, None, None] ** 2 * np.exp(-0.5 * dist)
        pair = M[:, :, None] & M[:, None, :]
        kf = np.where(pair, kf, 0.0)
        ema_var = np.asarray(hp.noise_std)[:, 0] ** 2
        is_new = G == 1
        grid = np.exp(np.linspace(np.log(1e-3), np.log(1e3), 61))
        best = np.full(Y.shape[0], np.inf)
        best_noise = sf * 0.1
        idx = np.arange(X.shape[0])
        ones = M.astype(float)
        for gv in grid:
            nv = (gv * sf) ** 2
            diag = np.where(is_new[None, :], nv[:, None], ema_var[:, None])
            diag = np.where(M, diag, 1.0)
            ky = kf.copy()
            ky[:, idx, idx] += diag
            try:
                chol = np.linalg.cholesky(ky)
            except np.linalg.LinAlgError:
                continue
            kinv = np.linalg.inv(ky)
            k1 = np.einsum("bij,bj->bi", kinv, ones)
            mean = np.sum(k1 * Y, axis=1) / np.sum(k1 * ones, axis=1)
            r = np.where(M, Y - mean[:, None], 0.0)
            quad = np.einsum("bi,bij,bj->b", r, kinv, r)
            logdet = 2 * np.sum(np.log(np.diagonal(chol, axis1=1, axis2=2)), axis=1)
            nll = 0.5 * quad + 0.5 * logdet
            better = nll < best
            best = np.where(better, nll, best)
            best_noise = np.where(better, gv * sf, best_noise)
        n_new = m_new.sum(axis=0)
        floor = np.sqrt(np.where(m_new, sig_floor**2, 0.0).sum(axis=0) / np.maximum(n_new, 1))
        return np.maximum(best_noise, floor)

    # ------------------------------------------------------------------ prediction
    def _require_fitted(self):
        if not hasattr(self, "gp_"):
            raise NotFittedError("this FRFPoseModel is not fitted yet; call fit() first")

    def extrapolating(self, poses) -> np.ndarray:
        """Which poses lie outside the calibrated range (per coordinate).

        Parameters
        ----------
        poses
            (n,) or (n, n_inputs) in the units of ``input_names``.

        Returns
        -------
        ndarray of bool (n,)
            True where any coordinate is outside the range of the training poses (by more
            than 1e-9 of that range: the rule of every pose model,
            :class:`robovib.gp.extrapolation.TrainingRegion`).
        """
        from ..gp.extrapolation import extrapolating

        self._require_fitted()
        return extrapolating(self, self._poses(poses))

    def predict(self, poses, return_std: bool = False):
        """Complex compliance at poses (thesis Eq. 9-10 per bin).

        Parameters
        ----------
        poses
            (n,) or (n, n_inputs) in the units of ``input_names``.
        return_std
            Also return the latent std ``sqrt(var Re + var Im)`` (n, n_f) [m/N].

        Returns
        -------
        h : (n, n_f) complex [m/N]
        std : (n, n_f) [m/N], if ``return_std``
        """
        self._require_fitted()
        x = self._poses(poses)
        mean, std = self.gp_.predict(x, return_std=True)
        n_f = self.frequency_hz_.size
        h = (mean[:, :n_f] + 1j * mean[:, n_f:]) / _SCALE
        if not return_std:
            return h
        return h, np.sqrt(std[:, :n_f] ** 2 + std[:, n_f:] ** 2) / _SCALE

    def integrated_variance(self, poses) -> np.ndarray:
        """Predictive variance summed over frequency and Re/Im, per pose.

        The sum over the 2 n_f GPs of the latent variance (thesis Eq. 10) at each pose.

        Parameters
        ----------
        poses
            (n,) or (n, n_inputs) in the units of ``input_names``.

        Returns
        -------
        ndarray (n,)
            Integrated predictive variance [(um/N)^2].
        """
        self._require_fitted()
        _, std = self.gp_.predict(self._poses(poses), return_std=True)
        return np.sum(std**2, axis=1)

    @property
    def X_train_(self) -> np.ndarray:
        """(n, n_inputs) training poses (EMA and OMA rows) in the units of ``input_names``."""
        return self.gp_.X_train_

    def gp_posteriors(self) -> list[tuple]:
        """The model's GP for :func:`robovib.campaign.next_poses` (its model protocol).

        Returns
        -------
        list of tuple
            One ``(posterior, noise_std, signal_std, columns, mode)``: the
            :class:`~robovib.gp.posterior.GPPosterior` of the 2 n_f GPs (Re, then Im, of each
            bin), the EMA (group 0) noise std and the signal std (2 n_f,) [um/N], the output
            columns ``0 .. 2 n_f - 1`` and mode 0.
        """
        from ..gp.predictive import noise_std_of

        self._require_fitted()
        hp = self.gp_.hyperparameters_
        n_out = 2 * self.frequency_hz_.size
        signal = np.broadcast_to(np.asarray(hp.signal_std, float), (n_out,))
        return [(self.gp_.posterior_, noise_std_of(hp), signal, np.arange(n_out), 0)]

    def next_poses(self, candidates, k: int = 3) -> NextPoses:
        """The next ``k`` hammer-test poses: :func:`robovib.campaign.next_poses` on this model.

        Greedy integrated-variance reduction (the package's one next-poses algorithm): each
        pick maximises the reduction of the latent variance (thesis Eq. 10) summed over all
        candidates, bins and Re/Im (each GP normalised by its prior variance), the earlier
        picks conditioned on as EMA measurements (a GP's variance does not depend on the
        observed value).

        Parameters
        ----------
        candidates
            (m,) or (m, n_inputs) candidate poses in the units of ``input_names``.
        k
            Poses to choose (1 <= k <= m).

        Returns
        -------
        NextPoses
            The chosen poses (``poses``, (k, n_inputs), in pick order) with the candidates'
            variance for :func:`robovib.campaign.plot_next_poses`.

        Raises
        ------
        NotFittedError, ValueError
            Unfitted model, bad candidates or ``k``.
        """
        self._require_fitted()
        return next_poses(self, self._poses(candidates), k)

    # ------------------------------------------------------------------ persistence (no pickle)
    def save(self, path, *, provenance: dict | None = None, inputs=(), force: bool = False) -> None:
        """HDF5 (atomic): training data, hyperparameters, scalers, units and provenance.

        Attributes: ``format``, ``format_version``, ``robovib_version``, ``created_utc``,
        ``units`` (the header of :mod:`robovib.files.h5format`; files of older robovib say
        ``version``), ``kernel``,
        ``input_names`` (units in the names), ``direction`` (x, y, z or empty),
        ``compliance_unit = "um/N"`` (training targets and noise), ``frequency_unit = "Hz"``,
        ``groups = "0=EMA,1=OMA"``, and ``provenance/<key>`` for the given dict
        (strings/numbers). Written through :func:`robovib.io.atomic_output`: ``path`` must not
        be one of ``inputs`` unless ``force``.

        Parameters
        ----------
        path
            Output ``.h5`` file.
        provenance
            Extra ``provenance/<key>`` attributes (strings or numbers).
        inputs
            Files the model was made from (recorded with their hashes; ``path`` may not be one).
        force
            Allow ``path`` to be one of ``inputs``.
        """
        import h5py

        from ..files.h5format import write_header
        from ..files.h5safe import USERBLOCK_SIZE, seal, seal_file
        from ..files.provenance import set_units, write_provenance
        from ..files.safe_write import atomic_output

        self._require_fitted()
        gp = self.gp_
        with atomic_output(path, inputs=inputs, force=force) as tmp:
            with h5py.File(tmp, "w", userblock_size=USERBLOCK_SIZE) as h5:
                write_header(
                    h5, _FORMAT, _VERSION,
                    units="frequency_hz Hz; targets and noise um/N (Re, Im of compliance); inputs "
                    "in the units of input_names; every dataset's unit in its 'units' attribute",
                )  # fmt: skip
                h5.attrs["kernel"] = self.kernel
                h5.attrs["input_names"] = list(self.input_names)
                h5.attrs["direction"] = getattr(self, "direction_", None) or ""
                h5.attrs["compliance_unit"] = "um/N"
                h5.attrs["frequency_unit"] = "Hz"
                h5.attrs["groups"] = "0=EMA,1=OMA"
                h5.attrs["targets"] = "columns: Re of n_f bins, then Im of n_f bins"
                for key, value in (provenance or {}).items():
                    h5.attrs[f"provenance/{key}"] = value
                for name, value in {
                    "frequency_hz": self.frequency_hz_, "X_train": gp.X_train_, "Y_train": np.nan_to_num(gp.Y_train_),
                    "mask": gp.mask_, "groups": gp._active_groups, "theta": gp._theta, "x_loc": gp._x_loc,
                    "x_scale": gp._x_scale, "y_loc": gp._y_loc, "y_scale": gp._y_scale,
                    "pose_lo": self.pose_range_[0], "pose_hi": self.pose_range_[1],
                }.items():  # fmt: skip
                    set_units(
                        h5.create_dataset(name, data=value), _DATASET_UNITS.get(name, "input units")
                    )
                write_provenance(h5, inputs=inputs)
                seal(h5)
            seal_file(tmp)

    @classmethod
    def load(cls, path) -> FRFPoseModel:
        """Read a model written by :meth:`save` (versions 1 and 2).

        Parameters
        ----------
        path
            A ``.h5`` file written by :meth:`save`.

        Returns
        -------
        FRFPoseModel
            The fitted model (training data, hyperparameters and scalers as saved).

        Raises
        ------
        ValueError
            Not HDF5, or not a robovib FRF pose model.
        """
        from ..files.h5format import open_verified, read_tree

        path = Path(path)
        h5, _, _, _ = open_verified(
            path, {_FORMAT: _VERSION}, what="robovib FRF pose model", read_whole=True
        )
        with h5:
            tree = read_tree(h5, path)  # links, storage and checksum checked as it reads
        d, kernel, direction, names = _checked_model_tree(tree, path)
        model = cls(d["frequency_hz"], kernel=kernel, input_names=names)
        gp = BatchedGPRegressor(kernel=kernel, n_noise_groups=2)
        gp._x_loc, gp._x_scale, gp._y_loc, gp._y_scale = (
            d["x_loc"],
            d["x_scale"],
            d["y_loc"],
            d["y_scale"],
        )
        gp._theta = d["theta"]
        gp._active_groups = d["groups"].astype(int)
        gp._squeeze = False
        gp.n_iter_ = np.zeros(gp._theta.shape[0], int)
        try:
            gp._set_training_data(d["X_train"], d["Y_train"], d["mask"].astype(bool))
        except (ValueError, np.linalg.LinAlgError):
            from ..files.h5safe import FileContentError

            raise FileContentError(
                path,
                "the stored GP (theta, X_train, Y_train) cannot be factorised: the file is "
                "damaged or was not written by robovib",
            ) from None
        model.gp_ = gp
        model.frequency_hz_ = np.asarray(d["frequency_hz"], float)
        model.pose_range_ = (d["pose_lo"], d["pose_hi"])
        model.direction_ = direction
        model.n_features_in_ = len(names)
        return model


def _checked_model_tree(tree, path):
    """The datasets and attributes of a hybrid model file, each checked for type, shape and
    finiteness (one-line errors naming the file and the member)."""
    from ..files.h5format import as_text
    from ..gp.pose_checks import MAX_TRAINING_POINTS, TreeChecker

    c = TreeChecker(path)
    kernel = c.text(tree, "kernel", "")
    if kernel not in ("ard", "isotropic"):
        c.fail("/", f"attribute 'kernel' is {kernel!r}, expected 'ard' or 'isotropic'")
    direction = as_text(tree.attrs.get("direction", "")) or None
    if direction not in (None, "x", "y", "z"):
        c.fail("/", f"attribute 'direction' is {direction!r}, expected x, y, z or empty")
    raw_names = np.asarray(tree.attrs.get("input_names", ["s_m"]))
    if raw_names.ndim != 1 or raw_names.size == 0 or raw_names.dtype.kind not in "OSU":
        c.fail("/", "attribute 'input_names' is not a list of names")
    names = tuple(as_text(v) for v in raw_names.tolist())
    n_in = len(names)
    f = c.array(tree, "frequency_hz", "", kind="iuf", shape=(None,), finite=True)
    if f.size < 2 or np.any(np.diff(f) <= 0):
        c.fail("frequency_hz", "is not an increasing axis of at least 2 bins")
    n_out = 2 * f.size
    X = c.array(tree, "X_train", "", kind="f", shape=(None, n_in), finite=True)
    n = X.shape[0]
    if not 1 <= n <= MAX_TRAINING_POINTS:
        c.fail("X_train", f"{n} training points; a model holds 1 to {MAX_TRAINING_POINTS}")
    d = {"frequency_hz": f, "X_train": X}
    d["Y_train"] = c.array(tree, "Y_train", "", kind="f", shape=(n, n_out), finite=True)
    d["mask"] = c.array(tree, "mask", "", kind="biu", shape=(n, n_out))
    groups = c.array(tree, "groups", "", kind="iu", shape=(n,))
    if np.any((groups != 0) & (groups != 1)):
        c.fail("groups", "holds noise groups other than 0 (EMA) and 1 (OMA)")
    d["groups"] = groups
    theta = c.array(tree, "theta", "", kind="f", shape=(n_out, None), finite=True)
    if theta.shape[1] - 3 not in (1, n_in):
        c.fail("theta", f"has shape {theta.shape}, expected ({n_out}, {n_in + 3} or 4)")
    d["theta"] = theta
    for key, size, positive in (("x_loc", n_in, False), ("x_scale", n_in, True),
                                ("y_loc", n_out, False), ("y_scale", n_out, True),
                                ("pose_lo", n_in, False), ("pose_hi", n_in, False)):  # fmt: skip
        d[key] = c.array(tree, key, "", kind="f", shape=(size,), finite=True, positive=positive)
    return d, kernel, direction, names


_GROUP = {"EMA": 0, "OMA": 1}


def _groups_of(frfs) -> np.ndarray:
    """Noise group per FRF from its source (0 = EMA, 1 = OMA); model FRFs are refused."""
    for i, f in enumerate(frfs):
        if f.source not in _GROUP:
            raise ValueError(f"FRF {i} has source {f.source!r}; expected measured EMA or OMA")
    return np.array([_GROUP[f.source] for f in frfs], int)


def _common_direction(frfs, model_direction, what):
    dirs = {f.direction for f in frfs} - {None}
    if len(dirs) > 1:
        raise ValueError(f"cannot {what} one model with FRFs of several directions {sorted(dirs)}")
    direction = dirs.pop() if dirs else None
    if model_direction is not None and direction is not None and direction != model_direction:
        raise ValueError(
            f"the model is of direction {model_direction!r} but the FRFs are {direction!r}: "
            "a model must be updated with FRFs of its own direction"
        )
    return direction
