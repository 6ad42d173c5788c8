"""Pose-dependent model of the whole FRF: one GP per frequency bin (thesis §5.2.3-5.2.4).

What is modelled: the **real and imaginary parts** of the compliance in each bin, two GPs per
bin (all bins and parts fitted in one batched call). The compliance is linear in the modal
residues and the H1 estimation error is close to complex Gaussian, so a Gaussian model of
Re/Im is consistent with both the physics and the noise; it keeps the phase (needed to
convolve forces, §3.5.2). A GP of |H| would lose the phase, and a GP of log|H| turns additive
noise into a biased multiplicative one near anti-resonances.

Sources: EMA (hammer, group 0) and OMA (milling, group 1) have separate noise
hyperparameters (§5.2.4: different sensors). Updating with OMA FRFs (§5.2.4):

* ``"posterior"`` — hyperparameters kept, Eq. 9-10 with the enlarged data (OMA noise = EMA's);
* ``"warm"`` — hyperparameters re-optimised starting from the EMA optimum (the thesis' method);
* full retraining = a new :meth:`fit` on all data from the default start.

Flagged OMA bins (harmonics, low coherence) enter as missing targets of those bins only.
"""

from __future__ import annotations

import time
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from sklearn.base import BaseEstimator
from sklearn.exceptions import NotFittedError

from ..gp.regressor import BatchedGPRegressor

__all__ = ["FRFPoseModel", "UpdateReport"]

_FORMAT = "robovib-frf-pose-model"


@dataclass(frozen=True)
class UpdateReport:
    mode: str
    iterations_total: int
    iterations_mean_per_gp: float
    wall_time_s: float


class FRFPoseModel(BaseEstimator):
    """Per-bin GP model of the compliance over the pose (``fit`` / ``update`` / ``predict``).

    Parameters
    ----------
    frequency_hz
        The common frequency grid (n_f,): all FRFs must be given on it.
    kernel, n_restarts, rng
        Passed to :class:`~robovib.gp.BatchedGPRegressor` (2 n_f outputs, 2 noise groups).

    Notes
    -----
    A scikit-learn estimator (parameters stored unchanged, clone-able). Noise groups are given
    per sample as ``groups`` (0 = EMA, 1 = OMA); new data enter through :meth:`update` (the
    same names as :class:`~robovib.gp.BatchedGPRegressor`). ``sources=`` is a deprecated alias
    of ``groups=``.
    """

    def __init__(
        self, frequency_hz, kernel: str = "isotropic", n_restarts: int | None = 0, rng=0
    ) -> None:
        self.frequency_hz = frequency_hz
        self.kernel = kernel
        self.n_restarts = n_restarts
        self.rng = rng

    @staticmethod
    def _groups(groups, sources, default: int, n: int) -> np.ndarray:
        if sources is not None:
            warnings.warn(
                "sources= is deprecated; pass the noise groups as groups=",
                DeprecationWarning,
                stacklevel=3,
            )
            groups = sources if groups is None else groups
        return np.full(n, default, int) if groups is None else np.asarray(groups, int)

    def _targets(self, frfs, mask):
        h = np.asarray(frfs, complex)
        if h.ndim != 2 or h.shape[1] != self.frequency_hz_.size:
            raise ValueError(
                f"FRFs must be (n_poses, {self.frequency_hz_.size}) on the model's frequency grid, got {h.shape}"
            )
        m = np.ones(h.shape, bool) if mask is None else np.asarray(mask, bool)
        if m.shape != h.shape:
            raise ValueError("mask must have the FRFs' shape")
        if not np.all(np.isfinite(h[m])):
            raise ValueError("FRFs contain NaN or inf at unmasked bins")
        scale = 1e6  # um/N: O(1) numbers inside
        y = np.hstack([np.where(m, h.real, 0.0), np.where(m, h.imag, 0.0)]) * scale
        return y, np.hstack([m, m])

    @staticmethod
    def _poses(poses) -> np.ndarray:
        p = np.asarray(poses, float)
        return p[:, None] if p.ndim == 1 else p

    def fit(self, poses, frfs, mask=None, groups=None, sources=None) -> FRFPoseModel:
        """Fit from scratch; ``groups`` (n,) ints: 0 = EMA, 1 = OMA (default all EMA)."""
        grid = np.asarray(self.frequency_hz, float)
        if grid.ndim != 1 or grid.size == 0 or not np.all(np.isfinite(grid)):
            raise ValueError("frequency_hz must be a non-empty 1-D array of finite values [Hz]")
        self.frequency_hz_ = grid
        x = self._poses(poses)
        y, m = self._targets(frfs, mask)
        groups = self._groups(groups, sources, 0, x.shape[0])
        t0 = time.perf_counter()
        self.gp_ = BatchedGPRegressor(
            kernel=self.kernel, n_restarts=self.n_restarts, n_noise_groups=2, rng=self.rng
        )
        self.gp_.fit(x, y, mask=m, groups=groups)
        self.last_report_ = UpdateReport(
            "fit",
            int(self.gp_.n_iter_.sum()),
            float(self.gp_.n_iter_.mean()),
            time.perf_counter() - t0,
        )
        self.pose_range_ = (x.min(axis=0), x.max(axis=0))
        return self

    def update(
        self, poses, frfs, mask=None, groups=None, sources=None, *, mode: str = "warm"
    ) -> UpdateReport:
        """Bayesian update with new FRFs: ``mode="posterior"`` or ``"warm"`` (see module docs)."""
        if mode not in ("posterior", "warm"):
            raise ValueError(f"unknown update mode {mode!r}; expected 'posterior' or 'warm'")
        self._require_fitted()
        x = self._poses(poses)
        y, m = self._targets(frfs, mask)
        groups = self._groups(groups, sources, 1, x.shape[0])
        # The OMA noise is not identifiable from EMA data alone: start it at the EMA noise
        # (kept there by "posterior", re-optimised by "warm").
        if not np.any(self.gp_._active_groups == 1):
            self.gp_._theta[:, -1] = self.gp_._theta[:, -2]
        t0 = time.perf_counter()
        self.gp_.update(x, y, mask=m, groups=groups, mode=mode)
        self.last_report_ = UpdateReport(
            mode,
            int(self.gp_.n_iter_.sum()),
            float(self.gp_.n_iter_.mean()),
            time.perf_counter() - t0,
        )
        self.pose_range_ = (
            np.minimum(self.pose_range_[0], x.min(axis=0)),
            np.maximum(self.pose_range_[1], x.max(axis=0)),
        )
        return self.last_report_

    def _require_fitted(self):
        if not hasattr(self, "gp_"):
            raise NotFittedError("this FRFPoseModel is not fitted yet; call fit() first")

    def extrapolating(self, poses) -> np.ndarray:
        """(n,) bool: poses outside the calibrated range (per coordinate)."""
        self._require_fitted()
        x = self._poses(poses)
        lo, hi = self.pose_range_
        return np.any((x < lo - 1e-12) | (x > hi + 1e-12), axis=1)

    def predict(self, poses, return_std: bool = False):
        """Complex compliance (n, n_f) [m/N] and, optionally, its std (sqrt(var Re + var Im))."""
        self._require_fitted()
        x = self._poses(poses)
        if not np.all(np.isfinite(x)):
            raise ValueError("poses contain NaN or inf")
        mean, std = self.gp_.predict(x, return_std=True)
        n_f = self.frequency_hz_.size
        h = (mean[:, :n_f] + 1j * mean[:, n_f:]) / 1e6
        if not return_std:
            return h
        return h, np.sqrt(std[:, :n_f] ** 2 + std[:, n_f:] ** 2) / 1e6

    def integrated_variance(self, poses) -> np.ndarray:
        """Predictive variance summed over frequency and Re/Im, per pose (n,) [(um/N)^2]."""
        _, std = self.gp_.predict(self._poses(poses), return_std=True)
        return np.sum(std**2, axis=1)

    def next_poses(self, candidates, k: int = 3) -> np.ndarray:
        """Greedy choice of the next ``k`` hammer-test poses by integrated predictive variance.

        After each pick the model is conditioned on a pseudo-observation there (the variance
        of a GP does not depend on the observed value), so the next pick goes elsewhere.
        """
        self._require_fitted()
        cand = self._poses(candidates)
        if k < 1 or k > len(cand):
            raise ValueError(f"k must be in [1, {len(cand)}]")
        import copy

        gp = copy.deepcopy(self.gp_)
        chosen = []
        for _ in range(k):
            _, std = gp.predict(cand, return_std=True)
            score = np.sum(std**2, axis=1)
            score[chosen] = -np.inf
            i = int(np.argmax(score))
            chosen.append(i)
            mean = gp.predict(cand[i : i + 1])
            gp.update(cand[i : i + 1], mean, groups=np.zeros(1, int))
        return cand[chosen]

    # ------------------------------------------------------------------ persistence (no pickle)
    def save(self, path) -> None:
        """HDF5: training data, hyperparameters and scalers, with a format tag and version."""
        import h5py

        self._require_fitted()
        gp = self.gp_
        with h5py.File(path, "w") as h5:
            h5.attrs["format"] = _FORMAT
            h5.attrs["version"] = 1
            h5.attrs["kernel"] = self.kernel
            for name, value in {
                "frequency_hz": self.frequency_hz_, "X_train": gp.X_train_, "Y_train": np.nan_to_num(gp.Y_train_),
                "mask": gp.mask_, "groups": gp._active_groups, "theta": gp._theta, "x_loc": gp._x_loc,
                "x_scale": gp._x_scale, "y_loc": gp._y_loc, "y_scale": gp._y_scale,
                "pose_lo": self.pose_range_[0], "pose_hi": self.pose_range_[1],
            }.items():  # fmt: skip
                h5.create_dataset(name, data=value)

    @classmethod
    def load(cls, path) -> FRFPoseModel:
        import h5py

        path = Path(path)
        try:
            h5 = h5py.File(path, "r")
        except OSError as exc:
            raise ValueError(f"{path}: not a readable HDF5 file ({exc})") from None
        with h5:
            if h5.attrs.get("format") != _FORMAT or int(h5.attrs.get("version", -1)) != 1:
                raise ValueError(f"{path}: not a robovib FRF pose model (version 1)")
            d = {k: h5[k][()] for k in h5}
            kernel = str(h5.attrs["kernel"])
        model = cls(d["frequency_hz"], kernel=kernel)
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
        gp._set_training_data(d["X_train"], d["Y_train"], d["mask"].astype(bool))
        model.gp_ = gp
        model.frequency_hz_ = np.asarray(d["frequency_hz"], float)
        model.pose_range_ = (d["pose_lo"], d["pose_hi"])
        return model
