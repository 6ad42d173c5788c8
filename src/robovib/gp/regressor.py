"""Exact Gaussian-process regression of many independent outputs at once (thesis Eq. 6-10, 33).

One GP per output column, each with its own hyperparameters, all fitted in one vectorised call:
9 modal outputs of chapter 3, or hundreds of FRF bins of chapter 5.

Model, per output ``b`` (thesis Eq. 6-8)::

    y_b(q) = m_b + f_b(q) + eps,   f_b ~ GP(0, k_b),   eps ~ N(0, sigma_n,b^2)
    k_b(q, q') = sigma_f,b^2 * exp(-1/2 * sum_d (q_d - q'_d)^2 / l_b,d^2)

Eq. 7 of the thesis prints the exponent as ``-(q-q')^T(q-q') / (2 sigma_l)``; the
squared-exponential kernel divides by the *squared* length scale, which is what is implemented
(the printed form only rescales the hyperparameter). ``kernel="isotropic"`` (one length scale, as
in the thesis) or ``"ard"`` (one per input dimension).

The constant mean ``m_b`` is estimated by maximum likelihood: for given kernel hyperparameters
it has the closed form ``m = 1^T K^-1 y / 1^T K^-1 1`` (generalised least squares), and the
log marginal likelihood (Eq. 33) is maximised over the remaining hyperparameters with that
profile; as in MATLAB's ``fitrgp`` the estimate is then used as a plug-in (its own uncertainty
is not added to the predictive variance).

Inputs are standardised and targets centred/scaled inside the model; hyperparameters are
optimised in that scaled space and reported in the data's units.

Missing targets are supported through ``mask`` (``True`` = observed): a missing entry is
decoupled from the others (unit diagonal, zero covariance, zero residual), which leaves the
likelihood and the posterior of the observed entries exactly as if it were absent.

Speed and memory (``robovib.gp._likelihood``, ``benchmarks/bench_gp.py``): replicated inputs
(identical rows in one noise group, e.g. Table A1's 3 hammer tests per pose) are collapsed
exactly to their means before anything else; ``K^-1`` for the gradient comes from LAPACK
``potrf``/``potri`` in place; work arrays are chunked over outputs (a bounded working set, plus
the fitted ``L^-1`` of 8 B x outputs x n_unique^2); random restarts start from the best of
screened candidates and starts that meet in one basin are merged. ``fit``/``predict`` run with
one BLAS thread (:func:`robovib._threads.single_blas_thread`): many small matrices gain
nothing from BLAS threads and lose much on a shared machine.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from typing import Literal

import numpy as np
from scipy import optimize
from sklearn.base import BaseEstimator
from sklearn.exceptions import NotFittedError

from .._threads import single_blas_thread
from . import _likelihood
from .covariances import COVARIANCES, correlation
from .optimize import batched_bfgs
from .posterior import fitted_posterior, standardisation, theta_from_hyperparameters

__all__ = ["BatchedGPRegressor", "GPHyperparameters", "GPNumericalError", "JitterWarning"]

# Box for the log-hyperparameters in the scaled space (standardised inputs, unit-variance targets).
_LOG_SIGNAL_BOUNDS = (np.log(1e-3), np.log(1e2))
_LOG_LENGTH_BOUNDS = (np.log(1e-2), np.log(1e3))
_LOG_NOISE_BOUNDS = (np.log(1e-4), np.log(1e1))
_JITTER_STEPS = _likelihood._JITTER_STEPS
# Random restarts are chosen as the best of this many screened candidates each.
_SCREEN_PER_START = 4
# Relative function-change stop of the optimiser: that of SciPy's L-BFGS-B (factr=1e7), which
# scikit-learn uses.
_FTOL = 1e7 * np.finfo(float).eps


class GPNumericalError(np.linalg.LinAlgError):
    """The covariance matrix of an output stayed not positive definite after jitter escalation."""


class JitterWarning(UserWarning):
    """Jitter had to be added to a covariance matrix to factorise it."""


def _raise_if_failed(nll: np.ndarray) -> None:
    failed = ~np.isfinite(nll)
    if np.any(failed):
        raise GPNumericalError(
            f"covariance not positive definite for outputs {np.flatnonzero(failed).tolist()} "
            f"even with jitter up to {_JITTER_STEPS[-1]:g} x mean diagonal"
        )


@dataclass(frozen=True)
class GPHyperparameters:
    """Hyperparameters of ``B`` independent GPs, in the data's units (batch axis first).

    Attributes
    ----------
    signal_std
        (B,) sigma_f, in target units.
    length_scales
        (B, d) characteristic length scales, in input units (all columns equal if isotropic).
    noise_std
        (B,) sigma_n, in target units.
    mean
        (B,) constant mean m, in target units.
    """

    signal_std: np.ndarray
    length_scales: np.ndarray
    noise_std: np.ndarray
    mean: np.ndarray

    def select(self, index) -> GPHyperparameters:
        """The hyperparameters of the outputs ``index``.

        Parameters
        ----------
        index : array_like
            Output indices (any NumPy index).

        Returns
        -------
        GPHyperparameters
            Those outputs' hyperparameters.
        """
        return GPHyperparameters(
            signal_std=self.signal_std[index],
            length_scales=self.length_scales[index],
            noise_std=self.noise_std[index],
            mean=self.mean[index],
        )


def _vecdot_einsum(a, b):
    return np.einsum("...i,...i->...", a, b)


#: Row-wise dot product (NumPy >= 2 has a ufunc for it).
_vecdot = getattr(np, "vecdot", _vecdot_einsum)


def _as_2d_float(name: str, value, ndim_hint: str) -> np.ndarray:
    """A dense real 2-D float array with at least one row (1-D: one column); clear errors for
    sparse, complex and empty input (scikit-learn's estimator checks)."""
    if type(value).__module__.startswith("scipy.sparse"):
        raise TypeError(
            f"{name} is a sparse matrix: sparse input is not supported; pass a dense array"
        )
    arr = np.asarray(value)
    if np.iscomplexobj(arr):
        raise ValueError(f"{name}: Complex data not supported")
    arr = arr.astype(float, copy=False)
    if arr.ndim == 1:
        arr = arr[:, None]
    if arr.ndim != 2:
        raise ValueError(f"{name} must be 2-D {ndim_hint}, got shape {arr.shape}")
    if arr.shape[0] == 0:
        raise ValueError(f"{name} has 0 sample(s) (shape {arr.shape}); at least one is needed")
    if arr.shape[1] == 0:
        raise ValueError(
            f"{name} has 0 feature(s) (shape={arr.shape}) while a minimum of 1 is required."
        )
    return arr


def _checked_query(name: str, X, n_features: int, estimator: str) -> np.ndarray:
    """Query inputs as a finite (n, n_features) float array, with sklearn's error wording."""
    if np.ndim(X) == 1 and n_features != 1:
        raise ValueError(
            f"{name} is 1-D but the model has {n_features} inputs: Reshape your data "
            "to (n_query, n_features)"
        )
    Xq = _as_2d_float(name, X, "(n_query, n_features)")
    if Xq.shape[1] != n_features:
        raise ValueError(
            f"{name} has {Xq.shape[1]} features, but {estimator} is expecting "
            f"{n_features} features as input"
        )
    if not np.all(np.isfinite(Xq)):
        raise ValueError(f"{name} contains NaN or inf")
    return Xq


class BatchedGPRegressor(BaseEstimator):
    """Independent exact GPs for every output column, fitted and evaluated in one batch.

    Parameters
    ----------
    kernel : {"isotropic", "ard"}
        The length scales (not the covariance family, which is ``covariance``): ``"isotropic"``
        (thesis Eq. 7: one length scale shared by all inputs) or ``"ard"`` (automatic relevance
        determination: one length scale per input).
    mean
        ``"constant"`` (estimated, thesis) or ``"zero"`` (after target centring is disabled,
        exactly the zero-mean GP of scikit-learn).
    normalize
        Standardise inputs and centre/scale targets inside the model (default ``True``).
    optimizer
        ``"bfgs"`` (batched BFGS, thesis Eq. 34-36), ``"scipy"`` (SciPy L-BFGS-B, one output at a
        time; a reference) or ``None`` (keep the initial hyperparameters).
    n_restarts
        Extra random starting points per output for the optimiser; the best optimum is kept.
        ``None`` (default): 2 when fitting from scratch, 0 for a warm start.
    max_iter
        Iteration cap of the optimiser, per output and start.
    gtol
        Gradient tolerance of the optimiser (max-norm, scaled space).
    initial_hyperparameters
        Optional :class:`GPHyperparameters` (data units) to start from: a warm start.
    n_noise_groups
        Number of observation sources with their own noise level (e.g. 2: EMA and OMA FRFs,
        thesis §5.2.4). ``fit(..., groups=...)`` assigns each sample to a group; the noise
        hyperparameters are then (B, G) and ``noise_std`` has that shape.
    rng
        Seed or :class:`numpy.random.Generator` for the restarts.
    covariance : {"se", "matern52", "matern32"}
        The covariance family (:mod:`robovib.gp.covariances`; the length scales are ``kernel``):
        ``"se"`` (squared exponential, thesis Eq. 7), ``"matern52"`` or ``"matern32"``.

    Notes
    -----
    A scikit-learn estimator (:class:`sklearn.base.BaseEstimator`): the constructor stores its
    arguments unchanged, so :func:`sklearn.base.clone`, ``get_params``/``set_params`` and the
    repr work; using an unfitted model raises :class:`sklearn.exceptions.NotFittedError`.
    Vocabulary shared by every robovib pose model: *noise groups* are given per sample as
    ``groups`` (``n_noise_groups`` of them), and new data are added with :meth:`update`.

    Attributes
    ----------
    hyperparameters_ : GPHyperparameters
    n_iter_ : ndarray (B,)
        Optimiser iterations of the start that was kept, per output.
    n_iter_total_ : ndarray (B,)
        Iterations summed over all starts, per output.
    log_marginal_likelihood_value_ : ndarray (B,)
        Eq. 33 at the optimum, in the data's units.
    converged_ : ndarray (B,) of bool
    posterior_ : GPPosterior
        The posterior (Eq. 9-10) every prediction evaluates.
    jitter_ : ndarray (B,)
        Jitter added to the diagonal (scaled units) to factorise each covariance.

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn.base import clone
    >>> from robovib.gp import BatchedGPRegressor
    >>> X = np.linspace(0, 1, 15)[:, None]
    >>> gp = clone(BatchedGPRegressor(kernel="ard", rng=0)).fit(X, np.sin(4 * X))
    >>> mean, std = gp.predict(X[:3], return_std=True)
    >>> mean.shape, std.shape
    ((3, 1), (3, 1))
    """

    def __init__(
        self,
        kernel: Literal["isotropic", "ard"] = "isotropic",
        mean: Literal["constant", "zero"] = "constant",
        normalize: bool = True,
        optimizer: Literal["bfgs", "scipy"] | None = "bfgs",
        n_restarts: int | None = None,
        max_iter: int = 200,
        gtol: float = 1e-5,
        initial_hyperparameters: GPHyperparameters | None = None,
        n_noise_groups: int = 1,
        rng: int | np.random.Generator | None = None,
        covariance: Literal["se", "matern52", "matern32"] = "se",
    ) -> None:
        self.kernel = kernel
        self.covariance = covariance
        self.mean = mean
        self.normalize = normalize
        self.optimizer = optimizer
        self.n_restarts = n_restarts
        self.max_iter = max_iter
        self.gtol = gtol
        self.initial_hyperparameters = initial_hyperparameters
        self.n_noise_groups = n_noise_groups
        self.rng = rng

    def update(
        self,
        X_new,
        Y_new,
        mask=None,
        groups=None,
        *,
        mode: Literal["posterior", "warm"] = "posterior",
    ) -> BatchedGPRegressor:
        """Bayesian update of a fitted model with new observations (thesis §5.2.4).

        The one name for updating a robovib pose model (also :meth:`FRFPoseModel.update
        <robovib.hybrid.FRFPoseModel.update>`).

        Parameters
        ----------
        X_new
            (m, n_features) new inputs.
        Y_new
            (m, n_outputs) new targets (or (m,) for a model fitted on a 1-D ``Y``).
        mask
            Optional boolean array like ``Y_new``: ``True`` where the target is observed.
        groups
            Optional (m,) int noise group of each new sample (needed when ``n_noise_groups > 1``).
        mode
            ``"posterior"``: keep the hyperparameters and recompute the posterior with the
            enlarged data (Eq. 9-10); ``"warm"``: re-optimise the hyperparameters starting from
            the current ones.

        Returns
        -------
        self

        Raises
        ------
        NotFittedError
            If the model is not fitted.
        ValueError
            On an unknown ``mode`` or new data of the wrong shape.
        """
        if mode not in ("posterior", "warm"):
            raise ValueError(f"unknown update mode {mode!r}; expected 'posterior' or 'warm'")
        return self.add_observations(X_new, Y_new, mask, reoptimize=(mode == "warm"), groups=groups)

    # ------------------------------------------------------------------ validation
    def _check_params(self) -> None:
        if self.kernel not in ("isotropic", "ard"):
            raise ValueError(f"unknown kernel {self.kernel!r}; expected 'isotropic' or 'ard'")
        if self.covariance not in COVARIANCES:
            raise ValueError(
                f"unknown covariance {self.covariance!r}; expected one of {COVARIANCES}"
            )
        if self.mean not in ("constant", "zero"):
            raise ValueError(f"unknown mean {self.mean!r}; expected 'constant' or 'zero'")
        if self.optimizer not in ("bfgs", "scipy", None):
            raise ValueError(
                f"unknown optimizer {self.optimizer!r}; expected 'bfgs', 'scipy' or None"
            )
        if self.n_restarts is not None and int(self.n_restarts) < 0:
            raise ValueError(f"n_restarts must be >= 0, got {self.n_restarts}")

    @staticmethod
    def _check_xy(X, Y, mask, min_observed: int = 2):
        X = _as_2d_float("X", X, "(n_samples, n_features)")
        Y = np.asarray(Y, dtype=float)
        squeeze = Y.ndim == 1
        Y = _as_2d_float("Y", Y, "(n_samples, n_outputs)")
        if X.shape[0] != Y.shape[0]:
            raise ValueError(
                f"X and Y have mismatched lengths: {X.shape[0]} samples vs {Y.shape[0]} targets"
            )
        if not np.all(np.isfinite(X)):
            raise ValueError("X contains NaN or inf")
        if mask is None:
            mask = np.ones(Y.shape, dtype=bool)
        else:
            mask = np.asarray(mask, dtype=bool)
            if mask.ndim == 1:
                mask = mask[:, None]
            if mask.shape != Y.shape:
                raise ValueError(f"mask shape {mask.shape} does not match Y shape {Y.shape}")
        if not np.all(np.isfinite(Y[mask])):
            raise ValueError(
                "Y contains NaN or inf at observed entries; mark missing targets with mask=False"
            )
        n_obs = mask.sum(axis=0)
        if np.any(n_obs < min_observed):
            bad = np.flatnonzero(n_obs < min_observed).tolist()
            raise ValueError(
                f"outputs {bad} have fewer than {min_observed} observed samples "
                f"(n_samples={X.shape[0]})"
            )
        return X, np.where(mask, Y, 0.0), mask, squeeze

    # ------------------------------------------------------------------ scaling
    def _fit_scalers(self, X, Y, mask):
        x_loc, x_scale, y_loc, y_scale = standardisation(X, Y, mask, self.normalize)
        self._x_loc, self._x_scale = x_loc, x_scale
        self._y_loc, self._y_scale = y_loc, y_scale

    def _scale_x(self, X):
        return (X - self._x_loc) / self._x_scale

    def _scale_y(self, Y, mask):
        return np.where(mask, (Y - self._y_loc) / self._y_scale, 0.0)

    # ------------------------------------------------------------------ parameter vectors
    def _n_length(self, n_features: int) -> int:
        return 1 if self.kernel == "isotropic" else n_features

    def _bounds(self, n_features: int):
        n_len = self._n_length(n_features)
        g = self._n_groups
        lower = np.array(
            [_LOG_SIGNAL_BOUNDS[0], *[_LOG_LENGTH_BOUNDS[0]] * n_len, *[_LOG_NOISE_BOUNDS[0]] * g]
        )
        upper = np.array(
            [_LOG_SIGNAL_BOUNDS[1], *[_LOG_LENGTH_BOUNDS[1]] * n_len, *[_LOG_NOISE_BOUNDS[1]] * g]
        )
        return lower, upper

    def _theta_from_hyperparameters(
        self, hp: GPHyperparameters, n_features: int, clip: bool = True
    ) -> np.ndarray:
        theta = theta_from_hyperparameters(
            hp.signal_std, hp.length_scales, hp.noise_std, n_groups=self._n_groups,
            isotropic=self.kernel == "isotropic", x_scale=self._x_scale, y_scale=self._y_scale,
        )  # fmt: skip
        if not clip:
            return theta
        lower, upper = self._bounds(n_features)
        return np.clip(theta, lower, upper)

    @property
    def _n_groups(self) -> int:
        return int(self.n_noise_groups)

    def _groups_for(self, n: int) -> np.ndarray:
        groups = getattr(self, "_active_groups", None)
        return np.zeros(n, dtype=int) if groups is None or groups.size != n else groups

    def _split(self, theta):
        g = self._n_groups
        log_sf = theta[:, 0]
        log_l = theta[:, 1:-g]
        log_sn = theta[:, -g:]  # (k, G)
        return log_sf, log_l, log_sn

    # ------------------------------------------------------------------ likelihood core
    def _design(self, x_s, y_s, mask, groups=None):
        """The replicate-collapsed training set (scaled x (n, d), y and mask (n, B))."""
        groups = self._groups_for(x_s.shape[0]) if groups is None else groups
        return _likelihood.collapse_replicates(x_s, y_s.T, mask.T, groups, self._n_groups)

    def _evaluate(
        self, theta, design, *, want_grad=True, allow_fail=True, want_state=False, mean=None
    ):
        """Eq. 33 on a design; ``mean``: "constant" (profiled) or "zero" (default: self.mean)."""
        mean = self.mean if mean is None else mean
        nll, grad, state = _likelihood.evaluate(
            theta,
            design,
            n_groups=self._n_groups,
            constant_mean=mean == "constant",
            want_grad=want_grad,
            want_state=want_state,
            covariance=getattr(self, "covariance", "se"),
        )
        if not allow_fail:
            _raise_if_failed(nll)
        return nll, grad, state

    def _nll_and_grad(self, theta, y, mask, sq_diff, *, want_grad=True, allow_fail=True):
        """Negative log marginal likelihood (Eq. 33, mean profiled) and its gradient.

        theta: (k, p); y, mask: (k, n) scaled targets and observation masks; sq_diff: (n, n, d)
        squared scaled input differences. No replicate collapsing (see :meth:`_design`).
        Returns (nll (k,), grad (k, p) or None, (chol_inv, alpha, mean, jitter)).
        """
        n = sq_diff.shape[0]
        k = y.shape[0]
        G = self._n_groups
        design = _likelihood.Design(
            x=np.zeros((n, 0)),
            sq_flat=sq_diff.reshape(n * n, -1),
            group=self._groups_for(n),
            y=np.where(mask, y, 0.0),
            obs=np.asarray(mask, bool),
            count=np.ones((k, n)),
            ss=np.zeros((k, G)),
            extra=np.zeros((k, G)),
            half_log_count=np.zeros(k),
            index=np.arange(n),
        )
        nll, grad, state = self._evaluate(
            theta, design, want_grad=want_grad, allow_fail=allow_fail, want_state=not want_grad
        )
        extra = None
        if state is not None:
            extra = (state["chol_inv"], state["alpha"], state["mean"], state["jitter"])
        return nll, grad, extra

    # ------------------------------------------------------------------ fitting
    def _initial_thetas(self, n_out: int, n_features: int, rng: np.random.Generator):
        lower, upper = self._bounds(n_features)
        n_len = self._n_length(n_features)
        if self.initial_hyperparameters is not None:
            # Fixed hyperparameters (optimizer=None) are used exactly as given; an optimiser's
            # starting point is moved into its box.
            base = self._theta_from_hyperparameters(
                self.initial_hyperparameters, n_features, clip=self.optimizer is not None
            )
            n_random = 0 if self.n_restarts is None else int(self.n_restarts)
        else:
            base = np.tile(
                np.array([0.0, *[0.0] * n_len, *[np.log(0.1)] * self._n_groups]), (n_out, 1)
            )
            n_random = 2 if self.n_restarts is None else int(self.n_restarts)
            if n_random > 0 and self.optimizer is not None:
                # The default start plus n_random starts chosen by screening candidates.
                n_cand = _SCREEN_PER_START * n_random
                return [base], self._candidates(n_out, n_features, rng, n_cand)
        starts = [base]
        for _ in range(n_random):
            draw = np.column_stack(
                [
                    rng.uniform(np.log(0.3), np.log(3.0), n_out),
                    rng.uniform(np.log(0.1), np.log(10.0), (n_out, n_len)),
                    rng.uniform(np.log(1e-3), np.log(0.5), (n_out, self._n_groups)),
                ]
            )
            starts.append(np.clip(draw, lower, upper))
        return starts, None

    def _candidates(self, n_out, n_features, rng, n_cand):
        """(n_cand, n_out, p) Latin-hypercube starting points in a wide box (scaled space)."""
        n_len = self._n_length(n_features)
        lo = np.array([np.log(0.1), *[np.log(0.03)] * n_len, *[np.log(1e-3)] * self._n_groups])
        hi = np.array([np.log(10.0), *[np.log(30.0)] * n_len, *[np.log(1.0)] * self._n_groups])
        # Latin hypercube per output: one point in each of n_cand strata of every parameter.
        strata = rng.permuted(
            np.broadcast_to(np.arange(n_cand)[:, None, None], (n_cand, n_out, lo.size)), axis=0
        )
        u = (strata + rng.uniform(size=strata.shape)) / n_cand
        return lo + u * (hi - lo)

    def _screen(self, design, candidates, n_keep):
        """The ``n_keep`` candidates of highest likelihood, per output (value-only evaluations).

        Screening many cheap points and starting BFGS from the best few finds the global mode of
        multimodal likelihoods (short vs long length scale) more often than as many random starts.
        """
        n_cand, n_out, p = candidates.shape
        flat = candidates.reshape(n_cand * n_out, p)
        owner = np.tile(np.arange(n_out), n_cand)
        nll, _, _ = self._evaluate(flat, design.take(owner), want_grad=False)
        nll = np.where(np.isfinite(nll), nll, np.inf).reshape(n_cand, n_out)
        # Keep the best candidate of each of n_keep strata of log(length scale x noise / signal):
        # the two usual modes (short length scale and little noise: "interpolating"; long length
        # scale and more noise: "smoothing") lie at either end, so both get a start.
        coord = (
            candidates[:, :, 1 : -self._n_groups].mean(axis=2)
            + candidates[:, :, -self._n_groups :].mean(axis=2)
            - candidates[:, :, 0]
        )
        rank = np.argsort(np.argsort(coord, axis=0, kind="stable"), axis=0, kind="stable")
        stratum = rank * n_keep // n_cand
        cols = np.arange(n_out)
        return [
            candidates[np.argmin(np.where(stratum == j, nll, np.inf), axis=0), cols]
            for j in range(n_keep)
        ]

    def _optimize(self, x_s, y_s, mask, theta_starts, candidates=None):
        n_out, n_features = y_s.shape[1], x_s.shape[1]
        design = self._design(x_s, y_s, mask)
        if candidates is not None:
            n_keep = candidates.shape[0] // _SCREEN_PER_START
            theta_starts = [*theta_starts, *self._screen(design, candidates, n_keep)]
        n_starts = len(theta_starts)
        theta0 = np.concatenate(theta_starts, axis=0)
        owner = np.tile(np.arange(n_out), n_starts)
        lower, upper = self._bounds(n_features)
        if self.optimizer is None:
            theta_opt = theta0
            nll, _, _ = self._evaluate(theta0, design.take(owner), want_grad=False)
            n_iter = np.zeros(theta0.shape[0], dtype=int)
            converged = np.ones(theta0.shape[0], dtype=bool)
        elif self.optimizer == "bfgs":

            def fun(theta, index):
                nll, grad, _ = self._evaluate(theta, design.take(owner[index]))
                return nll, grad

            res = batched_bfgs(
                fun,
                theta0,
                lower=lower,
                upper=upper,
                max_iter=self.max_iter,
                gtol=self.gtol,
                ftol=_FTOL,
                same_problem=owner,
            )
            theta_opt, nll, n_iter, converged = res.x, res.fun, res.n_iter, res.converged
        else:
            theta_opt = np.empty_like(theta0)
            nll = np.empty(theta0.shape[0])
            n_iter = np.zeros(theta0.shape[0], dtype=int)
            converged = np.zeros(theta0.shape[0], dtype=bool)
            for row in range(theta0.shape[0]):
                one = design.take(owner[row : row + 1])

                def fun1(t, one=one):
                    val, grad, _ = self._evaluate(t[None], one)
                    return (val[0], grad[0]) if np.isfinite(val[0]) else (1e300, np.zeros_like(t))

                out = optimize.minimize(
                    fun1,
                    theta0[row],
                    jac=True,
                    method="L-BFGS-B",
                    bounds=list(zip(lower, upper, strict=True)),
                    options={"maxiter": self.max_iter, "gtol": self.gtol},
                )
                theta_opt[row], nll[row], n_iter[row], converged[row] = (
                    out.x,
                    out.fun,
                    out.nit,
                    out.success,
                )
        nll_by_start = nll.reshape(n_starts, n_out)
        best = np.argmin(np.where(np.isfinite(nll_by_start), nll_by_start, np.inf), axis=0)
        pick = best * n_out + np.arange(n_out)
        self.n_iter_ = n_iter[pick]
        self.n_iter_total_ = n_iter.reshape(n_starts, n_out).sum(axis=0)
        self.converged_ = converged[pick]
        return theta_opt[pick]

    def _set_groups(self, groups, n: int) -> np.ndarray:
        if groups is None:
            if self._n_groups != 1:
                raise ValueError(
                    f"n_noise_groups={self._n_groups}: pass groups= to assign samples to noise groups"
                )
            return np.zeros(n, dtype=int)
        g = np.asarray(groups)
        if g.shape != (n,) or not np.issubdtype(g.dtype, np.integer):
            raise ValueError(f"groups must be an integer array of shape ({n},)")
        if np.any(g < 0) or np.any(g >= self._n_groups):
            raise ValueError(
                f"groups must be in [0, {self._n_groups}) for n_noise_groups={self._n_groups}"
            )
        return g.astype(int)

    def fit(self, X, Y, mask=None, groups=None) -> BatchedGPRegressor:
        """Fit one GP per column of ``Y`` (hyperparameters by maximising Eq. 33).

        See ``docs/methods.md`` section 3 (GP pose models).

        Parameters
        ----------
        X : array_like, shape (n_samples, n_features)
            Inputs (e.g. poses, in the units the caller chose: the model scales them itself).
        Y : array_like, shape (n_samples,) or (n_samples, n_outputs)
            Targets, one GP per column, any unit.
        mask : array_like of bool, shape like ``Y``, optional
            ``True`` where the target is observed; NaN targets must be masked.
        groups : array_like of int, shape (n_samples,), optional
            Noise group of each sample in ``0 .. n_noise_groups - 1`` (e.g. 0 = EMA, 1 = OMA).

        Returns
        -------
        BatchedGPRegressor
            ``self``, fitted (``hyperparameters_``, ``n_iter_``, ``log_marginal_likelihood_value_``).

        Raises
        ------
        ValueError
            Wrong shapes, NaN inputs, unmasked NaN targets, bad groups or constructor arguments.

        Examples
        --------
        >>> import numpy as np
        >>> from robovib.gp import BatchedGPRegressor
        >>> X = np.linspace(0, 1, 20)[:, None]
        >>> gp = BatchedGPRegressor(rng=0).fit(X, np.column_stack([np.sin(6 * X[:, 0]), X[:, 0]]))
        >>> gp.predict(X[:2]).shape
        (2, 2)
        """
        with single_blas_thread():
            return self._fit(X, Y, mask, groups)

    def _fit(self, X, Y, mask, groups) -> BatchedGPRegressor:
        self._check_params()
        X, Y, mask, squeeze = self._check_xy(X, Y, mask)
        if int(self.n_noise_groups) < 1:
            raise ValueError(f"n_noise_groups must be >= 1, got {self.n_noise_groups}")
        self._active_groups = self._set_groups(groups, X.shape[0])
        self._fit_scalers(X, Y, mask)
        rng = np.random.default_rng(self.rng)
        starts, candidates = self._initial_thetas(Y.shape[1], X.shape[1], rng)
        x_s, y_s = self._scale_x(X), self._scale_y(Y, mask)
        self._theta = self._optimize(x_s, y_s, mask, starts, candidates)
        self._squeeze = squeeze
        self._set_training_data(X, Y, mask)
        return self

    def _set_training_data(self, X, Y, mask):
        self.X_train_, self.Y_train_, self.mask_ = X, np.where(mask, Y, np.nan), mask
        x_s, y_s = self._scale_x(X), self._scale_y(Y, mask)
        design = self._design(x_s, y_s, mask)
        post, nll, jitter = fitted_posterior(
            self._theta, design, n_groups=self._n_groups, constant_mean=self.mean == "constant",
            covariance=getattr(self, "covariance", "se"), x_loc=self._x_loc,
            x_scale=self._x_scale, y_loc=self._y_loc, y_scale=self._y_scale,
        )  # fmt: skip
        _raise_if_failed(nll)
        if np.any(jitter > 0):
            warnings.warn(
                f"jitter added to the covariance of outputs {np.flatnonzero(jitter > 0).tolist()} "
                f"(max {jitter.max():.3g} in scaled units)",
                JitterWarning,
                stacklevel=3,
            )
        self.jitter_ = jitter
        # The posterior given replicates equals that given their means: unique inputs only.
        self.posterior_ = post
        self._x_s, self._chol_inv, self._alpha, self._m_s = (
            post.x_s,
            post.chol_inv,
            post.alpha,
            post.mean_s,
        )
        self._obs_u = design.obs  # (B, u) outputs observed at each unique input
        self._sf2, self._inv_l2, m = post.sf2, post.inv_l2, post.mean_s
        _, log_l, log_sn = self._split(self._theta)
        # predict_one's precomputed arrays (data units; see there).
        self._p1_x = design.x * self._x_scale + self._x_loc
        self._p1_neg_half_inv_l2 = -0.5 * self._inv_l2 / self._x_scale**2
        self._p1_log_k0 = (np.log(self._sf2) + np.log(self._y_scale))[:, None]
        self._p1_offset = m * self._y_scale + self._y_loc
        self._p1_var0 = self._sf2 * self._y_scale**2
        # Eq. 33 in data units: the Jacobian of the target scaling shifts the log density.
        self.log_marginal_likelihood_value_ = -nll - mask.sum(axis=0) * np.log(self._y_scale)
        n_features = X.shape[1]
        self.hyperparameters_ = GPHyperparameters(
            signal_std=np.sqrt(self._sf2) * self._y_scale,
            length_scales=np.exp(np.broadcast_to(log_l, (log_l.shape[0], n_features)))
            * self._x_scale,
            noise_std=(np.exp(log_sn) * self._y_scale[:, None])[:, 0]
            if self._n_groups == 1
            else np.exp(log_sn) * self._y_scale[:, None],
            mean=m * self._y_scale + self._y_loc,
        )
        self.n_features_in_ = n_features
        self.n_outputs_ = Y.shape[1]

    # ------------------------------------------------------------------ updating
    def add_observations(
        self, X_new, Y_new, mask=None, *, reoptimize: bool = False, groups=None
    ) -> BatchedGPRegressor:
        """Add observations to a fitted model (Bayesian update, thesis §5.2.4).

        With ``reoptimize=False`` the hyperparameters stay and only the posterior is recomputed
        (Eq. 9-10 with the enlarged data set). With ``reoptimize=True`` the hyperparameters are
        re-optimised starting from the current ones (warm start); ``n_iter_`` then counts the
        iterations of that update. The internal input/target scaling is kept from the first fit
        so that the warm start stays meaningful. ``groups`` assigns the new samples to noise
        groups (needed when ``n_noise_groups > 1``).

        Parameters
        ----------
        X_new, Y_new : array_like
            New inputs and targets.
        mask : array_like, optional
            Observed targets (default: all).
        reoptimize : bool
            Re-optimise the hyperparameters from the current ones.
        groups : array_like, optional
            Pose group of each new row.

        Returns
        -------
        BatchedGPRegressor
            ``self``, updated.
        """
        with single_blas_thread():
            return self._add_observations(X_new, Y_new, mask, reoptimize, groups)

    def _add_observations(self, X_new, Y_new, mask, reoptimize, groups):
        self._require_fitted()
        X_new, Y_new, mask_new, _ = self._check_xy(X_new, Y_new, mask, min_observed=0)
        if X_new.shape[1] != self.n_features_in_ or Y_new.shape[1] != self.n_outputs_:
            raise ValueError(
                f"new data has {X_new.shape[1]} features / {Y_new.shape[1]} outputs; the model was "
                f"fitted with {self.n_features_in_} / {self.n_outputs_}"
            )
        X = np.vstack([self.X_train_, X_new])
        mask_all = np.vstack([self.mask_, mask_new])
        self._active_groups = np.concatenate(
            [self._active_groups, self._set_groups(groups, X_new.shape[0])]
        )
        Y = np.vstack([np.where(self.mask_, self.Y_train_, 0.0), Y_new])
        if reoptimize:
            if self.optimizer is None:
                raise ValueError("reoptimize=True needs an optimizer ('bfgs' or 'scipy')")
            self._theta = self._optimize(
                self._scale_x(X), self._scale_y(Y, mask_all), mask_all, [self._theta]
            )
        else:
            self.n_iter_ = np.zeros(self.n_outputs_, dtype=int)
        self._set_training_data(X, Y, mask_all)
        return self

    # ------------------------------------------------------------------ prediction
    def _require_fitted(self):
        if not hasattr(self, "_theta"):
            raise NotFittedError("this BatchedGPRegressor is not fitted yet; call fit() first")

    def predict(self, X, return_std: bool = False, include_noise: bool = False):
        """Posterior mean (Eq. 9) and, optionally, standard deviation (Eq. 10).

        Parameters
        ----------
        X
            (n_query, n_features) query inputs.
        return_std
            Also return the predictive standard deviation.
        include_noise
            Add the observation-noise variance (predict a new *measurement*, not the latent mean).

        Returns
        -------
        mean : ndarray (n_query, n_outputs) — or (n_query,) if fitted on a 1-D ``Y``
        std : ndarray, same shape, if ``return_std``

        Examples
        --------
        >>> import numpy as np
        >>> from robovib.gp import BatchedGPRegressor
        >>> X = np.linspace(0, 1, 15)[:, None]
        >>> gp = BatchedGPRegressor(rng=0).fit(X, 2 * X[:, 0])
        >>> bool(abs(gp.predict([[0.5]])[0] - 1.0) < 1e-2)
        True
        """
        with single_blas_thread():
            return self._predict(X, return_std, include_noise)

    def _predict(self, X, return_std, include_noise):
        self._require_fitted()
        Xq = _checked_query("X", X, self.n_features_in_, "BatchedGPRegressor")
        mean, std = self.posterior_.predict(Xq)
        if not return_std:
            return mean[:, 0] if self._squeeze else mean
        if include_noise:
            # The noise of group 0 (the first source, e.g. the reference measurements).
            noise_var = np.exp(2.0 * self._theta[:, -self._n_groups]) * self._y_scale**2
            std = np.sqrt(std**2 + noise_var[None, :])
        if self._squeeze:
            return mean[:, 0], std[:, 0]
        return mean, std

    def predict_one(self, x) -> tuple[np.ndarray, np.ndarray]:
        """Fast path for the control cycle: mean and latent std of every output at one input.

        ``x`` is a single input of shape (n_features,); returns two (n_outputs,) arrays. No
        input validation beyond the shape, to stay well under 100 µs for hundreds of outputs.

        Parameters
        ----------
        x : numpy.ndarray
            (n_features,) one input.

        Returns
        -------
        mean, std : numpy.ndarray
            (n_outputs,) each.
        """
        x = np.asarray(x, dtype=float)
        if x.shape != (self.n_features_in_,):
            raise ValueError(f"x must have shape ({self.n_features_in_},), got {x.shape}")
        # Scalings folded into precomputed arrays (_set_training_data): the kernel row is in
        # data units times y_scale, so mean and variance come out in data units.
        d2 = (self._p1_x - x) ** 2  # (n, d)
        if self.covariance == "se":
            k = np.exp(self._p1_neg_half_inv_l2 @ d2.T + self._p1_log_k0)  # (B, n)
        else:
            r2 = -2.0 * (self._p1_neg_half_inv_l2 @ d2.T)
            k = np.exp(self._p1_log_k0) * correlation(r2, self.covariance)
        mean = self._p1_offset + _vecdot(k, self._alpha)
        v = np.matmul(self._chol_inv, k[:, :, None])[:, :, 0]
        var = self._p1_var0 - _vecdot(v, v)
        return mean, np.sqrt(np.maximum(var, 0.0, out=var), out=var)

    def log_marginal_likelihood(
        self, hyperparameters: GPHyperparameters | None = None
    ) -> np.ndarray:
        """Eq. 33 for each output, in data units, at the fitted or the given hyperparameters.

        Parameters
        ----------
        hyperparameters
            Hyperparameters in data units; their ``mean`` is the constant mean used (passed in,
            not re-estimated). ``None``: the value at the fitted optimum.

        Returns
        -------
        ndarray (n_outputs,)
            log p(y | X, hyperparameters) of the observed targets of each output.

        Raises
        ------
        NotFittedError
            If the model is not fitted.
        GPNumericalError
            If a covariance matrix is not positive definite at the given hyperparameters.
        """
        self._require_fitted()
        if hyperparameters is None:
            return self.log_marginal_likelihood_value_.copy()
        theta = self._theta_from_hyperparameters(hyperparameters, self.n_features_in_, clip=False)
        x_s = self._scale_x(self.X_train_)
        mask = self.mask_
        y = np.where(mask, self.Y_train_, 0.0) - np.asarray(hyperparameters.mean, float)
        y_s = np.where(mask, y / self._y_scale, 0.0)
        design = self._design(x_s, y_s, mask)
        with single_blas_thread():
            # The mean is given (subtracted above), not re-estimated.
            nll, _, _ = self._evaluate(
                theta, design, want_grad=False, allow_fail=False, mean="zero"
            )
        return -nll - mask.sum(axis=0) * np.log(self._y_scale)
