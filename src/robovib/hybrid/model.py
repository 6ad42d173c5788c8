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
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..gp.regressor import BatchedGPRegressor

__all__ = ["FRFPoseModel", "UpdateReport", "frfs_on_grid"]

#: Units of the datasets of a saved model (path coordinate s [m], compliance scaled to um/N).
_DATASET_UNITS = {
    "frequency_hz": "Hz", "X_train": "m", "Y_train": "um/N", "mask": "1", "groups": "1",
    "theta": "1 (log hyperparameters of the scaled inputs/outputs)", "x_loc": "m", "x_scale": "m",
    "y_loc": "um/N", "y_scale": "um/N", "pose_lo": "m", "pose_hi": "m",
}  # fmt: skip
_FORMAT = "robovib-frf-pose-model"


@dataclass(frozen=True)
class UpdateReport:
    mode: str
    iterations_total: int
    iterations_mean_per_gp: float
    wall_time_s: float


class FRFPoseModel:
    """Per-bin GP model of the compliance over the pose (``fit`` / ``update`` / ``predict``).

    Parameters
    ----------
    frequency_hz
        The common frequency grid (n_f,): all FRFs must be given on it.
    kernel, n_restarts, rng
        Passed to :class:`~robovib.gp.BatchedGPRegressor` (2 n_f outputs, 2 noise groups).
    """

    def __init__(
        self, frequency_hz, kernel: str = "isotropic", n_restarts: int | None = 0, rng=0
    ) -> None:
        self.frequency_hz = np.asarray(frequency_hz, float)
        self.kernel = kernel
        self.n_restarts = n_restarts
        self.rng = rng

    # ------------------------------------------------------------------ FRF objects, checked
    def fit_frfs(self, frfs) -> FRFPoseModel:
        """Fit from FRF objects (path coordinate in ``meta["path_s_m"]``), checked at the door.

        All FRFs must be compliances of one direction (stored as ``direction_``) from EMA or OMA
        (source sets the noise group); bins outside an FRF's range are an error.

        Raises
        ------
        ValueError
            Mixed directions, model-source FRFs, missing path coordinate, other quantity, or an
            FRF that does not cover the model's frequency grid.
        """
        frfs = list(frfs)
        direction = _common_direction(frfs, None, "fit")
        h, s, m, groups = frfs_on_grid(frfs, self.frequency_hz)
        self.fit(s, h, mask=m, sources=groups)
        self.direction_ = direction
        return self

    def update_frfs(
        self, frfs, *, mode: str = "warm", expect_source: str | None = "OMA"
    ) -> UpdateReport:
        """Bayesian update from FRF objects, checked against the model.

        Each FRF's direction must be the model's (``hybrid update model_x.h5 oma_y.h5`` fails)
        and, with ``expect_source`` (default ``"OMA"``), its source must be that one (EMA FRFs
        given as OMA are refused rather than fitted with the OMA noise level). Grid bins
        outside an FRF's range are treated as missing.

        Raises
        ------
        ValueError
            Direction or source mismatch, or see :func:`frfs_on_grid`.
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
        h, s, m, groups = frfs_on_grid(frfs, self.frequency_hz, partial=True)
        return self.update(s, h, mask=m, sources=groups, mode=mode)

    def _targets(self, frfs, mask):
        h = np.asarray(frfs, complex)
        if h.ndim != 2 or h.shape[1] != self.frequency_hz.size:
            raise ValueError(
                f"FRFs must be (n_poses, {self.frequency_hz.size}) on the model's frequency grid, got {h.shape}"
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

    def fit(self, poses, frfs, mask=None, sources=None) -> FRFPoseModel:
        """Fit from scratch; ``sources`` (n,) ints: 0 = EMA, 1 = OMA (default all EMA)."""
        x = self._poses(poses)
        y, m = self._targets(frfs, mask)
        groups = np.zeros(x.shape[0], int) if sources is None else np.asarray(sources, int)
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

    def update(self, poses, frfs, mask=None, sources=None, *, mode: str = "warm") -> UpdateReport:
        """Bayesian update with new FRFs: ``mode="posterior"`` or ``"warm"`` (see module docs)."""
        if mode not in ("posterior", "warm"):
            raise ValueError(f"unknown update mode {mode!r}; expected 'posterior' or 'warm'")
        self._require_fitted()
        x = self._poses(poses)
        y, m = self._targets(frfs, mask)
        groups = np.ones(x.shape[0], int) if sources is None else np.asarray(sources, int)
        # The OMA noise is not identifiable from EMA data alone: start it at the EMA noise
        # (kept there by "posterior", re-optimised by "warm").
        if not np.any(self.gp_._active_groups == 1):
            self.gp_._theta[:, -1] = self.gp_._theta[:, -2]
        t0 = time.perf_counter()
        self.gp_.add_observations(x, y, mask=m, reoptimize=(mode == "warm"), groups=groups)
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
            raise RuntimeError("this FRFPoseModel is not fitted yet; call fit() first")

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
        n_f = self.frequency_hz.size
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
            gp.add_observations(cand[i : i + 1], mean, groups=np.zeros(1, int))
        return cand[chosen]

    # ------------------------------------------------------------------ persistence (no pickle)
    def save(self, path, *, inputs=(), force: bool = False) -> None:
        """HDF5: training data, hyperparameters and scalers, with a format tag and version.

        Written atomically (:func:`robovib.io.atomic_output`); ``path`` must not be one of
        ``inputs`` unless ``force``.
        """
        import h5py

        from ..io.provenance import set_units, write_provenance
        from ..io.safe_write import atomic_output

        self._require_fitted()
        gp = self.gp_
        with atomic_output(path, inputs=inputs, force=force) as tmp, h5py.File(tmp, "w") as h5:
            h5.attrs["format"] = _FORMAT
            h5.attrs["version"] = 1
            h5.attrs["kernel"] = self.kernel
            h5.attrs["direction"] = getattr(self, "direction_", None) or ""
            h5.attrs["frequency_unit"] = "Hz"
            h5.attrs["compliance_unit"] = "um/N (Re, Im stacked)"
            from .. import __version__

            h5.attrs["robovib_version"] = __version__
            for name, value in {
                "frequency_hz": self.frequency_hz, "X_train": gp.X_train_, "Y_train": np.nan_to_num(gp.Y_train_),
                "mask": gp.mask_, "groups": gp._active_groups, "theta": gp._theta, "x_loc": gp._x_loc,
                "x_scale": gp._x_scale, "y_loc": gp._y_loc, "y_scale": gp._y_scale,
                "pose_lo": self.pose_range_[0], "pose_hi": self.pose_range_[1],
            }.items():  # fmt: skip
                set_units(h5.create_dataset(name, data=value), _DATASET_UNITS[name])
            write_provenance(h5, inputs=inputs)

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
            d = {k: h5[k][()] for k in h5 if k != "provenance"}
            kernel = str(h5.attrs["kernel"])
            direction = str(h5.attrs.get("direction", "")) or None
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
        model.pose_range_ = (d["pose_lo"], d["pose_hi"])
        model.direction_ = direction
        return model


_GROUP = {"EMA": 0, "OMA": 1}


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


def frfs_on_grid(frfs, grid, partial: bool = False):
    """FRFs interpolated on a frequency grid, with path coordinates, bin masks and noise groups.

    Parameters
    ----------
    frfs : sequence of FRF
        Compliances with ``meta["path_s_m"]`` [m]; OMA bins flagged in ``meta["flagged"]``
        become missing targets.
    grid : (n_f,) array [Hz]
    partial : bool
        True: grid bins outside an FRF's range are masked (missing), not an error.

    Returns
    -------
    values : (n, n_f) complex [m/N]
    s_m : (n,) path coordinates [m]
    mask : (n, n_f) bool, True = usable bin
    groups : (n,) int, 0 = EMA, 1 = OMA

    Raises
    ------
    ValueError
        No FRFs, a missing path coordinate, a non-compliance FRF, a model-source FRF, or
        (``partial=False``) an FRF not covering the grid.
    """
    grid = np.asarray(grid, float)
    if len(frfs) == 0:
        raise ValueError("no FRFs given")
    vals, s, masks, groups = [], [], [], []
    for i, f in enumerate(frfs):
        if "path_s_m" not in f.meta:
            raise ValueError(
                f"FRF {i} has no path coordinate (write it with --path-s / from `hybrid oma`)"
            )
        if f.quantity != "compliance":
            raise ValueError(f"FRF {i} is {f.quantity}, expected compliance")
        if f.source not in _GROUP:
            raise ValueError(f"FRF {i} has source {f.source!r}; expected measured EMA or OMA")
        s_i = float(f.meta["path_s_m"])
        if not np.isfinite(s_i):
            raise ValueError(f"FRF {i} has a non-finite path coordinate {s_i}")
        outside = (grid < f.frequency_hz[0] - 1e-3) | (grid > f.frequency_hz[-1] + 1e-3)
        if np.any(outside) and not partial:
            raise ValueError(
                f"FRF {i} covers {f.frequency_hz[0]:g}-{f.frequency_hz[-1]:g} Hz, not the model "
                f"grid {grid[0]:g}-{grid[-1]:g} Hz"
            )
        vals.append(
            np.interp(grid, f.frequency_hz, f.values.real)
            + 1j * np.interp(grid, f.frequency_hz, f.values.imag)
        )
        flagged = np.asarray(f.meta.get("flagged", np.zeros(f.frequency_hz.size, bool)), bool)
        nearest = np.clip(np.searchsorted(f.frequency_hz, grid), 0, f.frequency_hz.size - 1)
        masks.append(~flagged[nearest] & ~outside)
        s.append(s_i)
        groups.append(_GROUP[f.source])
    return np.array(vals), np.array(s), np.array(masks), np.array(groups, int)
