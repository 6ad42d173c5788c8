"""The robust (bias-aware) Bayesian update of an FRF pose model with OMA FRFs, and its report.

:func:`robust_update` (the ``"robust"`` mode of :meth:`robovib.hybrid.FRFPoseModel.update`,
beyond the thesis) is a function of the model's GP and the new arrays. The OMA FRFs are checked
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
the Y direction of the study). What was rejected is in the :class:`UpdateReport` (the report of every update).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from ..gp._state import noise_groups
from ..gp.regressor import BatchedGPRegressor, GPHyperparameters

__all__ = ["UpdateReport", "peak_band", "robust_update"]

_MIN_GAIN_NATS = 1.0  # held-out log-density gain OMA must bring (per bin, per direction)
_SCALE_PRECISION = 0.25  # a source gain off 1 is applied when known to this relative std


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


def robust_update(
    gp: BatchedGPRegressor,
    frequency_hz: np.ndarray,
    x: np.ndarray,
    y: np.ndarray,
    m: np.ndarray,
    g: np.ndarray,
    *,
    noise_std: np.ndarray | None = None,
    chi2_reject: float = 13.8,
    reoptimize: bool = False,
    resolution_hz: float | None = None,
    rng=0,
) -> tuple[BatchedGPRegressor, UpdateReport]:
    """The robust update of an EMA model's GP with OMA data (steps 0-7 of this module's docs).

    Parameters
    ----------
    gp
        The fitted GP of the model: 2 n_f outputs (Re of the bins, then Im), 2 noise groups
        (0 = EMA, 1 = OMA); targets in the model's units (um/N). Not modified.
    frequency_hz
        (n_f,) the model's bins [Hz].
    x, y, m, g
        The new poses (n, d), targets (n, 2 n_f), observed mask (n, 2 n_f) and noise groups
        (n,), all 1 (OMA).
    noise_std
        Optional (n, n_f) random-error std of each new bin, in the targets' units, 0 where
        unobserved: a floor for the OMA noise.
    chi2_reject
        Threshold of the chi-square(2) bias tests.
    reoptimize
        Re-optimise all hyperparameters after the checks (warm start on the cleaned data).
    resolution_hz
        Frequency resolution of the (Hann-windowed Welch) OMA estimates [Hz]; default the
        grid step; 0 for FRFs without window bias.
    rng
        Seed of the new GP.

    Returns
    -------
    tuple of (BatchedGPRegressor, UpdateReport)
        The updated GP (a new object) and what the update did (``wall_time_s`` 0: the
        caller times it).
    """
    n_f = frequency_hz.size
    n_obs = int(m[:, :n_f].sum())
    mu, s = gp.predict(x, return_std=True)  # (n, 2 n_f) um/N, latent std
    sig = np.zeros_like(y) if noise_std is None else np.hstack([noise_std, noise_std])
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
    peak0, _ = peak_band(frequency_hz, mc, resolution_hz)
    win_corr = np.ones_like(mc)
    if np.any(peak0):
        win_corr = np.array([_hann_bias_ratio(frequency_hz, h, peak0, resolution_hz) for h in mc])
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
        bad_bin = (n_seg > 0) & (chi_bin > chi2_reject)
        bad_obs = obs & (chi_obs > chi2_reject)
        new_keep = obs & ~bad_bin[None, :] & ~bad_obs
        if np.array_equal(new_keep, keep):
            break
        keep = new_keep
    n_rej = int(obs.sum() - keep.sum())
    y_new = np.hstack([yc.real, yc.imag])
    m_new = np.hstack([keep, keep])
    # 4. OMA noise per output by marginal likelihood with the EMA kernel fixed.
    noise_oma = _ml_source_noise(gp, x, y_new, m_new, g, sig)
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
    peak, bias = peak_band(frequency_hz, mc, resolution_hz)
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
        lo, hi = frequency_hz[peak].min(), frequency_hz[peak].max()
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
            f"dominant peak bin {frequency_hz[peak_bin]:.2f} Hz kept from the EMA model; "
            f"OMA corrected there for the window bias (up to "
            f"{100 * float(np.max(np.abs(1 - win_corr[:, peak]))):.0f} %)"
        )
    gain_f = _heldout_gain(gp, x, y_new, m_new, g, hp_new, noise_oma, rng)
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
    G_all = np.concatenate([noise_groups(gp), g])
    new = BatchedGPRegressor(
        kernel=gp.kernel,
        optimizer="bfgs" if reoptimize and not held_all else None,
        n_restarts=0,
        initial_hyperparameters=hp_new,
        n_noise_groups=2,
        rng=rng,
    )
    new.fit(X_all, Y_all, mask=M_all, groups=G_all)
    if not reoptimize or held_all:
        new.n_iter_ = np.zeros(2 * n_f, int)
    rej_hz = tuple(float(f) for f in frequency_hz[bad_bin])
    hold_hz = tuple(float(f) for f in frequency_hz[hold]) if not held_all else ()
    return new, UpdateReport(
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


def peak_band(frequency_hz, mc, resolution_hz=None) -> tuple[np.ndarray, float]:
    """The dominant peak's band where a Hann-windowed Welch estimate is biased by > 5 %.

    Parameters
    ----------
    frequency_hz
        (n_f,) bins [Hz].
    mc
        (n, n_f) complex FRFs (e.g. the EMA model's predictions at the OMA poses); the peak
        is that of their RMS over the rows.
    resolution_hz
        Resolution of the windowed estimate [Hz]; default the grid step; <= 0: no bias.

    Returns
    -------
    band : ndarray of bool (n_f,)
        The half-power band (+1 bin each side) where the window bias
        (1/3)(1.5 df / B_r)^2 (Bendat & Piersol, B_r the half-power bandwidth) exceeds 5 %;
        all False otherwise.
    bias : float
        That bias (0 to 1).
    """
    f = np.asarray(frequency_hz, float)
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


def _heldout_gain(gp, x, y, m, g, hp_new, noise_oma, rng) -> np.ndarray:
    """Per bin: held-out log predictive density of the OMA data, updated minus EMA-only.

    Two folds (alternate segments in pose order); each fold's observations are predicted
    by the EMA model plus the other fold's kept OMA data (hyperparameters ``hp_new``) and
    by the EMA model alone, both with the OMA noise ``noise_oma`` (Re/Im summed). NaN
    where a bin has no held-out observation or fewer than 4 OMA segments are kept.
    """
    n_f = y.shape[1] // 2
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
            kernel=gp.kernel,
            optimizer=None,
            n_restarts=0,
            initial_hyperparameters=hp_new,
            n_noise_groups=2,
            rng=rng,
        )
        sub.fit(
            np.vstack([gp.X_train_, x[tr]]),
            np.vstack([np.where(gp.mask_, gp.Y_train_, 0.0), np.where(m[tr], y[tr], 0.0)]),
            mask=np.vstack([gp.mask_, m[tr]]),
            groups=np.concatenate([noise_groups(gp), g[tr]]),
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


def _ml_source_noise(gp, x_new, y_new, m_new, g_new, sig_floor) -> np.ndarray:
    """Noise std per output [um/N] of the new group maximising Eq. 33, kernel fixed.

    A log grid search (robust, no derivatives) over [1e-3, 1e3] x the output's signal std;
    the result is floored by the RMS of the given random errors of that output.
    """
    hp = gp.hyperparameters_
    X = np.vstack([gp.X_train_, x_new])
    Y = np.vstack([np.where(gp.mask_, gp.Y_train_, 0.0), y_new]).T  # (B, n)
    M = np.vstack([gp.mask_, m_new]).T
    G = np.concatenate([noise_groups(gp), g_new])
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
