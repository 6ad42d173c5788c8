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

* ``"robust"`` (default) — *bias-aware* update, beyond the thesis: the OMA FRFs are checked
  against the current (EMA) model's predictive distribution before they are used (window bias,
  source gain, biased bins, outliers, OMA noise by marginal likelihood, held-out evidence); the
  kernel hyperparameters stay those of the EMA fit. The steps:
  :mod:`robovib.hybrid.robust_update`; what was rejected is in the :class:`UpdateReport`.
* ``"posterior"`` — hyperparameters kept, Eq. 9-10 with the enlarged data (OMA noise = EMA's);
* ``"warm"`` — hyperparameters re-optimised starting from the EMA optimum (the thesis' method);
* full retraining = a new :meth:`FRFPoseModel.fit` on all data from the default start.

Flagged OMA bins (harmonics, low coherence) enter as missing targets of those bins only.

The file layout is :mod:`robovib.hybrid.model_file`; the model's frequency grid is
:func:`robovib.hybrid.frfs.frequency_grid`.
"""

from __future__ import annotations

import dataclasses
import time
import warnings

import numpy as np
from sklearn.base import BaseEstimator
from sklearn.exceptions import NotFittedError

from ..campaign.selection import NextPoses, next_poses
from ..gp._state import start_noise_group_like
from ..gp.regressor import BatchedGPRegressor
from .frfs import frequency_grid, frfs_on_grid
from .model_file import load_frf_pose_model, save_frf_pose_model
from .robust_update import UpdateReport, robust_update

__all__ = ["FRFPoseModel", "UpdateReport", "frequency_grid"]


_SCALE = 1e6  # m/N -> um/N: O(1) numbers inside the GPs
UPDATE_MODES = ("robust", "posterior", "warm")


def _gp_add(gp: BatchedGPRegressor, x, y, mask, groups, reoptimize: bool) -> None:
    """Add observations through the house's updating name (``update``)."""
    gp.update(x, y, mask=mask, groups=groups, mode="warm" if reoptimize else "posterior")


class FRFPoseModel(BaseEstimator):
    """Per-bin GP model of the compliance over the pose (``fit`` / ``update`` / ``predict``).

    Parameters
    ----------
    frequency_hz
        The common frequency grid (n_f,) [Hz]: all FRFs must be given on it.
    kernel : {"isotropic", "ard"}
        The length scales of the GP (not its covariance family): one shared by all pose inputs
        (``"isotropic"``, thesis Eq. 7) or one per pose input (``"ard"``).
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
            ``"robust"`` (bias check, rejection, OMA noise by marginal likelihood, see
            :mod:`robovib.hybrid.robust_update`), ``"posterior"`` or ``"warm"``.
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
            which sets their window bias at a sharp peak (steps 0 and 5 of :mod:`robovib.hybrid.robust_update`);
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
            self.gp_, report = robust_update(
                self.gp_, self.frequency_hz_, x, y, m, g,
                noise_std=self._noise_floor(noise_std, m), chi2_reject=self.chi2_reject,
                reoptimize=reoptimize, resolution_hz=oma_resolution_hz, rng=self.rng,
            )  # fmt: skip
            report = dataclasses.replace(report, wall_time_s=time.perf_counter() - t0)
        else:
            # The OMA noise is not identifiable from EMA data alone: start it at the EMA
            # noise (kept there by "posterior", re-optimised by "warm").
            start_noise_group_like(self.gp_, 1, like=0)
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

    def _noise_floor(self, noise_std, m) -> np.ndarray | None:
        """The (n, n_f) random errors [m/N] checked, in the targets' units, 0 where unobserved."""
        if noise_std is None:
            return None
        n_f = self.frequency_hz_.size
        ns = np.asarray(noise_std, float)
        if ns.shape != (m.shape[0], n_f):
            raise ValueError(f"noise_std must be (n, n_f) = {(m.shape[0], n_f)}, got {ns.shape}")
        ns = np.where(m[:, :n_f], ns, 0.0)
        if np.any(~np.isfinite(ns)) or np.any(ns < 0):
            raise ValueError("noise_std must be finite and >= 0 [m/N]")
        return ns * _SCALE

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
        from ..gp.bands import noise_std_of

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
        be one of ``inputs`` unless ``force``. The layout: :mod:`robovib.hybrid.model_file`.

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
        self._require_fitted()
        save_frf_pose_model(self, path, provenance=provenance, inputs=inputs, force=force)

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
        return load_frf_pose_model(cls, path)


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
