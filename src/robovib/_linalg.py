"""Small dense linear algebra in NumPy alone: the matrix exponential and the discrete Riccati
equation.

SciPy's :mod:`scipy.linalg` costs ~0.2-0.3 s to import (its array-API layer), more than a
command at one pose spends computing: ``robovib control gains`` and the stability charts use
these instead (tested against :func:`scipy.linalg.expm` and
:func:`scipy.linalg.solve_discrete_are`).
"""

from __future__ import annotations

import numpy as np

__all__ = ["batched_expm", "solve_dare"]

_PADE13 = (
    64764752532480000.0, 32382376266240000.0, 7771770303897600.0, 1187353796428800.0,
    129060195264000.0, 10559470521600.0, 670442572800.0, 33522128640.0, 1323241920.0,
    40840800.0, 960960.0, 16380.0, 182.0, 1.0,
)  # fmt: skip


_PADE9 = (
    17643225600.0, 8821612800.0, 2075673600.0, 302702400.0, 30270240.0, 2162160.0, 110880.0,
    3960.0, 90.0, 1.0,
)  # fmt: skip
#: Largest 1-norm for which the degree-9 Padé approximant is accurate to unit roundoff (Higham).
_THETA9 = 2.097847961257068


def _pade9(a: np.ndarray) -> np.ndarray:
    """Degree-9 Padé approximant of ``exp`` for matrices of 1-norm <= ``_THETA9``."""
    b = _PADE9
    eye = np.broadcast_to(np.eye(a.shape[-1]), a.shape)
    a2 = a @ a
    a4 = a2 @ a2
    a6 = a4 @ a2
    a8 = a6 @ a2
    u = a @ (b[9] * a8 + b[7] * a6 + b[5] * a4 + b[3] * a2 + b[1] * eye)
    v = b[8] * a8 + b[6] * a6 + b[4] * a4 + b[2] * a2 + b[0] * eye
    return np.linalg.solve(v - u, v + u)


def batched_expm(a: np.ndarray) -> np.ndarray:
    """``exp(A)`` for a stack of square matrices (..., s, s), vectorised over the stack.

    Scaling and squaring with the degree-13 Padé approximant (Higham, *SIAM J. Matrix Anal.
    Appl.* 26, 2005), the degree-9 one unscaled for matrices of 1-norm <= 2.098: each matrix is scaled by ``2^-s`` so its 1-norm is <= 5.37, the Padé
    approximant is one batched linear solve, then squared ``s`` times (``s`` per matrix). SciPy's
    ``expm`` gives the same numbers but loops over the stack in Python.

    Parameters
    ----------
    a : numpy.ndarray (..., s, s)
        The stack of matrices.

    Returns
    -------
    numpy.ndarray (..., s, s)
        ``exp`` of each matrix.
    """
    a = np.asarray(a, float)
    if a.ndim < 2 or a.shape[-1] != a.shape[-2]:
        raise ValueError(f"expected a stack of square matrices (..., s, s), got {a.shape}")
    norm = np.max(np.sum(np.abs(a), axis=-2), axis=-1)
    small = norm <= _THETA9
    if a.ndim >= 3 and np.any(small) and not np.all(small):
        out = np.empty_like(a)
        out[small] = _pade9(a[small])
        out[~small] = batched_expm(a[~small])
        return out
    if np.all(small):  # degree 9 is exact to rounding there: one product fewer, no squaring
        return _pade9(a)
    s = np.maximum(0, np.ceil(np.log2(np.maximum(norm, 1e-300) / 5.371920351148152))).astype(int)
    a = a / (2.0**s)[..., None, None]
    b = _PADE13
    eye = np.broadcast_to(np.eye(a.shape[-1]), a.shape)
    a2 = a @ a
    a4 = a2 @ a2
    a6 = a4 @ a2
    u = a @ (a6 @ (b[13] * a6 + b[11] * a4 + b[9] * a2) + b[7] * a6 + b[5] * a4 + b[3] * a2
             + b[1] * eye)  # fmt: skip
    v = a6 @ (b[12] * a6 + b[10] * a4 + b[8] * a2) + b[6] * a6 + b[4] * a4 + b[2] * a2 + b[0] * eye
    r = np.linalg.solve(v - u, v + u)
    for k in range(int(s.max(initial=0))):
        sq = (s > k)[..., None, None]
        r = np.where(sq, r @ r, r)
    return r


def solve_dare(a, b, q, r, *, rtol: float = 1e-14, max_iter: int = 100) -> np.ndarray:
    """Stabilising solution ``X`` of ``X = A'XA - A'XB (R + B'XB)^-1 B'XA + Q``.

    The structure-preserving doubling algorithm (Chu, Fan & Lin, *Linear Algebra Appl.* 396,
    2005): ``A_0 = A``, ``G_0 = B R^-1 B'``, ``H_0 = Q`` and, with ``W = I + G_k H_k``::

        A_{k+1} = A_k W^-1 A_k,   G_{k+1} = G_k + A_k W^-1 G_k A_k',
        H_{k+1} = H_k + A_k' H_k W^-1 A_k  ->  X

    converges quadratically (the error falls like the closed-loop spectral radius to the power
    ``2^k``) and needs no invertible ``A`` (a delay line has none). Where it does not converge in
    ``max_iter`` doublings, :func:`scipy.linalg.solve_discrete_are` answers instead.

    Parameters
    ----------
    a : array_like (n, n)
    b : array_like (n, m)
    q : array_like (n, n)
        Symmetric positive semi-definite.
    r : array_like (m, m)
        Symmetric positive definite.
    rtol, max_iter
        Relative change of ``H_k`` accepted as converged; doublings at most.

    Returns
    -------
    ndarray (n, n)
        Symmetric ``X``.
    """
    a = np.asarray(a, float)
    b = np.asarray(b, float)
    q = np.asarray(q, float)
    r = np.asarray(r, float)
    n = a.shape[0]
    ak, gk, hk = a, b @ np.linalg.solve(r, b.T), q
    gk = 0.5 * (gk + gk.T)
    eye = np.eye(n)
    for _ in range(int(max_iter)):
        w = eye + gk @ hk
        w_a = np.linalg.solve(w, ak)  # W^-1 A_k
        w_g = np.linalg.solve(w, gk)  # W^-1 G_k
        h_next = hk + ak.T @ hk @ w_a
        gk = gk + ak @ w_g @ ak.T
        gk = 0.5 * (gk + gk.T)
        ak = ak @ w_a
        h_next = 0.5 * (h_next + h_next.T)
        if not np.all(np.isfinite(h_next)):
            break
        done = np.max(np.abs(h_next - hk)) <= rtol * max(np.max(np.abs(h_next)), 1e-300)
        hk = h_next
        if done:
            return hk
    from scipy import linalg

    return linalg.solve_discrete_are(a, b, q, r)
