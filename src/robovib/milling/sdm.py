"""Chatter stability by first-order semi-discretization (Insperger & Stépán), vectorised over speeds.

Model
-----
The tool tip is flexible in the feed (x) and normal (y) directions; each direction is a sum of
modes (``x = sum_r xi_r`` over the x modes, likewise y), mode ``r`` obeying
``m_r xi_r'' + c_r xi_r' + k_r xi_r = F_dir(r)``. With flute ``j`` at the immersion angle
``phi_j(t) = 2 pi n t / 60 + 2 pi j / N`` (clockwise from +y, the convention of
:mod:`robovib.milling.forces`) and the dynamic chip thickness ``(r(t) - r(t - tau)) . u_j``,
``u_j = (sin phi_j, cos phi_j)``, the regenerative force linearised about the periodic motion is
(Insperger & Stépán, *Int. J. Numer. Meth. Eng.* 61, 2004, Eq. 22; Altintas' ``-a K_t A(t)/2``)::

    F(t) = -a H(t) (r(t) - r(t - tau)),   tau = 60 / (N n)
    H = sum_j g_j [[s (K_t c + K_n s),  c (K_t c + K_n s)],
                   [s (-K_t s + K_n c), c (-K_t s + K_n c)]],   s = sin phi_j, c = cos phi_j

(``g_j = 1`` inside the engagement ``[phi_st, phi_ex]`` of :func:`~robovib.milling.forces.
engagement_angles`, ``K_t = ktc``, ``K_n = krc``; the edge coefficients do not regenerate). The
helix angle is ignored: every axial slice is taken at the same immersion angle, which is the
standard assumption of the method (it slightly smooths ``H`` in reality and matters only at low
radial immersion with large helix and depth).

With ``y = [xi, xi']`` this is the periodic delay-differential equation
``y' = (A0 + a B(t)) y(t) - a B(t) y(t - tau)``.

Semi-discretization (first order)
---------------------------------
One delay period is cut into steps ``[t_i, t_{i+1})`` on a grid that repeats every period, so
``t_i - tau`` is again a grid point ``t_{i-M}``. On each step ``B`` is replaced by its exact
average ``B_i`` (``H`` integrated analytically over the step's angles) and the delayed term by the
linear interpolation ``xi(t - tau) = xi_{i-M} + (t - t_i)/h_i (xi_{i-M+1} - xi_{i-M})``
(Insperger, Stépán & Turi, *J. Sound Vib.* 313, 2008). The step is then solved exactly::

    y_{i+1} = E_i y_i + (R_i - S_i) xi_{i-M} + S_i xi_{i-M+1},   E_i = exp(A_i h_i)
    R_i = int_0^h exp(A_i (h - s)) ds D_i,   S_i = int_0^h exp(A_i (h - s)) s/h ds D_i

(``A_i = A0 + a B_i``, ``D_i`` the delayed-displacement input), all three from one matrix
exponential of the block matrix ``[[A_i, D_i, 0], [0, 0, I/h], [0, 0, 0]] h`` (Van Loan). The
cutting arc is resolved by ``steps_per_period`` equal steps; when the arc is shorter than the
tooth pitch the free flight is one exact step with no delayed term, so only the displacements at
the cutting grid points of the previous period enter the state. Chaining the steps over one
period gives the monodromy matrix ``Phi`` of ``z = [y_0, xi_{-M}, ..., xi_{-M+m}]``; the cut is
asymptotically stable iff all eigenvalues (Floquet multipliers) satisfy ``|mu| < 1``. A critical
multiplier leaving the unit circle as a complex pair is a Hopf (secondary Hopf) bifurcation, at
``-1`` a flip (period doubling) — the lobes the zero-order method cannot see at low immersion.

The critical depth at every speed is found by a geometric scan upwards in depth (ratio 1.2
between depths) that stops at the first unstable depth, refined by the Illinois (regula-falsi)
method on ``log |mu|_max``, all speeds in one batch (batched matrix exponentials, products and
eigenvalues in NumPy). It is the *lowest* unstable depth: where a speed has an unstable window
(e.g. a flip lens at low immersion), then a stable pocket, then the Hopf lobe, the window's
lower edge is the limit (a window narrower than one scan step can be missed).

Only the largest multiplier is needed. It is found by a few Arnoldi iterations on the monodromy
matrix (:func:`dominant_eigenvalues`: 12 batched matrix-vector products instead of a dense
eigendecomposition of the ``(d + n (m + 1))``-square matrix, each Ritz value's residual checked,
with a dense fallback), which made a 200-speed chart 2.5-5 times faster at the same limits (to
~1e-10); ``eigensolver="dense"`` computes every eigenvalue, the reference.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from .._linalg import batched_expm
from ..modal.parameters import ModalParameters
from .envelope import LobeEnvelope
from .forces import CuttingCoefficients, CuttingConditions, MillingTool, engagement_angles

__all__ = [
    "EIGENSOLVERS",
    "batched_expm",
    "critical_depths",
    "dominant_eigenvalues",
    "floquet_multipliers",
    "milling_force_matrices",
    "sdm_lobes",
    "semi_discretization_multipliers",
    "turning_minimum_depth",
]


def turning_minimum_depth(mode: ModalParameters, specific_force_n_per_m2: float) -> float:
    """Closed-form minimum critical depth [m] of a 1-DOF regenerative process with constant force.

    For ``m x'' + c x' + k x = -a h (x(t) - x(t - tau))`` (``h`` > 0 the constant directional
    cutting coefficient [N/m²]) the characteristic equation on the imaginary axis,
    ``1 + a h G(i w) (1 - exp(-i w tau)) = 0`` with ``G = 1/(k - m w² + i c w)``, has the real
    part ``1 + 2 a h Re G = 0`` at every boundary point, so ``a_lim(w) = -1 / (2 h Re G(i w))``.
    ``Re G = (1 - r²) / (k ((1 - r²)² + (2 zeta r)²))`` is most negative at ``r² = 1 + 2 zeta``,
    where it equals ``-1 / (4 k zeta (1 + zeta))``; hence the absolute stability limit::

        a_min = 2 k zeta (1 + zeta) / h

    Parameters
    ----------
    mode : ModalParameters
        The single mode (k [N/m], zeta).
    specific_force_n_per_m2 : float
        ``h`` [N/m²], > 0.

    Returns
    -------
    float
        ``a_min`` [m].
    """
    if not specific_force_n_per_m2 > 0:
        raise ValueError(f"specific force must be > 0 N/m², got {specific_force_n_per_m2!r}")
    k, z = mode.stiffness_n_per_m, mode.damping_ratio
    return 2 * k * z * (1 + z) / specific_force_n_per_m2


# -- specific force matrices ---------------------------------------------------------------------


def _h_antiderivative(phi: np.ndarray, kt: float, kn: float) -> np.ndarray:
    """Antiderivative in phi of H's four entries (..., 2, 2) for one engaged flute."""
    s2 = np.sin(2 * phi)
    int_sc = np.sin(phi) ** 2 / 2
    int_ss = phi / 2 - s2 / 4
    int_cc = phi / 2 + s2 / 4
    return np.stack(
        [
            np.stack([kt * int_sc + kn * int_ss, kt * int_cc + kn * int_sc], axis=-1),
            np.stack([-kt * int_ss + kn * int_sc, -kt * int_sc + kn * int_cc], axis=-1),
        ],
        axis=-2,
    )


def milling_force_matrices(
    n_flutes: int,
    phi_start_rad: float,
    phi_exit_rad: float,
    coefficients: CuttingCoefficients,
    steps_per_period: int,
) -> tuple[np.ndarray, np.ndarray]:
    """Step-averaged specific force matrices ``H_i`` over one tooth period and the step lengths.

    Parameters
    ----------
    n_flutes : int
        Number of teeth ``N``.
    phi_start_rad, phi_exit_rad : float
        Engagement angles [rad], ``0 <= phi_st < phi_ex <= pi``.
    coefficients : CuttingCoefficients
        ``ktc`` and ``krc`` [N/m²] are used.
    steps_per_period : int
        Steps across the cutting arc (the whole period when the arc is >= the tooth pitch).

    Returns
    -------
    h_n_per_m2 : ndarray (n_steps, 2, 2)
        Average of ``H(t)`` over each step, per unit axial depth [N/m²] (module docs).
    fraction : ndarray (n_steps,)
        Step lengths as fractions of the tooth period (sum 1). When the arc is shorter than the
        pitch the last step is the free flight (``H = 0``).
    """
    m = int(steps_per_period)
    if m < 2:
        raise ValueError(f"steps_per_period must be >= 2, got {steps_per_period}")
    n = int(n_flutes)
    if n < 1:
        raise ValueError(f"n_flutes must be >= 1, got {n_flutes}")
    if not 0 <= phi_start_rad < phi_exit_rad <= math.pi + 1e-12:
        raise ValueError(
            f"engagement must satisfy 0 <= phi_st < phi_ex <= pi rad, got "
            f"({phi_start_rad}, {phi_exit_rad})"
        )
    pitch = 2 * math.pi / n
    arc = phi_exit_rad - phi_start_rad
    if arc < pitch - 1e-12:
        edges = np.linspace(phi_start_rad, phi_exit_rad, m + 1)
        edges = np.append(edges, phi_start_rad + pitch)
    else:
        edges = np.linspace(0.0, pitch, m + 1)
    a, b = edges[:-1], edges[1:]
    total = np.zeros((a.size, 2, 2))
    for j in range(n):
        # Angles of flute j over each step, and every 2 pi shift that can meet the engagement.
        aj, bj = a + j * pitch, b + j * pitch
        for shift in (-2 * math.pi, 0.0, 2 * math.pi, 4 * math.pi):
            lo = np.clip(aj + shift, phi_start_rad, phi_exit_rad)
            hi = np.clip(bj + shift, phi_start_rad, phi_exit_rad)
            inside = hi > lo
            if np.any(inside):
                diff = _h_antiderivative(hi, coefficients.ktc, coefficients.krc)
                diff = diff - _h_antiderivative(lo, coefficients.ktc, coefficients.krc)
                total += np.where(inside[:, None, None], diff, 0.0)
    width = b - a
    return total / width[:, None, None], width / pitch


# -- dominant Floquet multipliers --------------------------------------------------------------

EIGENSOLVERS = ("arnoldi", "dense")


def dominant_eigenvalues(
    a: np.ndarray, n_eigenvalues: int = 1, *, krylov_dim: int = 12, rtol: float = 1e-10
) -> np.ndarray:
    """Largest-modulus eigenvalues of a stack of square matrices (b, N, N) by Arnoldi iterations.

    ``krylov_dim`` steps of the Arnoldi process (classical Gram-Schmidt, repeated once) from a
    fixed start vector, batched over the stack, then the eigenvalues of the small Hessenberg
    matrices (the Ritz values). A Ritz value counts as converged when its residual
    ``|h_{k+1,k}| |e_k^T s|`` is below ``rtol`` times its modulus (floored at 1e-3); matrices
    with one unconverged value are tried again with twice the steps while that is at most a
    quarter of ``N``, then fall back to the dense ``numpy.linalg.eigvals``. The SDM monodromy
    matrix has a few multipliers well away from the cloud near zero, so 12 steps replace an
    O(N³) eigendecomposition by 12 O(N²) matrix-vector products (the chart's main cost).

    Parameters
    ----------
    a : ndarray (b, N, N)
        Real matrices.
    n_eigenvalues : int
        How many to return, by decreasing modulus (dense for more than ``krylov_dim // 2``).
    krylov_dim : int
        Arnoldi steps (the Krylov subspace's dimension).
    rtol : float
        Relative residual accepted.

    Returns
    -------
    ndarray (b, n_eigenvalues) complex
    """
    a = np.asarray(a, float)
    b, n, _ = a.shape
    k = min(int(krylov_dim), n)
    n_ev = int(n_eigenvalues)
    if n_ev > k // 2 or k < 4:
        mu = np.linalg.eigvals(a)
        order = np.argsort(-np.abs(mu), axis=1)[:, :n_ev]
        return np.take_along_axis(mu, order, axis=1)
    q = np.zeros((b, k + 1, n))
    hess = np.zeros((b, k + 1, k))
    v = np.cos(0.7 * np.arange(n) + 0.3) + 0.5  # generic, deterministic start vector
    q[:, 0] = v / np.linalg.norm(v)
    for j in range(k):
        w = np.matmul(a, q[:, j, :, None])[..., 0]
        basis = q[:, : j + 1]
        for _ in range(2):  # Gram-Schmidt twice: orthogonal to working precision
            c = np.matmul(basis, w[..., None])[..., 0]
            w = w - np.matmul(c[:, None, :], basis)[:, 0]
            hess[:, : j + 1, j] += c
        beta = np.linalg.norm(w, axis=1)
        hess[:, j + 1, j] = beta
        ok = beta > 1e-300  # an invariant subspace: the Ritz values are exact
        q[:, j + 1] = np.where(ok[:, None], w / np.where(ok, beta, 1.0)[:, None], 0.0)
    ritz, vec = np.linalg.eig(hess[:, :k, :k])
    order = np.argsort(-np.abs(ritz), axis=1)[:, :n_ev]
    mu = np.take_along_axis(ritz, order, axis=1)
    resid = np.abs(hess[:, k, k - 1])[:, None] * np.abs(
        np.take_along_axis(vec[:, k - 1, :], order, axis=1)
    )
    bad = np.flatnonzero(~np.all(resid <= rtol * np.maximum(np.abs(mu), 1e-3), axis=1))
    if bad.size and 4 * k <= n:  # slow convergence (close moduli): a larger subspace first
        mu[bad] = dominant_eigenvalues(a[bad], n_ev, krylov_dim=2 * k, rtol=rtol)
    elif bad.size:
        dense = np.linalg.eigvals(a[bad])
        order = np.argsort(-np.abs(dense), axis=1)[:, :n_ev]
        mu[bad] = np.take_along_axis(dense, order, axis=1)
    return mu


# -- semi-discretization core ----------------------------------------------------------------


def _modal_matrices(modes_x: Sequence[ModalParameters], modes_y: Sequence[ModalParameters]):
    modes = list(modes_x) + list(modes_y)
    if not modes:
        raise ValueError("at least one mode (x or y) is needed")
    for md in modes:
        if not isinstance(md, ModalParameters):
            raise TypeError(f"modes must be ModalParameters, got {type(md).__name__}")
    n = len(modes)
    sel = np.zeros((2, n))  # r = sel @ xi  (x, y displacement from modal coordinates)
    sel[0, : len(modes_x)] = 1.0
    sel[1, len(modes_x) :] = 1.0
    wn = np.array([md.omega_n for md in modes])
    zeta = np.array([md.damping_ratio for md in modes])
    mass = np.array([md.mass_kg for md in modes])
    a0 = np.zeros((2 * n, 2 * n))
    a0[:n, n:] = np.eye(n)
    a0[n:, :n] = -np.diag(wn**2)
    a0[n:, n:] = -np.diag(2 * zeta * wn)
    return a0, sel, mass, n


def semi_discretization_multipliers(
    modes_x: Sequence[ModalParameters],
    modes_y: Sequence[ModalParameters],
    h_n_per_m2: np.ndarray,
    fraction: np.ndarray,
    delay_s,
    depth_m,
    *,
    n_multipliers: int = 1,
    eigensolver: str = "arnoldi",
) -> np.ndarray:
    """Largest Floquet multipliers of the semi-discretized periodic DDE (module docs).

    Parameters
    ----------
    modes_x, modes_y : sequence of ModalParameters
        Tool-tip modes in the feed (x) and normal (y) directions (either may be empty).
    h_n_per_m2 : ndarray (n_steps, 2, 2)
        Step-averaged specific force matrix per unit depth [N/m²] (e.g.
        :func:`milling_force_matrices`; a constant one models turning).
    fraction : ndarray (n_steps,)
        Step lengths as fractions of the delay (positive, summing to 1).
    delay_s, depth_m : array_like (b,)
        Delay (tooth period) [s] and axial depth [m] per batch element (broadcast together).
    n_multipliers : int
        How many multipliers to return, by decreasing modulus.
    eigensolver : {"arnoldi", "dense"}
        ``"arnoldi"``: :func:`dominant_eigenvalues` (checked residuals, dense fallback);
        ``"dense"``: every eigenvalue of the monodromy matrix (``numpy.linalg.eigvals``).

    Returns
    -------
    ndarray (b, n_multipliers) complex
        Floquet multipliers; the cut is stable where ``|mu| < 1``.
    """
    if eigensolver not in EIGENSOLVERS:
        raise ValueError(f"eigensolver must be one of {EIGENSOLVERS}, got {eigensolver!r}")
    _, sel, mass, n = _modal_matrices(modes_x, modes_y)
    hmat = np.asarray(h_n_per_m2, float)
    frac = np.asarray(fraction, float)
    if hmat.ndim != 3 or hmat.shape[1:] != (2, 2) or frac.shape != hmat.shape[:1]:
        raise ValueError(
            f"h_n_per_m2 must be (n_steps, 2, 2) and fraction (n_steps,), got {hmat.shape} "
            f"and {frac.shape}"
        )
    if np.any(frac <= 0) or abs(frac.sum() - 1) > 1e-9:
        raise ValueError("fraction must be positive step lengths summing to 1 (of the delay)")
    delay, depth = np.broadcast_arrays(
        np.atleast_1d(np.asarray(delay_s, float)), np.atleast_1d(np.asarray(depth_m, float))
    )
    if delay.ndim != 1:
        raise ValueError(f"delay_s and depth_m must be 1-D, got shape {delay.shape}")
    if not (np.all(np.isfinite(delay)) and np.all(delay > 0)):
        raise ValueError("delay_s must be positive finite seconds")
    if not (np.all(np.isfinite(depth)) and np.all(depth >= 0)):
        raise ValueError("depth_m must be finite and >= 0 m")
    modes = list(modes_x) + list(modes_y)
    wn = np.array([md.omega_n for md in modes])
    zeta = np.array([md.damping_ratio for md in modes])
    b = delay.size
    phi = _monodromy(
        np.broadcast_to(wn, (b, n)), np.broadcast_to(zeta, (b, n)),
        np.broadcast_to(mass, (b, n)), sel, hmat, frac, delay, depth,
    )  # fmt: skip
    if eigensolver == "arnoldi":
        return dominant_eigenvalues(phi, int(n_multipliers))
    mu = np.linalg.eigvals(phi)
    order = np.argsort(-np.abs(mu), axis=1)[:, : int(n_multipliers)]
    return np.take_along_axis(mu, order, axis=1)


def _monodromy(wn, zeta, mass, sel, hmat, frac, delay, depth) -> np.ndarray:
    """Monodromy matrices (b, dim, dim) of the semi-discretized DDE, the modes per batch element.

    ``wn`` [rad/s], ``zeta``, ``mass`` [kg] (b, n) of the ``n`` modes of each element (``sel``
    (2, n) maps them on x and y; equal for all elements), ``hmat`` (n_steps, 2, 2) and ``frac``
    (n_steps,) as in :func:`semi_discretization_multipliers`, ``delay`` [s] and ``depth`` [m]
    (b,). Samples of a structure with different modes are solved in one batch this way.
    """
    b, n = wn.shape
    d = 2 * n
    n_steps = frac.size
    cutting = np.any(hmat != 0, axis=(1, 2))
    # Delayed displacement indices (i - M, i - M + 1), M = n_steps; state columns for them.
    needed = sorted(
        {i - n_steps for i in np.flatnonzero(cutting)}
        | {i - n_steps + 1 for i in np.flatnonzero(cutting)}
    )
    col: dict[int, int] = {}
    for j in needed:
        if j == 0:
            continue  # xi_0 is part of y_0
        col[j] = d + n * len(col)
    dim = d + n * len(col)

    def cols_of(j: int) -> slice:
        start = 0 if j == 0 else col[j]
        return slice(start, start + n)

    # Modal input of the delayed displacement: xi'' += M^-1 sel^T H sel a xi(t - tau).
    mh = (sel.T @ hmat @ sel)[None] / mass[:, None, :, None]  # (b, n_steps, n, n)
    h = delay[:, None] * frac[None, :]  # (b, n_steps)
    size = d + 2 * n
    blk = np.zeros((b, n_steps, size, size))
    idx = np.arange(n)
    blk[:, :, idx, n + idx] = 1.0
    blk[:, :, n + idx, idx] = -(wn**2)[:, None, :]
    blk[:, :, n + idx, n + idx] = -(2 * zeta * wn)[:, None, :]
    blk[:, :, n:d, :n] -= depth[:, None, None, None] * mh
    blk[:, :, n:d, d : d + n] = depth[:, None, None, None] * mh
    blk[:, :, d : d + n, d + n :] = np.eye(n)[None, None] / h[:, :, None, None]
    blk *= h[:, :, None, None]
    # Balance before the exponential: velocities in units of wn x displacement (exp(T^-1 B T) =
    # T^-1 exp(B) T). The blocks' 1-norms fall from ~10-10^4 to ~1, and with them the
    # squarings of the scaling-and-squaring method (the chart's main cost).
    t = np.ones((b, size))
    t[:, n:d] = wn
    blk *= t[:, None, None, :] / t[:, None, :, None]
    ex = batched_expm(blk)
    ex *= t[:, None, :, None] / t[:, None, None, :]
    e_mat = ex[..., :d, :d]
    r_mat = ex[..., :d, d : d + n]
    s_mat = ex[..., :d, d + n :]
    y = np.zeros((b, d, dim))
    y[:, :, :d] = np.eye(d)
    xi_out: dict[int, np.ndarray] = {0: y[:, :n, :].copy()}
    for i in range(n_steps):
        y = e_mat[:, i] @ y
        if cutting[i]:
            y[:, :, cols_of(i - n_steps)] += r_mat[:, i] - s_mat[:, i]
            y[:, :, cols_of(i - n_steps + 1)] += s_mat[:, i]
        xi_out[i + 1] = y[:, :n, :]
    phi = np.zeros((b, dim, dim))
    phi[:, :d, :] = y
    for j, c in col.items():
        phi[:, c : c + n, :] = xi_out[j + n_steps]
    return phi


def floquet_multipliers(
    modes_x: Sequence[ModalParameters],
    modes_y: Sequence[ModalParameters],
    tool: MillingTool,
    conditions: CuttingConditions,
    coefficients: CuttingCoefficients,
    spindle_rpm,
    depth_m,
    *,
    steps_per_period: int = 40,
) -> np.ndarray:
    """Largest Floquet multiplier (b,) complex of milling at speeds [rpm] and depths [m].

    The radial immersion and milling direction come from ``conditions`` (its own speed and
    depth are not used); see :func:`semi_discretization_multipliers`.

    Parameters
    ----------
    modes_x, modes_y : sequence of ModalParameters
        Tool-tip modes in the feed (x) and normal (y) directions (either may be empty).
    tool : MillingTool
        Number of flutes (delay = tooth period) and geometry.
    conditions : CuttingConditions
        Radial immersion and milling direction (up / down).
    coefficients : CuttingCoefficients
        Tangential and radial cutting-force coefficients [N/m²].
    spindle_rpm, depth_m : array_like (b,)
        Spindle speeds [rpm] (positive) and axial depths of cut [m], broadcast together.
    steps_per_period : int
        Semi-discretization steps per tooth period.

    Returns
    -------
    ndarray (b,) complex
        Floquet multiplier of largest modulus; the cut is stable where ``|mu| < 1``.

    Raises
    ------
    ValueError
        Non-positive or non-finite speeds.
    """
    rpm = np.atleast_1d(np.asarray(spindle_rpm, float))
    if not (np.all(np.isfinite(rpm)) and np.all(rpm > 0)):
        raise ValueError("spindle_rpm must be positive finite speeds [rpm]")
    phi_st, phi_ex = engagement_angles(tool, conditions)
    hmat, frac = milling_force_matrices(
        tool.n_flutes, phi_st, phi_ex, coefficients, steps_per_period
    )
    delay = 60.0 / (tool.n_flutes * rpm)
    return semi_discretization_multipliers(modes_x, modes_y, hmat, frac, delay, depth_m)[:, 0]


def _classify(mu: np.ndarray, delay: np.ndarray, modes: Sequence[ModalParameters]):
    """Bifurcation kind and chatter frequency [Hz] from the critical multiplier.

    The multiplier fixes the chatter frequency up to multiples of the tooth-passing frequency,
    ``f = (±arg(mu) / 2 pi + k) / T``; the candidate where the modes' summed receptance
    magnitude is largest is reported (the vibration is dominated by it).
    """
    ang = np.angle(mu)
    kind = np.where(
        np.abs(np.abs(ang) - math.pi) < 0.02, "flip", np.where(np.abs(ang) < 0.02, "fold", "hopf")
    )
    base = np.abs(ang) / (2 * math.pi)
    ks = np.arange(0, 400)
    cand = np.concatenate(
        [(base[:, None] + ks[None]) / delay[:, None], (-base[:, None] + ks[None]) / delay[:, None]],
        axis=1,
    )
    fmax = 3 * max(md.natural_frequency_hz for md in modes)
    cand = np.where((cand > 0) & (cand < fmax), cand, np.nan)
    mag = sum(np.abs(md.compliance(np.nan_to_num(cand))) for md in modes)
    mag = np.where(np.isfinite(cand), mag, -1.0)
    pick = np.argmax(mag, axis=1)
    return kind, cand[np.arange(cand.shape[0]), pick]


def critical_depths(
    modes_x: Sequence[ModalParameters],
    modes_y: Sequence[ModalParameters],
    h_n_per_m2: np.ndarray,
    fraction: np.ndarray,
    delay_s,
    *,
    depth_range_m: tuple[float, float] | None = None,
    n_scan: int | None = None,
    rtol: float = 1e-3,
    max_iter: int = 40,
    eigensolver: str = "arnoldi",
    warm_start: bool = True,
    scan_ratio: float = 1.2,
    first_stride: int = 8,
    scan_from_m=None,
    batch_modes: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Lowest unstable depth [m] at each delay [s] of the semi-discretized DDE, and its multiplier.

    Parameters
    ----------
    modes_x, modes_y, h_n_per_m2, fraction
        As in :func:`semi_discretization_multipliers`.
    delay_s : array_like (b,)
        Delays [s].
    depth_range_m : (float, float), optional
        Geometric scan range [m]; default ``/10`` to ``x1000`` of the smallest 1-DOF turning
        limit (:func:`turning_minimum_depth`) with the largest averaged force coefficient.
    n_scan : int, optional
        Scan points over the whole range (overrides ``scan_ratio``; the old default was 10, a
        factor 2.8 between points, which stepped over unstable windows).
    scan_ratio : float
        Ratio of neighbouring scan depths (default 1.2). Each speed is scanned upwards and
        leaves the scan at its first unstable depth, which is then refined, so the result is
        the *lowest* unstable depth: an unstable window below a stable pocket (flip lenses at
        low immersion, several modes) is found wherever it is wider than one scan step.
    rtol, max_iter
        Relative tolerance and iteration cap of the Illinois refinement.
    eigensolver : {"arnoldi", "dense"}
        How the largest multiplier is found (:func:`semi_discretization_multipliers`).
    warm_start : bool
        Scan every ``first_stride``-th speed from the bottom of the range, and the others from
        just below the lowest limit found among those (no speed chatters below the lowest
        critical depth over all speeds; a speed unstable already there is scanned from the
        bottom), and end each refinement when the linearised step in log(depth) falls below
        ``rtol / 4``. ``False``: every speed from the bottom, brackets closed to ``rtol``.
    first_stride : int
        Speeds between two full scans (``warm_start``).
    scan_from_m : array_like (b,), optional
        Depth [m] per delay from which the scan starts instead (e.g. a little below the limits
        of a nearby structure, when many similar ones are solved); a speed already unstable
        there is scanned again from about 3x lower (down to the bottom of the range), so the
        result is its lowest unstable depth unless a window lies wholly below a stable start.
        NaN or non-positive: from the bottom.
    batch_modes : (wn_rad_s, zeta, mass_kg), each (b, n), optional
        A different structure at every delay (e.g. the samples of a predictive distribution,
        all solved in one batch): the natural frequencies [rad/s], damping ratios and modal
        masses [kg] of its ``n`` modes, in the order ``modes_x + modes_y`` (which then give only
        the x/y split and the default depth range).

    Returns
    -------
    a_lim_m : ndarray (b,)
        Critical depth (``inf`` where stable up to the top of the range).
    multiplier : ndarray (b,) complex
        Critical Floquet multiplier just above ``a_lim_m`` (NaN where stable).
    """
    hmat = np.asarray(h_n_per_m2, float)
    frac = np.asarray(fraction, float)
    delay = np.atleast_1d(np.asarray(delay_s, float))
    modes = list(modes_x) + list(modes_y)
    if not modes:
        raise ValueError("at least one mode (x or y) is needed")
    if depth_range_m is None:
        h_avg = float(np.max(np.abs(np.einsum("i,ijk->jk", frac, hmat))))
        if not h_avg > 0:
            raise ValueError("the specific force matrices are all zero: nothing regenerates")
        ref = min(turning_minimum_depth(md, h_avg) for md in modes)
        lo, hi = ref / 10, ref * 1000
    else:
        lo, hi = (float(v) for v in depth_range_m)
        if not 0 < lo < hi:
            raise ValueError(f"depth_range_m must be 0 < low < high [m], got {depth_range_m}")

    if batch_modes is not None:
        wn_b, zeta_b, mass_b = (np.asarray(v, float) for v in batch_modes)
        if not wn_b.shape == zeta_b.shape == mass_b.shape == (delay.size, len(modes)):
            raise ValueError(
                f"batch_modes must be three ({delay.size}, {len(modes)}) arrays, got "
                f"{wn_b.shape}, {zeta_b.shape}, {mass_b.shape}"
            )
        sel_b = _modal_matrices(modes_x, modes_y)[1]

    def radius(depths, idx):
        if batch_modes is None:
            mu = semi_discretization_multipliers(
                modes_x, modes_y, hmat, frac, delay[idx], depths, eigensolver=eigensolver
            )
        else:
            phi = _monodromy(wn_b[idx], zeta_b[idx], mass_b[idx], sel_b, hmat, frac,
                             delay[idx], np.asarray(depths, float))  # fmt: skip
            mu = dominant_eigenvalues(phi) if eigensolver == "arnoldi" else np.linalg.eigvals(phi)
            if eigensolver != "arnoldi":
                mu = np.take_along_axis(mu, np.argsort(-np.abs(mu), axis=1)[:, :1], axis=1)
        return np.abs(mu[:, 0]), mu[:, 0]

    if not scan_ratio > 1:
        raise ValueError(f"scan_ratio must be > 1, got {scan_ratio!r}")
    n_grid = math.ceil(math.log(hi / lo) / math.log(scan_ratio)) + 1
    grid = np.geomspace(lo, hi, max(n_grid, 2) if n_scan is None else int(n_scan))

    def refine(idx, a_lo, f_lo, a_hi, f_hi):
        """Illinois iterations on log|mu| over brackets [a_lo, a_hi] at delay[idx] (in place)."""
        side = np.zeros(idx.size, int)
        mu_hi = np.full(idx.size, np.nan + 0j)
        g_lo, g_hi = f_lo.copy(), f_hi.copy()  # log|mu| at the ends (never halved)
        for _ in range(int(max_iter)):
            i = np.flatnonzero((a_hi - a_lo) > rtol * a_hi)  # speeds still being refined
            if i.size == 0:
                break
            denom = f_hi[i] - f_lo[i]
            a_new = np.where(
                denom > 0, a_hi[i] - f_hi[i] * (a_hi[i] - a_lo[i]) / np.where(denom > 0, denom, 1),
                0.5 * (a_lo[i] + a_hi[i]),
            )  # fmt: skip
            bad = ~((a_new > a_lo[i]) & (a_new < a_hi[i]))
            a_new = np.where(bad, 0.5 * (a_lo[i] + a_hi[i]), a_new)
            r, mu = radius(a_new, idx[i])
            f_new = np.log(r)
            up = f_new >= 0
            if warm_start:
                # Converged by the residual: log|mu| is nearly linear in log(depth) near the
                # root; with the slope across the bracket, a step below rtol / 4 ends the search.
                with np.errstate(divide="ignore", invalid="ignore"):
                    slope = (g_hi[i] - g_lo[i]) / np.log(a_hi[i] / a_lo[i])
                    step = -f_new / slope
                close = (a_lo[i] > 0) & (slope > 0) & (np.abs(step) < 0.25 * rtol)
                g_hi[i] = np.where(up, f_new, g_hi[i])
                g_lo[i] = np.where(up, g_lo[i], f_new)
                if np.any(close):
                    c = i[close]
                    a_root = a_new[close] * np.exp(step[close])
                    a_lo[c], a_hi[c], mu_hi[c] = a_root, a_root, mu[close]
                    keep = ~close
                    i, a_new, f_new, up, mu = i[keep], a_new[keep], f_new[keep], up[keep], mu[keep]
            # Illinois: halve the stale end's value when the same end is kept twice.
            f_lo[i] = np.where(up & (side[i] == 1), 0.5 * f_lo[i], f_lo[i])
            f_hi[i] = np.where(~up & (side[i] == -1), 0.5 * f_hi[i], f_hi[i])
            a_hi[i], f_hi[i] = np.where(up, a_new, a_hi[i]), np.where(up, f_new, f_hi[i])
            mu_hi[i] = np.where(up, mu, mu_hi[i])
            a_lo[i], f_lo[i] = np.where(up, a_lo[i], a_new), np.where(up, f_lo[i], f_new)
            side[i] = np.where(up, 1, -1)
        missing = ~np.isfinite(mu_hi)
        if np.any(missing):
            mu_hi[missing] = radius(a_hi[missing], idx[missing])[1]
        return 0.5 * (a_lo + a_hi), mu_hi

    def scan(idx, k0=None, stop=None):
        """Lowest critical depths at delay[idx]: geometric scan upwards, then refinement.

        ``k0`` (per speed) is the first grid index scanned (a speed already unstable there is
        scanned again from six grid steps lower, down to the bottom of the grid); ``stop`` (per
        speed) ends a speed's scan below that depth with ``inf`` (no unstable depth below it).
        """
        k0 = np.zeros(idx.size, int) if k0 is None else np.asarray(k0, int)
        stop = np.full(idx.size, np.inf) if stop is None else np.asarray(stop, float)
        rho = np.full((idx.size, grid.size), np.nan)
        # Scan upwards; a speed leaves the scan at its first unstable depth.
        first = np.full(idx.size, -1)
        done = np.zeros(idx.size, bool)
        for k in range(int(k0.min()), grid.size):
            done |= grid[k] >= stop
            todo = np.flatnonzero((first < 0) & ~done & (k >= k0))
            if not np.any((first < 0) & ~done):
                break
            if todo.size == 0:
                continue
            rho[todo, k] = radius(np.full(todo.size, grid[k]), idx[todo])[0]
            first[todo[rho[todo, k] >= 1]] = k
        again = np.flatnonzero((first >= 0) & (first == k0) & (k0 > 0))
        a_out = np.full(idx.size, np.inf)
        mu_out = np.full(idx.size, np.nan + 0j)
        if again.size:  # unstable at the scan's first depth: start 1.2^6 ~ 3x lower, again
            a_out[again], mu_out[again] = scan(idx[again], np.maximum(k0[again] - 6, 0))
            first[again] = -1
        act = np.flatnonzero(first >= 0)
        if act.size:
            k = first[act]
            a_hi = grid[k].astype(float)
            f_hi = np.log(rho[act, k])
            a_lo = np.where(k > 0, grid[np.maximum(k - 1, 0)], 0.0)
            f_lo = np.where(k > 0, np.log(rho[act, np.maximum(k - 1, 0)]), np.nan)
            # a = 0: multipliers are the free-vibration ones, |mu| = max exp(-zeta wn T) < 1.
            at_zero = k == 0
            if np.any(at_zero):
                f_lo[at_zero] = np.log(radius(np.zeros(at_zero.sum()), idx[act[at_zero]])[0])
            a_out[act], mu_out[act] = refine(idx[act], a_lo, f_lo, a_hi, f_hi)
        return a_out, mu_out

    nb = delay.size
    if scan_from_m is not None:
        start = np.broadcast_to(np.asarray(scan_from_m, float), (nb,))
        ok = np.isfinite(start) & (start > 0)
        k_start = np.where(ok, np.searchsorted(grid, np.where(ok, start, 0.0)) - 1, 0)
        return scan(np.arange(nb), np.clip(k_start, 0, grid.size - 1))
    stride0 = int(first_stride)
    if stride0 < 1:
        raise ValueError(f"first_stride must be >= 1, got {first_stride!r}")
    if not warm_start or nb < 2 * stride0 or stride0 == 1:
        return scan(np.arange(nb))
    # Warm start: every first_stride-th speed (in order of delay) is scanned from the bottom of
    # the range; no speed chatters below the lowest critical depth over all speeds, so the others
    # are scanned from just below the lowest limit of those (a speed unstable already there is
    # scanned again from lower down). Every speed is scanned at the same ratio, so an unstable
    # window below a stable pocket is found wherever it is wider than one scan step.
    order = np.argsort(delay, kind="stable")
    first_pass = order[np.unique(np.r_[np.arange(0, nb, stride0), nb - 1])]
    a_lim = np.full(nb, np.inf)
    mu_crit = np.full(nb, np.nan + 0j)
    a_lim[first_pass], mu_crit[first_pass] = scan(first_pass)
    rest = np.setdiff1d(np.arange(nb), first_pass)
    floor = np.min(a_lim[first_pass])
    k_floor = 0 if not np.isfinite(floor) else max(int(np.searchsorted(grid, floor)) - 2, 0)
    if rest.size:
        a_lim[rest], mu_crit[rest] = scan(rest, np.full(rest.size, k_floor))
    return a_lim, mu_crit


def sdm_lobes(
    modes_x: Sequence[ModalParameters],
    modes_y: Sequence[ModalParameters],
    tool: MillingTool,
    conditions: CuttingConditions,
    coefficients: CuttingCoefficients,
    spindle_rpm,
    *,
    steps_per_period: int = 40,
    steps_per_vibration: float = 12.0,
    max_steps: int = 200,
    depth_range_m: tuple[float, float] | None = None,
    n_scan: int | None = None,
    rtol: float = 1e-3,
    max_iter: int = 40,
    eigensolver: str = "arnoldi",
    warm_start: bool = True,
    scan_ratio: float = 1.2,
    first_stride: int = 8,
    scan_from_m=None,
) -> LobeEnvelope:
    """Stability envelope (critical axial depth at every speed) by semi-discretization.

    Parameters
    ----------
    modes_x, modes_y : sequence of ModalParameters
        Tool-tip modes in the feed (x) and normal (y) directions, any number each.
    tool : MillingTool
        ``n_flutes`` (tooth period) and ``diameter_m`` (immersion); the helix is ignored.
    conditions : CuttingConditions
        Radial depth and up/down milling (its speed and axial depth are not used).
    coefficients : CuttingCoefficients
        ``ktc``, ``krc`` [N/m²].
    spindle_rpm : array_like (n,)
        Speeds [rpm].
    steps_per_period : int
        Minimum steps across the cutting arc (40 is the usual choice; see the convergence test).
    steps_per_vibration, max_steps
        At low speeds the delay spans many periods of the modes: the cut is then resolved with
        at least ``steps_per_vibration`` steps per period of the highest mode, capped at
        ``max_steps`` (the state dimension grows with the steps).
    depth_range_m : (float, float), optional
        Depth scan [m]; default from the 1-DOF turning limit of the most flexible mode
        (``/10`` to ``x1000``). Speeds still stable at its top get ``inf``.
    n_scan : int, optional
        Geometric scan points over the whole range (default: ``scan_ratio`` between points).
    scan_ratio : float
        Ratio of neighbouring scan depths; the lowest unstable depth is found wherever the
        unstable window is wider than one step (:func:`critical_depths`).
    first_stride : int
        Speeds between two scans from the bottom of the range (``warm_start``).
    scan_from_m : array_like (n,), optional
        Depth [m] per speed where the scan starts (:func:`critical_depths`).
    rtol : float
        Relative tolerance on the critical depth.
    max_iter : int
        Bisection steps of the refinement at most.
    eigensolver : {"arnoldi", "dense"}
        Largest Floquet multiplier by Arnoldi iterations (default; residual-checked, dense
        fallback) or by every eigenvalue of the monodromy matrix (the slower reference).
    warm_start : bool
        Every ``first_stride``-th speed scanned from the bottom of the range, the others from
        just below the lowest limit found (:func:`critical_depths`); ``False`` scans every
        speed from the bottom (the reference).

    Returns
    -------
    LobeEnvelope
        ``a_lim_m`` (n,), the critical multiplier's kind (``hopf``/``flip``/``fold``) and the
        chatter frequency [Hz] at each speed.

    See ``docs/methods.md`` section 5.

    Examples
    --------
    >>> import numpy as np
    >>> from robovib.milling import ALUMINIUM_7075, CuttingConditions, MillingTool
    >>> from robovib.milling.sdm import sdm_lobes
    >>> from robovib.modal import ModalParameters
    >>> env = sdm_lobes([ModalParameters(30.0, 2e6, 0.05)], [], MillingTool(0.0254, 2),
    ...                 CuttingConditions(1750.0, 1e-4, 1e-3, 6e-3), ALUMINIUM_7075,
    ...                 np.linspace(1000, 3000, 5))
    >>> env.a_lim_m.shape
    (5,)
    """
    rpm = np.atleast_1d(np.asarray(spindle_rpm, float))
    if rpm.ndim != 1 or not (np.all(np.isfinite(rpm)) and np.all(rpm > 0)):
        raise ValueError("spindle_rpm must be a 1-D array of positive speeds [rpm]")
    modes = list(modes_x) + list(modes_y)
    if not modes:
        raise ValueError("at least one mode (x or y) is needed")
    phi_st, phi_ex = engagement_angles(tool, conditions)
    delay = 60.0 / (tool.n_flutes * rpm)
    # Steps across the cutting arc: at least steps_per_period, and enough to resolve the highest
    # mode (steps_per_vibration per its period) over the time in the cut; speeds are grouped by
    # their step count (multiples of 10) and each group is one batch.
    cut_fraction = min(1.0, (phi_ex - phi_st) / (2 * math.pi / tool.n_flutes))
    f_top = max(md.natural_frequency_hz for md in modes)
    need = np.ceil(steps_per_vibration * f_top * delay * cut_fraction / 10) * 10
    steps = np.clip(need, int(steps_per_period), max(int(steps_per_period), int(max_steps)))
    a_lim = np.full(rpm.size, np.inf)
    mu_crit = np.full(rpm.size, np.nan + 0j)
    for m in np.unique(steps, return_inverse=True)[0]:  # plain unique imports numpy.ma
        idx = np.flatnonzero(steps == m)
        hmat, frac = milling_force_matrices(tool.n_flutes, phi_st, phi_ex, coefficients, int(m))
        a_lim[idx], mu_crit[idx] = critical_depths(
            modes_x, modes_y, hmat, frac, delay[idx], depth_range_m=depth_range_m,
            n_scan=n_scan, rtol=rtol, max_iter=max_iter, eigensolver=eigensolver,
            warm_start=warm_start, scan_ratio=scan_ratio, first_stride=first_stride,
            scan_from_m=None if scan_from_m is None else np.broadcast_to(
                np.asarray(scan_from_m, float), rpm.shape)[idx],
        )  # fmt: skip
    nb = rpm.size
    active = np.flatnonzero(np.isfinite(a_lim))
    kind = np.full(nb, "none", dtype=object)
    chatter = np.full(nb, np.nan)
    if active.size:
        kk, fc = _classify(mu_crit[active], delay[active], modes)
        kind[active] = kk
        chatter[active] = fc
    return LobeEnvelope(
        spindle_rpm=rpm,
        a_lim_m=a_lim,
        chatter_hz=chatter,
        kind=kind.astype(str),
        method="sdm",
        settings=_envelope_settings(
            tool,
            conditions,
            coefficients,
            steps_per_period=steps_per_period,
            steps_per_vibration=steps_per_vibration,
            rtol=rtol,
            eigensolver=eigensolver,
            warm_start=warm_start,
            scan_ratio=float(scan_ratio) if n_scan is None else None,
        ),
    )


def _envelope_settings(
    tool: MillingTool,
    conditions: CuttingConditions,
    coefficients: CuttingCoefficients,
    *,
    steps_per_period: int,
    steps_per_vibration: float,
    rtol: float,
    eigensolver: str,
    warm_start: bool,
    scan_ratio: float | None,
    solver: str | None = None,
) -> dict:
    """The ``settings`` of an SDM :class:`~robovib.milling.envelope.LobeEnvelope`.

    One place for the keys (and their order, which JSON outputs keep) of :func:`sdm_lobes` and
    of the compiled kernel's envelopes (:func:`robovib.milling.sdm_kernel.sdm_envelopes`, which
    adds ``solver="compiled"``); lengths in m, cutting coefficients in N/m².
    """
    settings = {
        "steps_per_period_min": int(steps_per_period),
        "steps_per_vibration": float(steps_per_vibration),
        "n_flutes": int(tool.n_flutes),
        "radial_depth_m": conditions.radial_depth_m,
        "diameter_m": tool.diameter_m,
        "down_milling": bool(conditions.down_milling),
        "ktc_n_per_m2": coefficients.ktc,
        "krc_n_per_m2": coefficients.krc,
        "helix": "ignored",
        "rtol": rtol,
        "eigensolver": eigensolver,
    }
    if solver is not None:
        settings["solver"] = solver
    settings["warm_start"] = bool(warm_start)
    settings["scan_ratio"] = scan_ratio
    return settings
