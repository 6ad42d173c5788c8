"""Log marginal likelihood (thesis Eq. 33) of many independent GPs: the numerical core.

Kept apart from :class:`~robovib.gp.BatchedGPRegressor` so that the estimator only deals with
parameters, scaling and bookkeeping. Three things make it fast and lean:

* **Replicates collapsed exactly.** Identical inputs observed ``m`` times in the same noise group
  (Table A1 has 3 replicates per pose) are replaced by their mean with noise variance
  ``sigma^2 / m``; the likelihood of the full data is that of the reduced data plus a term that
  depends only on the noise (derivation in :func:`collapse_replicates`). The posterior of the
  latent function is the same, so prediction uses the reduced data too.
* **LAPACK inverse.** The gradient needs ``K^-1``; it is formed from the Cholesky factor by
  ``potrf`` + ``potri`` in place (2/3 n^3 flops instead of 4 n^3 for a general inverse and a
  product). NumPy and SciPy ship separate OpenBLAS builds: call this under
  :func:`robovib._threads.single_blas_thread` so their thread pools do not contend.
* **SciPy only when fitting.** SciPy's LAPACK is imported when first needed. The posterior of
  stored hyperparameters (:func:`evaluate` with ``linalg="numpy"``, value and state only) runs on
  NumPy's LAPACK, so that :mod:`robovib.gp.saved_model` builds the same posterior without SciPy.
* **Bounded memory.** Rows (outputs x starts) are processed in chunks whose work arrays (three
  ``n x n`` per row) are allocated once per call and fit in :data:`WORK_BYTES`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .covariances import correlation

_LOG_2PI = np.log(2.0 * np.pi)
#: Target size of the per-chunk work arrays (bytes); a chunk holds at least one row.
WORK_BYTES = 48 * 2**20
_JITTER_STEPS = (1e-10, 1e-8, 1e-6, 1e-4)


class _NumpyLapack:
    """The three LAPACK calls of the value-and-state path, on NumPy's LAPACK (no SciPy).

    Same calling convention as :mod:`scipy.linalg.lapack` (``lower=1`` only): ``dpotrf`` returns
    the lower Cholesky factor (``info = 1`` when not positive definite or not finite), ``dpotrs``
    solves with it, ``dtrtri`` inverts it. The input is left unchanged.
    """

    @staticmethod
    def dpotrf(a, lower=1, overwrite_a=0, clean=0):
        try:
            c = np.linalg.cholesky(a)
        except np.linalg.LinAlgError:
            return a, 1
        return c, 0 if np.all(np.isfinite(c)) else 1

    @staticmethod
    def dpotrs(c, b, lower=1):
        return np.linalg.solve(c.T, np.linalg.solve(c, b)), 0

    @staticmethod
    def dtrtri(c, lower=1, overwrite_c=0):
        return np.linalg.solve(c, np.eye(c.shape[-1])), 0


def _lapack(linalg: str = "scipy"):
    """The LAPACK wrappers: SciPy's (imported on first use) or NumPy's (:class:`_NumpyLapack`)."""
    if linalg == "numpy":
        return _NumpyLapack
    if linalg != "scipy":
        raise ValueError(f"linalg must be 'scipy' or 'numpy', got {linalg!r}")
    from scipy.linalg import lapack

    return lapack


@dataclass
class Design:
    """A (possibly replicate-collapsed) training set in the scaled space, for ``B`` outputs.

    Attributes
    ----------
    x : (u, d) unique scaled inputs.
    sq_flat : (u*u, d) squared input differences, flattened pairs first.
    group : (u,) noise group of each unique input.
    y : (B, u) mean scaled target over the observed replicates (0 where none).
    obs : (B, u) bool, at least one replicate observed.
    count : (B, u) number of observed replicates (1 where none, to keep divisions finite).
    ss : (B, G) within-replicate sum of squares per noise group.
    extra : (B, G) number of observations beyond the first per unique input, per group.
    half_log_count : (B,) 1/2 sum_i log m_i (Jacobian of the averaging).
    index : (n,) unique row of each original sample.
    """

    x: np.ndarray
    sq_flat: np.ndarray
    group: np.ndarray
    y: np.ndarray
    obs: np.ndarray
    count: np.ndarray
    ss: np.ndarray
    extra: np.ndarray
    half_log_count: np.ndarray
    index: np.ndarray
    sq_sum: np.ndarray | None = None  #: (u*u,) summed over inputs (isotropic kernel)

    def __post_init__(self):
        if self.sq_sum is None:
            self.sq_sum = self.sq_flat.sum(axis=1)

    @property
    def n_unique(self) -> int:
        return self.x.shape[0]

    @property
    def collapsed(self) -> bool:
        return self.n_unique < self.index.size

    def take(self, rows: np.ndarray) -> Design:
        """The design of the outputs ``rows`` (rows may repeat: one per optimiser start)."""
        return Design(
            self.x,
            self.sq_flat,
            self.group,
            self.y[rows],
            self.obs[rows],
            self.count[rows],
            self.ss[rows],
            self.extra[rows],
            self.half_log_count[rows],
            self.index,
            self.sq_sum,
        )


def collapse_replicates(
    x: np.ndarray, y: np.ndarray, mask: np.ndarray, group: np.ndarray, n_groups: int
) -> Design:
    """Reduce a data set to its unique (input, noise group) rows, exactly.

    For ``m`` observations ``y_j = f(x) + e_j``, ``e_j ~ N(0, s^2)`` at one input, the mean
    ``ybar`` and the contrasts ``y_j - ybar`` are independent; ``ybar = f(x) + N(0, s^2/m)`` and
    the contrasts do not depend on ``f``. Changing variables from the ``m`` values to
    ``(ybar, m - 1 orthonormal contrasts)`` (Jacobian ``sqrt(m)``) gives, summed over inputs::

        log p(y) = log N(ybar | mu 1, K_u + diag(s_i^2 / m_i))
                   - 1/2 sum_i log m_i
                   - sum_i [ S_i / (2 s_i^2) + (m_i - 1)/2 log(2 pi s_i^2) ]

    with ``S_i = sum_j (y_ij - ybar_i)^2``. The constant mean's GLS estimate is the same on both
    sides (the correction does not depend on it) and the posterior of ``f`` given ``y`` equals
    that given ``ybar`` (a sufficient statistic).

    Parameters
    ----------
    x : (n, d) scaled inputs. y : (B, n) scaled targets (0 where unobserved).
    mask : (B, n) bool, observed. group : (n,) noise group per sample. n_groups : G.
    """
    key = np.column_stack([x, group.astype(float)])
    uniq, index = np.unique(key, axis=0, return_inverse=True)
    index = index.reshape(-1)
    n_u = uniq.shape[0]
    n_out = y.shape[0]
    if n_u == x.shape[0]:
        xu, gu, index = x, group, np.arange(x.shape[0])
        obs = mask
        y_u = np.where(obs, y, 0.0)
        count = np.ones(obs.shape)
        ss = np.zeros((n_out, n_groups))
        extra = np.zeros((n_out, n_groups))
        half_log = np.zeros(n_out)
    else:
        xu, gu = uniq[:, :-1], uniq[:, -1].astype(int)
        onehot = np.zeros((x.shape[0], n_u))
        onehot[np.arange(x.shape[0]), index] = 1.0
        w = mask.astype(float)
        cnt = w @ onehot  # (B, u)
        obs = cnt > 0
        count = np.where(obs, cnt, 1.0)
        y_u = np.where(obs, ((w * y) @ onehot) / count, 0.0)
        dev = np.where(mask, y - y_u[:, index], 0.0)
        g_onehot = np.zeros((x.shape[0], n_groups))
        g_onehot[np.arange(x.shape[0]), group] = 1.0
        ss = (dev * dev) @ g_onehot
        extra = (w @ g_onehot) - obs.astype(float) @ np.eye(n_groups)[gu]
        half_log = 0.5 * np.sum(np.log(count), axis=1)
    sq = (xu[:, None, :] - xu[None, :, :]) ** 2
    return Design(
        x=xu,
        sq_flat=sq.reshape(n_u * n_u, -1),
        group=np.asarray(gu, dtype=int),
        y=y_u,
        obs=obs,
        count=count,
        ss=ss,
        extra=extra,
        half_log_count=half_log,
        index=index,
    )


def _factor_and_invert(
    buf: np.ndarray,
    logdet_half: np.ndarray,
    jitter: np.ndarray,
    rhs: np.ndarray | None = None,
    full: bool = True,
) -> None:
    """In place: buf[b] (symmetric PD) -> K^-1, log|K|/2 and jitter per matrix.

    ``rhs`` (k, n, r), if given, is overwritten by ``K^-1 rhs`` (from the factor, before the
    inverse). With ``full=False`` only the upper triangle (C order) of ``K^-1`` is written; the
    strict lower triangle keeps ``K``. A matrix that stays indefinite after jitter escalation gets
    ``jitter = inf`` (and an identity in ``buf``).
    """
    lapack = _lapack()
    n = buf.shape[-1]
    diag = np.diagonal(buf, axis1=1, axis2=2).copy()  # potrf overwrites it on failure
    for b in range(buf.shape[0]):
        # buf[b].T is the Fortran view of the same (symmetric) memory: factorised in place.
        c, info = lapack.dpotrf(buf[b].T, lower=1, overwrite_a=1, clean=0)
        if info != 0:
            c, jitter[b] = _jittered(buf, b, diag[b], lapack)
            if c is None:
                logdet_half[b] = np.inf
                buf[b] = np.eye(n)
                continue
        logdet_half[b] = np.sum(np.log(np.diagonal(c)))
        if rhs is not None:
            rhs[b], _ = lapack.dpotrs(c, rhs[b], lower=1)
        lapack.dpotri(c, lower=1, overwrite_c=1)
    if full:
        # In C order the valid triangle is the upper one; mirror it.
        iu, ju = np.triu_indices(n, 1)
        buf[:, ju, iu] = buf[:, iu, ju]


def _factor_and_solve(buf, rhs, logdet_half, jitter, chol_inv=None, linalg="scipy") -> None:
    """In place: rhs[b] <- K_b^-1 rhs[b] via potrf + potrs (value only: no inverse needed).

    With ``chol_inv`` (k, n, n), also write the inverse Cholesky factor L^-1 there (trtri).
    ``linalg``: whose LAPACK (:func:`_lapack`).
    """
    lapack = _lapack(linalg)
    diag = np.diagonal(buf, axis1=1, axis2=2).copy()
    for b in range(buf.shape[0]):
        c, info = lapack.dpotrf(buf[b].T, lower=1, overwrite_a=1, clean=0)
        if info != 0:
            c, jitter[b] = _jittered(buf, b, diag[b], lapack)
            if c is None:
                logdet_half[b] = np.inf
                if chol_inv is not None:
                    chol_inv[b] = np.eye(buf.shape[-1])
                continue
        logdet_half[b] = np.sum(np.log(np.diagonal(c)))
        rhs[b], _ = lapack.dpotrs(c, rhs[b], lower=1)
        if chol_inv is not None:
            c, _ = lapack.dtrtri(c, lower=1, overwrite_c=1)
            chol_inv[b] = np.tril(c)


_TRIANGLE_WEIGHTS: dict[int, np.ndarray] = {}


def _triangle_weights(n: int) -> np.ndarray:
    w = _TRIANGLE_WEIGHTS.get(n)
    if w is None:
        w = np.triu(np.full((n, n), 2.0), 1) + np.eye(n)
        if len(_TRIANGLE_WEIGHTS) > 16:
            _TRIANGLE_WEIGHTS.clear()
        _TRIANGLE_WEIGHTS[n] = w
    return w


def _jittered(buf, b, diag, lapack):
    """Cholesky of buf[b] with escalating jitter, after a failed in-place attempt."""
    # potrf overwrote the Fortran-lower (C-upper) triangle and the diagonal; the strict C-lower
    # triangle is intact.
    n = diag.size
    lower = np.tril(buf[b], -1)
    matrix = lower + lower.T + np.diag(diag)
    scale = float(np.mean(np.diag(matrix)))
    if not np.isfinite(scale) or not np.all(np.isfinite(matrix)):
        return None, np.inf
    for step in _JITTER_STEPS:
        buf[b] = matrix + step * scale * np.eye(n)
        c, info = lapack.dpotrf(buf[b].T, lower=1, overwrite_a=1, clean=0)
        if info == 0:
            return c, step * scale
    return None, np.inf


def evaluate(
    theta: np.ndarray,
    design: Design,
    *,
    n_groups: int,
    constant_mean: bool,
    want_grad: bool = True,
    want_state: bool = False,
    covariance: str = "se",
    linalg: str = "scipy",
):
    """Negative log marginal likelihood (Eq. 33, mean profiled) and gradient for each row.

    Parameters
    ----------
    theta : (k, p) log-hyperparameters [log sf, log l (1 or d), log sn (G)] per row.
    design : :class:`Design` whose per-output arrays have ``k`` rows (see :meth:`Design.take`).
    covariance : ``"se"``, ``"matern52"`` or ``"matern32"`` (:func:`robovib.gp.covariances.correlation`).
    linalg : ``"scipy"`` or ``"numpy"`` (whose LAPACK factorises; ``"numpy"`` needs
        ``want_grad=False``).

    Returns
    -------
    nll : (k,) ; inf where the covariance could not be factorised.
    grad : (k, p) or None.
    state : dict with ``chol_inv`` (k, u, u), ``alpha`` (k, u), ``mean`` (k,), ``jitter`` (k,)
        when ``want_state`` (else None).
    """
    k, p = theta.shape
    n = design.n_unique
    G = n_groups
    nll = np.empty(k)
    grad = np.empty((k, p)) if want_grad else None
    state = None
    if want_grad and linalg != "scipy":
        raise ValueError("the gradient needs linalg='scipy'")
    if want_state:
        if want_grad:
            raise ValueError("want_state needs want_grad=False")
        state = {
            "chol_inv": np.empty((k, n, n)),
            "alpha": np.empty((k, n)),
            "mean": np.empty(k),
            "jitter": np.empty(k),
        }
    # Work arrays: K_f and K^-1 buffers plus two n x n temporaries per row.
    chunk = max(1, min(k, WORK_BYTES // (5 * 8 * n * n)))
    kf_buf = np.empty((chunk, n * n))
    # γ(r) of the length-scale gradient; the SE kernel's is K itself (no buffer needed).
    kg_buf = np.empty((chunk, n * n)) if want_grad and covariance != "se" else None
    inv_buf = np.empty((chunk, n, n))
    all_obs = bool(design.obs.all())
    diag_idx = np.arange(n)
    for start in range(0, k, chunk):
        sl = slice(start, min(k, start + chunk))
        c = sl.stop - sl.start
        th = theta[sl]
        obs, count, y = design.obs[sl], design.count[sl], design.y[sl]
        log_sf, log_l, log_sn = th[:, 0], th[:, 1:-G], th[:, -G:]
        inv_l2 = np.exp(-2.0 * log_l)  # (c, 1 or d)
        kf = kf_buf[:c]
        if inv_l2.shape[1] == 1:
            np.multiply(design.sq_sum[None, :], inv_l2, out=kf)
        else:
            np.matmul(inv_l2, design.sq_flat.T, out=kf)
        sf2 = np.exp(2.0 * log_sf)[:, None]
        if covariance == "se":
            kf *= -0.5
            kf += 2.0 * log_sf[:, None]
            np.exp(kf, out=kf)
            kg3 = None
        else:
            rho, gam = correlation(kf, covariance, with_gradient=True)
            np.multiply(rho, sf2, out=kf)
            kg3 = None
            if kg_buf is not None:
                kg = kg_buf[:c]
                np.multiply(gam, sf2, out=kg)
                kg3 = kg.reshape(c, n, n)
        kf3 = kf.reshape(c, n, n)
        if not all_obs:
            kf3 *= obs[:, :, None]
            kf3 *= obs[:, None, :]
        noise_var = np.exp(2.0 * log_sn)  # (c, G)
        diag = np.where(obs, noise_var[:, design.group] / count, 1.0)
        kinv = inv_buf[:c]
        np.copyto(kinv, kf3)
        kinv[:, diag_idx, diag_idx] += diag
        logdet_half = np.empty(c)
        jitter = np.zeros(c)
        ones = obs.astype(float)
        rhs = np.stack([ones, y], axis=2)  # (c, n, 2) -> K^-1 [1, y]
        if want_grad:
            # Upper triangle of K^-1 only: the traces below weight it (2 off-diagonal, 1 diagonal).
            _factor_and_invert(kinv, logdet_half, jitter, rhs, full=False)
        else:
            # Value only (screening; and L^-1 for the fitted state): triangular solves.
            out = state["chol_inv"][sl] if want_state else None
            _factor_and_solve(kinv, rhs, logdet_half, jitter, out, linalg)
        kinv_1, kinv_y = rhs[:, :, 0], rhs[:, :, 1]
        failed = ~np.isfinite(logdet_half)
        if constant_mean:
            m = np.sum(kinv_1 * y, axis=1) / np.sum(kinv_1 * ones, axis=1)
        else:
            m = np.zeros(c)
        r = np.where(obs, y - m[:, None], 0.0)
        alpha = np.where(obs, kinv_y - m[:, None] * kinv_1, 0.0)
        n_obs = obs.sum(axis=1)
        sig2 = noise_var  # (c, G)
        correction = (
            design.half_log_count[sl]
            + np.sum(design.ss[sl] / (2.0 * sig2), axis=1)
            + np.sum(0.5 * design.extra[sl] * (_LOG_2PI + 2.0 * log_sn), axis=1)
        )
        value = 0.5 * np.sum(r * alpha, axis=1) + logdet_half + 0.5 * n_obs * _LOG_2PI + correction
        nll[sl] = np.where(failed, np.inf, value)
        if want_state:
            state["alpha"][sl] = alpha
            state["mean"][sl] = m
            state["jitter"][sl] = jitter
        if not want_grad:
            continue
        # dNLL/dtheta_j = 1/2 tr((K^-1 - alpha alpha^T) dK/dtheta_j)   (kinv becomes that - aa^T)
        kinv -= alpha[:, :, None] * alpha[:, None, :]
        kinv_diag = np.diagonal(kinv, axis1=1, axis2=2).copy()
        # Elementwise with the noise-free kernel; both symmetric, so sum the upper triangle with
        # weight 2 off the diagonal (the strict lower triangle of kinv is not K^-1: weight 0).
        tri = _triangle_weights(n)
        g = grad[sl]
        if kg3 is not None:
            if not all_obs:
                kg3 *= obs[:, :, None]
                kg3 *= obs[:, None, :]
            kg3 *= tri
            kg3 *= kinv
            g[:, 0] = np.sum(kinv * (kf3 * tri), axis=(1, 2))  # dK/dlog sf = 2 K_f
            wk = kg3.reshape(c, n * n)
        else:
            kf3 *= tri
            kinv *= kf3
            wk = kinv.reshape(c, n * n)
            g[:, 0] = np.sum(wk, axis=1)  # dK/dlog sf = 2 K_f
        if inv_l2.shape[1] == 1:
            g[:, 1] = 0.5 * (wk @ design.sq_sum) * inv_l2[:, 0]
        else:
            g[:, 1 : 1 + inv_l2.shape[1]] = 0.5 * (wk @ design.sq_flat) * inv_l2
        w_noise = np.where(obs, kinv_diag / count, 0.0)
        for j in range(G):
            in_group = design.group == j
            g[:, p - G + j] = (
                np.sum(w_noise[:, in_group], axis=1) * sig2[:, j]
                - design.ss[sl, j] / sig2[:, j]
                + design.extra[sl, j]
            )
        g[failed] = 0.0
    return nll, grad, state
