"""Read-only predictor of a saved :class:`~robovib.gp.PoseModalModel` (NumPy and h5py only).

``robovib gpr predict`` starts, loads a pose model and answers in well under a second: what costs
the time is not the prediction (microseconds) but importing scikit-learn and SciPy's optimisers
(~0.7 s on one core), which :class:`~robovib.gp.PoseModalModel` needs to *fit*. A
:class:`PosePredictor` reads the same HDF5 file (:meth:`PoseModalModel.save`) and evaluates the
same posterior without them:

* each GP output (thesis Eq. 9-10): the estimator's own construction at the stored
  hyperparameters (:func:`robovib.gp.posterior.fitted_posterior`: standardisation, replicates
  collapsed, Cholesky, profiled mean, ``alpha = K_y^-1 (y - m)``), run on NumPy's LAPACK instead
  of SciPy's, and evaluated by the same :class:`~robovib.gp.posterior.GPPosterior`;
* the mode-switch classifier (binary Laplace GP classifier, Rasmussen & Williams 2006, Algorithms
  3.1-3.2, as :class:`sklearn.gaussian_process.GaussianProcessClassifier` with ``optimizer=None``
  on the stored kernel): Newton iterations for the posterior mode, then the Williams-Barber
  five-erf approximation of the predictive probability;
* extrapolation: outside the box of the training inputs or outside the convex hull of the
  standardised unique training poses: the rule of :meth:`PoseModalModel.extrapolating`, one
  implementation (:class:`robovib.gp.extrapolation.TrainingRegion`, NumPy only).

:func:`predict_at` is the one prediction at a pose of both (``robovib gpr predict`` with or
without ``--model``): SI outputs with ±2σ, extrapolation and mode-switch flags.

The tests check it against :meth:`PoseModalModel.load` to 1e-10. A file whose covariance
needed jitter to factorise is refused (``ValueError``); :func:`load_pose_predictor` then falls
back to the full model.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .._threads import single_blas_thread
from ..files.h5format import as_text
from ._likelihood import collapse_replicates
from .contract import PosePredictionSide
from .extrapolation import TrainingRegion
from .pose_file import FORMAT as FORMAT  # re-exported (their former home)
from .pose_file import FORMAT_VERSION as FORMAT_VERSION
from .pose_file import read_pose_file, require_pose_inputs
from .posterior import GPPosterior, fitted_posterior, standardisation, theta_from_hyperparameters

__all__ = [
    "AMBIGUOUS_MODE_PROBABILITY",
    "JitterNeeded",
    "PosePrediction",
    "PosePredictor",
    "load_pose_predictor",
    "predict_at",
]

_QUANTITIES = (("fn", "hz"), ("stiffness", "n_per_m"), ("damping", "ns_per_m"))
_UNIT_LABELS = {"hz": "Hz", "n_per_m": "N/m", "ns_per_m": "N*s/m"}
# Williams & Barber's approximation of the logistic sigmoid by five error functions (the
# coefficients of scikit-learn's _gpc.py, fitted by least squares there).
_LAMBDAS = np.array([0.41, 0.4, 0.37, 0.44, 0.39])[:, None]
_COEFS = np.array([-1854.8214151, 3516.89893646, 221.29346712, 128.12323805, -2010.49422654])[
    :, None
]


class JitterNeeded(ValueError):
    """A stored covariance needed jitter to factorise: read the file with the full model."""


class _GP:
    """Posterior of a fitted BatchedGPRegressor group (stored hyperparameters, data units).

    Built by the estimator's own code (:func:`robovib.gp.posterior.fitted_posterior` on the
    replicate-collapsed training set), with NumPy's LAPACK instead of SciPy's.
    """

    switches_mode = False

    def __init__(self, group) -> None:
        d = {k: group[k][()] for k in group}
        a = group.attrs
        self.covariance = as_text(a["covariance"]) if "covariance" in a else "se"
        n_groups = int(a["n_noise_groups"])
        X = np.asarray(d["X"], float)
        mask = np.asarray(d["mask"], bool)
        Y = np.where(mask, d["Y"], 0.0)
        groups = np.asarray(d["groups"], int) if n_groups > 1 else np.zeros(X.shape[0], int)
        x_loc, x_scale, y_loc, y_scale = standardisation(X, Y, mask, bool(a["normalize"]))
        theta = theta_from_hyperparameters(
            d["signal_std"], d["length_scales"], d["noise_std"], n_groups=n_groups,
            isotropic=as_text(a["kernel"]) == "isotropic", x_scale=x_scale, y_scale=y_scale,
        )  # fmt: skip
        x_s, y_s = (X - x_loc) / x_scale, np.where(mask, (Y - y_loc) / y_scale, 0.0)
        design = collapse_replicates(x_s, y_s.T, mask.T, groups, n_groups)
        self.posterior, nll, jitter = fitted_posterior(
            theta, design, n_groups=n_groups, constant_mean=as_text(a["mean"]) == "constant",
            covariance=self.covariance, x_loc=x_loc, x_scale=x_scale, y_loc=y_loc,
            y_scale=y_scale, linalg="numpy",
        )  # fmt: skip
        if np.any(jitter > 0) or not np.all(np.isfinite(nll)):
            raise JitterNeeded("covariance not positive definite without jitter")
        self.noise_std = np.exp(theta[:, -n_groups]) * y_scale  # first (reference) group
        self.signal_std = np.sqrt(self.posterior.sf2) * y_scale  # data units
        self.X_train = X

    def predict(self, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return self.posterior.predict(X)


class _LaplaceGPC:
    """Binary Laplace GP classifier with a fixed kernel C * RBF (as scikit-learn's, optimizer=None)."""

    def __init__(self, X: np.ndarray, y: np.ndarray, theta: np.ndarray) -> None:
        self.X = np.asarray(X, float)
        self.c = math.exp(theta[0])
        self.ls = np.exp(np.asarray(theta[1:], float))
        labels = np.asarray(y).astype(bool)
        self.y = labels.astype(float)  # LabelEncoder of (False, True) -> 0, 1
        K = self._kernel(self.X, self.X)
        f = np.zeros_like(self.y)
        lml_prev = -np.inf
        for _ in range(100):  # scikit-learn's max_iter_predict
            pi = 1.0 / (1.0 + np.exp(-f))
            W = pi * (1 - pi)
            W_sr = np.sqrt(W)
            W_sr_K = W_sr[:, None] * K
            B = np.eye(W.shape[0]) + W_sr_K * W_sr
            L = np.linalg.cholesky(B)
            b = W * f + (self.y - pi)
            z = np.linalg.solve(L, W_sr_K @ b)
            a = b - W_sr * np.linalg.solve(L.T, z)
            f = K @ a
            lml = (
                -0.5 * a @ f
                - np.log1p(np.exp(-(self.y * 2 - 1) * f)).sum()
                - np.log(np.diag(L)).sum()
            )
            if lml - lml_prev < 1e-10:
                break
            lml_prev = lml
        self.pi, self.W_sr, self.L = pi, W_sr, L

    def _kernel(self, A: np.ndarray, B: np.ndarray) -> np.ndarray:
        d2 = (((A[:, None, :] - B[None, :, :]) / self.ls) ** 2).sum(axis=-1)
        return self.c * np.exp(-0.5 * d2)

    def predict_proba(self, X: np.ndarray) -> np.ndarray:
        """(m,) probability of the positive class (the high mode)."""
        K_star = self._kernel(self.X, X)
        f_star = K_star.T @ (self.y - self.pi)
        v = np.linalg.solve(self.L, self.W_sr[:, None] * K_star)
        var = self.c - np.einsum("ij,ij->j", v, v)
        alpha = 1 / (2 * var)
        gamma = _LAMBDAS * f_star
        erf = np.vectorize(math.erf, otypes=[float])
        integrals = (
            np.sqrt(np.pi / alpha)
            * erf(gamma * np.sqrt(alpha / (alpha + _LAMBDAS**2)))
            / (2 * np.sqrt(var * 2 * np.pi))
        )
        return (_COEFS * integrals).sum(axis=0) + 0.5 * _COEFS.sum()


class _Switching:
    """A stored ModeSwitchingGPRegressor: low-mode GP, optional high-mode GP, classifier."""

    switches_mode = True

    def __init__(self, group) -> None:
        a = group.attrs
        self.switching = np.asarray(a["switching_outputs"], int)
        self.features = as_text(a["classifier_features"])
        self.low = _GP(group["low"])
        self.high = _GP(group["high"]) if "high" in group else None
        self.high_mean = group["high_mean"][()] if "high_mean" in group else None
        self.all_high = bool(a["all_high"])
        self.classifier = None
        if "classifier" in group:
            c = group["classifier"]
            self.x_loc, self.x_scale = c["x_loc"][()], c["x_scale"][()]
            self.classifier = _LaplaceGPC(c["X"][()], c["y"][()], c["kernel_theta"][()])

    def _features(self, X: np.ndarray) -> np.ndarray:
        tag = self.features
        if tag == "none":
            return X
        kind, _, index = tag.partition(":")
        if kind != "rz_cos2":
            raise ValueError(f"unknown classifier feature map {tag!r}")
        X = np.array(X, float)
        i = int(index)
        X[:, i] = np.cos(np.radians(2.0 * X[:, i]))
        return X

    def high_mode_probability(self, X: np.ndarray) -> np.ndarray:
        if self.classifier is None:
            return np.full(X.shape[0], 1.0 if self.all_high else 0.0)
        return self.classifier.predict_proba((self._features(X) - self.x_loc) / self.x_scale)

    def components(self, X: np.ndarray):
        """``(p_high, low, high)`` as :meth:`ModeSwitchingGPRegressor.components`."""
        from .bands import UNMODELLED_MODE_RELATIVE_STD

        mean, std = self.low.predict(X)
        noise = np.broadcast_to(self.low.noise_std, mean.shape)
        h_mean, h_std, h_noise = mean.copy(), std.copy(), noise.copy()
        cols = self.switching
        if self.high is not None:
            m, s = self.high.predict(X)
            h_mean[:, cols], h_std[:, cols] = m, s
            h_noise[:, cols] = self.high.noise_std
        elif self.high_mean is not None:
            h_mean[:, cols] = self.high_mean
            h_std[:, cols] = UNMODELLED_MODE_RELATIVE_STD * np.abs(self.high_mean)
            h_noise[:, cols] = 0.0
        return self.high_mode_probability(X), (mean, std, noise), (h_mean, h_std, h_noise)

    def predict(self, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        mean, std = self.low.predict(X)
        use_high = self.high_mode_probability(X) > 0.5
        if np.any(use_high):
            cols = self.switching
            if self.high is not None:
                h_mean, h_std = self.high.predict(X[use_high])
            else:
                h_mean = np.tile(self.high_mean, (int(use_high.sum()), 1))
                h_std = np.full_like(h_mean, np.nan)
            mean[np.ix_(use_high, cols)] = h_mean
            std[np.ix_(use_high, cols)] = h_std
        return mean, std


class PosePredictor(PosePredictionSide):
    """Predictions of a saved pose model, without scikit-learn (see the module docstring).

    Honours the pose-model contract (:class:`robovib.gp.contract.PoseModel`) with the one
    prediction side of :class:`~robovib.gp.PoseModalModel`
    (:class:`robovib.gp.contract.PosePredictionSide`); only the GP posteriors are rebuilt here,
    with NumPy. To refit, update or save, load the :class:`~robovib.gp.PoseModalModel` itself.

    Use :meth:`load` (or :func:`load_pose_predictor`).
    """

    @classmethod
    def load(cls, path) -> PosePredictor:
        """Read a ``robovib.PoseModalModel`` HDF5 file (format version 1).

        Parameters
        ----------
        path : str or pathlib.Path
            The model file.

        Returns
        -------
        PosePredictor
            The predictor.

        Raises
        ------
        ValueError
            Not a readable HDF5 file, not a pose model, a newer format version, or a stored
            covariance that needed jitter (use :meth:`PoseModalModel.load`).
        """
        path = Path(path)
        tree, _ = read_pose_file(path)
        self = cls()
        a = tree.attrs
        params = json.loads(as_text(a["params_json"]))
        self.input_names = self.input_names_ = tuple(params["input_names"])
        self.directions = self.directions_ = tuple(params["directions"])
        self.params_ = params
        self.output_names_ = tuple(f"{d}_{q}_{u}" for d in self.directions_ for q, u in _QUANTITIES)
        self.output_units_ = tuple(
            _UNIT_LABELS[u] for _ in self.directions_ for _, u in _QUANTITIES
        )
        t = tree["training"]
        self.X_train_ = np.asarray(t["X"][()], float)
        self.n_outputs_ = len(self.output_names_)
        self._estimators = []
        try:
            with single_blas_thread():  # many small matrices: threads only contend
                estimators = [tree["estimators"][str(i)] for i in range(len(tree["estimators"]))]
                for g in estimators:
                    kind = as_text(g.attrs["kind"])
                    cols = np.asarray(g.attrs["columns"], int)
                    if kind == "BatchedGPRegressor":
                        self._estimators.append((_GP(g), cols))
                    elif kind == "ModeSwitchingGPRegressor":
                        self._estimators.append((_Switching(g), cols))
                    else:
                        raise ValueError(f"{path}: unknown estimator kind {kind!r}")
        except JitterNeeded as exc:
            raise JitterNeeded(f"{path}: {exc}; load it with PoseModalModel.load") from None
        self.mode_switches_ = {
            d: {k: (as_text(v) if isinstance(v, bytes | str) else v) for k, v in g.attrs.items()}
            for d, g in tree["mode_switches"].items()
        }
        self.provenance_ = {k: as_text(v) if isinstance(v, bytes) else v
                            for k, v in tree["provenance"].attrs.items()}  # fmt: skip
        self.calibration_ = None
        if "calibration" in tree:
            from .calibration import read_calibration

            self.calibration_ = read_calibration(tree["calibration"])
        self.region_ = TrainingRegion.of(self.X_train_)
        self.input_min_, self.input_max_ = self.region_.lo, self.region_.hi
        return self

    def _prediction_parts(self) -> list:
        return self._estimators

    def gp_posteriors(self) -> list[tuple[GPPosterior, np.ndarray, np.ndarray, np.ndarray, int]]:
        """Every GP of the model: ``(posterior, noise_std, signal_std, columns, mode)``.

        ``noise_std`` and ``signal_std`` (B,) in data units (the reference noise group),
        ``columns`` the model outputs of its B targets, ``mode`` 0 for the low (or only) mode
        and 1 for the high mode of a switching direction; what
        :func:`robovib.campaign.next_poses` needs, in the order of ``PoseModalModel``.

        Returns
        -------
        list of tuple
            ``(posterior, noise_std, signal_std, columns, mode)`` per GP.
        """
        out = []
        for est, cols in self._estimators:
            cols = np.asarray(cols, int)
            low = est.low if isinstance(est, _Switching) else est
            out.append((low.posterior, low.noise_std, low.signal_std, cols, 0))
            if isinstance(est, _Switching) and est.high is not None:
                h = est.high
                out.append((h.posterior, h.noise_std, h.signal_std, cols[est.switching], 1))
        return out


def load_pose_predictor(path, require_inputs=None):
    """A :class:`PosePredictor` of the file, or the full ``PoseModalModel`` where it must be.

    The full model (scikit-learn imported, ~1 s more) is loaded only when the stored covariance
    needed jitter to factorise.

    Parameters
    ----------
    path : str or pathlib.Path
        The model file.
    require_inputs : sequence of str, optional
        The input names the caller needs (checked as :func:`robovib.gp.load_pose_model` does).

    Returns
    -------
    PosePredictor or PoseModalModel
        A model with ``predict`` and ``predictive``.
    """
    try:
        model = PosePredictor.load(path)
    except JitterNeeded:
        from .pose_model import PoseModalModel

        model = PoseModalModel.load(path)
    require_pose_inputs(model, path, require_inputs)
    return model


#: Probability band of the high mode in which the dominant mode counts as ambiguous.
AMBIGUOUS_MODE_PROBABILITY = (0.2, 0.8)


@dataclass(frozen=True)
class PosePrediction:
    """Prediction of every output of a pose model at one pose.

    Attributes
    ----------
    pose
        Input name -> value, in the model's units.
    outputs
        One dict per output: ``output`` (name with unit suffix, e.g. ``x_fn_hz``), ``unit``,
        ``mean`` (the more probable mode), ``std``, ``lower_2sigma``, ``upper_2sigma`` (the
        *latent* modal parameter, calibrated where the model is), ``measurement_std`` and
        ``measurement_95`` (the 95 % set of a new hammer test: one or, at an uncertain mode
        switch, two ``[low, high]`` intervals), SI in ``unit``.
    extrapolating
        The pose lies outside the training inputs' box or convex hull.
    outside_inputs
        Inputs outside their training range.
    high_mode_probability
        Direction -> probability that the high mode dominates, for directions with a modelled
        mode switch (empty without).
    notes
        Warnings on the dominant mode: one per direction whose high-mode probability lies in
        :data:`AMBIGUOUS_MODE_PROBABILITY` (the data cannot tell which mode dominates).
    """

    pose: dict
    outputs: tuple
    extrapolating: bool
    outside_inputs: tuple[str, ...]
    high_mode_probability: dict = field(default_factory=dict)
    notes: tuple[str, ...] = ()

    def to_dict(self) -> dict:
        """JSON-ready: ``predictions`` keyed by output name (unit suffix), each with its unit.

        Returns
        -------
        dict
            The prediction as plain JSON types.
        """
        return {
            "pose": dict(self.pose),
            "extrapolating": self.extrapolating,
            "outside_inputs": list(self.outside_inputs),
            "high_mode_probability": dict(self.high_mode_probability),
            "notes": list(self.notes),
            "predictions": {
                o["output"]: {k: v for k, v in o.items() if k != "output"} for o in self.outputs
            },
        }


def predict_at(model, pose) -> PosePrediction:
    """Predict every output at one pose given by input name (the model's ``input_names``).

    Parameters
    ----------
    model
        A fitted :class:`robovib.gp.PoseModalModel` or its read-only
        :class:`robovib.gp.saved_model.PosePredictor` (same file, same numbers).
    pose
        Mapping input name -> value in the units of the name (``x_mm``, ``rz_deg``, ...).

    Returns
    -------
    PosePrediction
        SI outputs with ±2σ (latent std, thesis Eq. 10), extrapolation and mode-switch flags.

    Raises
    ------
    ValueError
        A missing or unknown input name, or a non-finite value.
    """
    names = tuple(model.input_names)
    given = dict(pose)
    missing = [n for n in names if n not in given]
    unknown = [n for n in given if n not in names]
    if missing or unknown:
        options = ", ".join("--" + n.rsplit("_", 1)[0] for n in names)
        raise ValueError(
            f"the model takes inputs {', '.join(names)} (options {options})"
            + (f"; missing {', '.join(missing)}" if missing else "")
            + (f"; not an input: {', '.join(unknown)}" if unknown else "")
        )
    x = np.array([[float(given[n]) for n in names]])
    if not np.all(np.isfinite(x)):
        raise ValueError(f"pose values must be finite, got {given}")
    units = model.output_units_
    pred = model.predictive(x)
    mean, std = pred.point(), pred.point_std("latent")
    std_meas = pred.point_std("measurement")
    sets = pred.intervals(0.95, "measurement")[0]
    outs = tuple(
        {
            "output": name,
            "unit": unit,
            "mean": float(m),
            "std": float(s),
            "lower_2sigma": float(m - 2 * s),
            "upper_2sigma": float(m + 2 * s),
            "measurement_std": float(sm),
            "measurement_95": [[float(a), float(b)] for a, b in iv],
        }
        for name, unit, m, s, sm, iv in zip(
            model.output_names_, units, mean[0], std[0], std_meas[0], sets, strict=True
        )
    )
    from .extrapolation import outside_inputs

    outside = outside_inputs(model, x[0], names)  # same range and tolerance as extrapolating()
    p = model.mode_switch_probability(x)
    dirs = tuple(model.directions_)
    high = (
        {} if p is None else {d: float(p[0, i]) for i, d in enumerate(dirs) if np.isfinite(p[0, i])}
    )
    a, b = AMBIGUOUS_MODE_PROBABILITY
    notes = tuple(
        f"P(high {d} mode dominant) = {q:.2f}: the data cannot tell which {d} mode dominates "
        f"here; the {d} values are those of the more probable mode"
        for d, q in high.items()
        if a < q < b
    )
    return PosePrediction(
        {n: float(given[n]) for n in names},
        outs,
        bool(model.extrapolating(x)[0]),
        outside,
        high,
        notes,
    )
