"""Compiled semi-discretization: the critical depth of many structures x speeds, one pair a loop.

The same first-order semi-discretization as :mod:`robovib.milling.sdm` (same steps, same
step-averaged force matrices, same depth grid and refinement, the same nonzero Floquet
multipliers), evaluated pair by pair (one structure at one speed) in a loop compiled by numba,
so that neither NumPy's batch bookkeeping nor a dense monodromy matrix is paid for:

* the step matrices ``E = exp(A h)``, ``R = int exp(A (h - s)) ds D`` and ``S = int exp(A (h -
  s)) s/h ds D`` come from ``phi``-functions, ``E = I + X phi_1(X)``, ``phi_1 = I + X phi_2``,
  with ``phi_2(X) = sum X^j / (j + 2)!`` summed by Horner's rule on ``X = A h / 2^s`` (1-norm
  <= 1/2, the series cut where its terms fall below 1e-14) and doubled back ``s`` times by
  ``E(2X) = E^2``, ``R(2X) = E R + R``, ``S(2X) = (E S + R + S) / 2`` (two half steps of the
  linearly interpolated delayed input); velocities are scaled by each mode's ``wn`` (the
  balancing of :func:`~robovib.milling.sdm._monodromy`), and products use the block structure
  ``X = [[0, diag], [Q, diag]]``;
* the delayed state holds only the x and y displacements (the regenerative force sees the
  modes only through them), ``d + 2 (m + 1)`` instead of ``d + n (m + 1)`` unknowns: the
  monodromy matrix ``C A`` of the reduced state and ``A C`` of the modal one have the same
  nonzero eigenvalues;
* the largest Floquet multiplier is found by Arnoldi iterations on the monodromy operator
  applied step by step (one period's march of the state), the Ritz values by the Francis
  double-shift QR of the small Hessenberg matrix (:func:`hessenberg_eigenvalues`), each checked
  by its residual (``1e-8`` of its modulus); within one pair's depth search the next Arnoldi
  run starts from the last dominant Ritz vector with half the subspace, then from the generic
  vector, then with twice the subspace, then the dense matrix and LAPACK;
* the depth search is that of :func:`~robovib.milling.sdm.critical_depths` per pair: a scan
  upwards on the same ``geomspace`` grid from a start depth (a pair already unstable at its
  start is scanned again from six grid steps lower), then Illinois iterations (secant in
  ``log`` depth) on ``log |mu|`` between the last stable and the first unstable depth, ended
  when the bracket is below ``rtol`` or the linearised step below ``rtol / 4``.

numba is imported by this module only, which the P(stable) code imports inside its functions;
the NumPy path of :mod:`.sdm` stays the reference and the tests compare the two
(``tests/milling/test_sdm_kernel.py``). Cost (one core): about 40 us per evaluation for a
2-DOF structure at 40 steps (about 180 us for 5 modes), ~7-8 evaluations per (sample, speed)
with the warm start of :func:`~robovib.milling.uncertainty.stability_probability`.
"""

from __future__ import annotations

import math

import numpy as np

try:
    import numba
except ImportError:  # numba is a dependency; a broken install falls back to the NumPy path
    numba = None

#: Whether the kernel runs compiled: without numba, or under ``NUMBA_DISABLE_JIT=1``, the loops
#: below would run interpreted by Python (hours for a chart), so ``stability_probability`` takes
#: the NumPy path of :mod:`.sdm` instead.
AVAILABLE = numba is not None and not numba.config.DISABLE_JIT


def jit(function):
    """``function`` compiled by numba, its machine code cached on disk where it can be.

    The cache lives next to this file, else in the user's cache folder; where neither is
    writable (a read-only install, no home folder) numba refuses ``cache=True`` with a
    ``RuntimeError`` at decoration, and the function is compiled in every process instead
    (about 10 s at first use). Without numba the function is returned as is (never called:
    see :data:`AVAILABLE`).
    """
    if numba is None:
        return function
    try:
        return numba.njit(cache=True, nogil=True)(function)
    except RuntimeError:  # "cannot cache function ...: no locator available"
        return numba.njit(nogil=True)(function)


__all__ = ["critical_depths_pairs"]


@jit
def hessenberg_eigenvalues(a, n, wr, wi):
    """Eigenvalues of the upper Hessenberg ``a[:n, :n]`` (overwritten) by Francis double-shift QR.

    The ``hqr`` algorithm (Wilkinson & Reinsch, *Handbook for Automatic Computation* II, 1971);
    returns False where 30 iterations do not split off an eigenvalue.
    """
    anorm = 0.0
    for i in range(n):
        for j in range(max(i - 1, 0), n):
            anorm += abs(a[i, j])
    nn = n - 1
    t = 0.0
    x = y = z = w = p = q = r = 0.0
    while nn >= 0:
        its = 0
        while True:
            ll = nn
            while ll >= 1:
                s = abs(a[ll - 1, ll - 1]) + abs(a[ll, ll])
                if s == 0.0:
                    s = anorm
                if abs(a[ll, ll - 1]) + s == s:
                    a[ll, ll - 1] = 0.0
                    break
                ll -= 1
            x = a[nn, nn]
            if ll == nn:
                wr[nn] = x + t
                wi[nn] = 0.0
                nn -= 1
                break
            y = a[nn - 1, nn - 1]
            w = a[nn, nn - 1] * a[nn - 1, nn]
            if ll == nn - 1:
                p = 0.5 * (y - x)
                q = p * p + w
                z = math.sqrt(abs(q))
                x += t
                if q >= 0.0:
                    z = p + math.copysign(z, p)
                    wr[nn - 1] = x + z
                    wr[nn] = x + z
                    if z != 0.0:
                        wr[nn] = x - w / z
                    wi[nn - 1] = 0.0
                    wi[nn] = 0.0
                else:
                    wr[nn - 1] = x + p
                    wr[nn] = x + p
                    wi[nn - 1] = -z
                    wi[nn] = z
                nn -= 2
                break
            if its == 30:
                return False
            if its == 10 or its == 20:
                t += x
                for i in range(nn + 1):
                    a[i, i] -= x
                s = abs(a[nn, nn - 1]) + abs(a[nn - 1, nn - 2])
                x = 0.75 * s
                y = x
                w = -0.4375 * s * s
            its += 1
            m = nn - 2
            while m >= ll:
                z = a[m, m]
                r = x - z
                s = y - z
                p = (r * s - w) / a[m + 1, m] + a[m, m + 1]
                q = a[m + 1, m + 1] - z - r - s
                r = a[m + 2, m + 1]
                s = abs(p) + abs(q) + abs(r)
                p /= s
                q /= s
                r /= s
                if m == ll:
                    break
                u = abs(a[m, m - 1]) * (abs(q) + abs(r))
                v = abs(p) * (abs(a[m - 1, m - 1]) + abs(z) + abs(a[m + 1, m + 1]))
                if u + v == v:
                    break
                m -= 1
            for i in range(m + 2, nn + 1):
                a[i, i - 2] = 0.0
                if i != m + 2:
                    a[i, i - 3] = 0.0
            for k in range(m, nn):
                if k != m:
                    p = a[k, k - 1]
                    q = a[k + 1, k - 1]
                    r = 0.0
                    if k != nn - 1:
                        r = a[k + 2, k - 1]
                    x = abs(p) + abs(q) + abs(r)
                    if x != 0.0:
                        p /= x
                        q /= x
                        r /= x
                s = math.copysign(math.sqrt(p * p + q * q + r * r), p)
                if s != 0.0:
                    if k == m:
                        if ll != m:
                            a[k, k - 1] = -a[k, k - 1]
                    else:
                        a[k, k - 1] = -s * x
                    p += s
                    x = p / s
                    y = q / s
                    z = r / s
                    q /= p
                    r /= p
                    for j in range(k, nn + 1):
                        p = a[k, j] + q * a[k + 1, j]
                        if k != nn - 1:
                            p += r * a[k + 2, j]
                            a[k + 2, j] -= p * z
                        a[k + 1, j] -= p * y
                        a[k, j] -= p * x
                    mmin = nn if nn < k + 3 else k + 3
                    for i in range(ll, mmin + 1):
                        p = x * a[i, k] + y * a[i, k + 1]
                        if k != nn - 1:
                            p += z * a[i, k + 2]
                            a[i, k + 2] -= p * r
                        a[i, k + 1] -= p * q
                        a[i, k] -= p
            if ll >= nn - 1:
                break
    return True


@jit
def ritz_residual_factor(hess, k, theta, s):
    """``|e_k^T s|`` of the unit eigenvector ``s`` (k,) complex of ``hess[:k, :k]`` for ``theta``.

    Two steps of inverse iteration with a slightly perturbed shift (complex Gaussian
    elimination with partial pivoting on the small Hessenberg matrix).
    """
    shift = theta * (1.0 + 1e-12) + 1e-300
    mat = np.empty((k, k), np.complex128)
    s[:k] = 1.0
    for _ in range(2):
        for i in range(k):
            for j in range(k):
                mat[i, j] = hess[i, j]
            mat[i, i] -= shift
        for c in range(k):
            piv = c
            for i in range(c + 1, k):
                if abs(mat[i, c]) > abs(mat[piv, c]):
                    piv = i
            if piv != c:
                for j in range(k):
                    tmp = mat[c, j]
                    mat[c, j] = mat[piv, j]
                    mat[piv, j] = tmp
                tmp = s[c]
                s[c] = s[piv]
                s[piv] = tmp
            if mat[c, c] == 0:
                mat[c, c] = 1e-300
            for i in range(c + 1, k):
                f = mat[i, c] / mat[c, c]
                if f != 0:
                    for j in range(c, k):
                        mat[i, j] -= f * mat[c, j]
                    s[i] -= f * s[c]
        for i in range(k - 1, -1, -1):
            acc = s[i]
            for j in range(i + 1, k):
                acc -= mat[i, j] * s[j]
            s[i] = acc / mat[i, i]
        nrm = 0.0
        for i in range(k):
            nrm += abs(s[i]) ** 2
        nrm = math.sqrt(nrm)
        for i in range(k):
            s[i] /= nrm
    return abs(s[k - 1])


@jit
def _xmul(wq, zq, q, p, out, n):
    """out = X p for X = [[0, diag(wq)], [q, diag(zq)]] (the balanced step matrix), d x d."""
    d = 2 * n
    for r in range(n):
        for c in range(d):
            out[r, c] = wq[r] * p[n + r, c]
    for r in range(n):
        for c in range(d):
            acc = zq[r] * p[n + r, c]
            for k in range(n):
                acc += q[r, k] * p[k, c]
            out[n + r, c] = acc


@jit
def step_matrices(wq, zq, q, h, n, e_out, r_out, s_out, work):
    """E, R~ = h phi_1(A h), S~ = h phi_2(A h) (d x d) of one step, in place.

    ``A = [[0, diag(wq)], [q, diag(zq)]]`` (velocities scaled by ``wn``); ``X = A h / 2^s``
    with 1-norm <= 1/2, ``phi_2(X)`` by Horner's rule, doubled back ``s`` times.
    """
    d = 2 * n
    nrm = 0.0
    for c in range(n):
        col = 0.0
        for r in range(n):
            col += abs(q[r, c])
        nrm = max(nrm, col)
    for r in range(n):
        nrm = max(nrm, abs(wq[r]) + abs(zq[r]))
    nrm *= h
    s = 0
    while nrm > 0.5 and s < 60:
        nrm *= 0.5
        s += 1
    hs = h / 2.0**s
    wx = work[3, 0, :n]
    zx = work[3, 1, :n]
    qx = work[4]
    for r in range(n):
        wx[r] = wq[r] * hs
        zx[r] = zq[r] * hs
        for c in range(n):
            qx[r, c] = q[r, c] * hs
    p = work[1]
    t = work[2]
    # Terms of phi_2: ||X||^j / (j + 2)!; the series is cut below 1e-14 (the depth search
    # needs log|mu| to ~1e-6; the tests hold E, R, S to 1e-11 of SciPy's expm).
    k = 0
    term = 0.5
    while term > 1e-14 and k < 40:
        k += 1
        term *= nrm / (k + 2)
    fact = 1.0
    for j in range(2, k + 3):
        fact *= j
    for r in range(d):
        for c in range(d):
            p[r, c] = 0.0
        p[r, r] = 1.0 / fact
    for j in range(k - 1, -1, -1):
        fact /= j + 3
        _xmul(wx, zx, qx, p, t, n)
        for r in range(d):
            for c in range(d):
                p[r, c] = t[r, c]
            p[r, r] += 1.0 / fact
    # phi_1 = I + X phi_2 (into t), E = I + X phi_1; R~ = hs phi_1, S~ = hs phi_2.
    _xmul(wx, zx, qx, p, t, n)
    for r in range(d):
        t[r, r] += 1.0
    _xmul(wx, zx, qx, t, e_out, n)
    for r in range(d):
        e_out[r, r] += 1.0
    for r in range(d):
        for c in range(d):
            r_out[r, c] = hs * t[r, c]
            s_out[r, c] = hs * p[r, c]
    x = work[0]
    # Double back: two half steps of the linearly interpolated delayed input.
    for _ in range(s):
        for r in range(d):
            for c in range(d):
                acc_r = 0.0
                acc_s = 0.0
                acc_e = 0.0
                for m in range(d):
                    acc_r += e_out[r, m] * r_out[m, c]
                    acc_s += e_out[r, m] * s_out[m, c]
                    acc_e += e_out[r, m] * e_out[m, c]
                x[r, c] = acc_r + r_out[r, c]
                p[r, c] = 0.5 * (acc_s + r_out[r, c] + s_out[r, c])
                t[r, c] = acc_e
        for r in range(d):
            for c in range(d):
                r_out[r, c] = x[r, c]
                s_out[r, c] = p[r, c]
                e_out[r, c] = t[r, c]


@jit
def build_steps(wn, zeta, inv_mass, nx, hmat, h_steps, cutting, depth, e_all, p_all, s_all, work):
    """Step matrices of every step at one depth (balanced coordinates, delayed input in x, y).

    Mode ``r`` (direction ``dir(r)``: x for ``r < nx``) obeys ``xi_r'' = -wn_r^2 xi_r - 2 zeta_r
    wn_r xi_r' - depth / m_r sum_c H[dir r, dir c] xi_c + depth / m_r (H r(t - tau))_dir r``.
    """
    n = wn.size
    d = 2 * n
    n_steps = h_steps.size
    wq = work[5, 0, :n]
    zq = work[5, 1, :n]
    q = work[6]
    rt = work[7]
    st = work[8]
    for r in range(n):
        wq[r] = wn[r]
        zq[r] = -2.0 * zeta[r] * wn[r]
    for i in range(n_steps):
        for r in range(n):
            dr = 0 if r < nx else 1
            g = depth * inv_mass[r] / wn[r]
            for c in range(n):
                dc = 0 if c < nx else 1
                q[r, c] = -g * hmat[i, dr, dc] if cutting[i] else 0.0
            q[r, r] -= wn[r]
        step_matrices(wq, zq, q, h_steps[i], n, e_all[i], rt, st, work)
        if cutting[i]:
            # D = [0; depth H[dir r, :] / (m_r wn_r)] (d x 2): R = R~ D, S = S~ D.
            for r in range(d):
                for c in range(2):
                    acc_r = 0.0
                    acc_s = 0.0
                    for m in range(n):
                        dm = 0 if m < nx else 1
                        dv = depth * inv_mass[m] / wn[m] * hmat[i, dm, c]
                        acc_r += rt[r, n + m] * dv
                        acc_s += st[r, n + m] * dv
                    p_all[i, r, c] = acc_r - acc_s
                    s_all[i, r, c] = acc_s


@jit
def matvec(z, out, e_all, p_all, s_all, cutting, n, nx, n_cut, full, y, ynew):
    """Monodromy operator on z = [y_0, r_{-M} ... r_{-M+m}] (r = (x, y) displacement).

    In the ``full`` case (the cut spans the whole period) the last delayed point is ``r_0``,
    read from ``y_0``.
    """
    d = 2 * n
    n_steps = cutting.size
    for r in range(d):
        y[r] = z[r]
    rx = 0.0
    ry = 0.0
    for r in range(n):
        if r < nx:
            rx += z[r]
        else:
            ry += z[r]
    out[d] = rx
    out[d + 1] = ry
    for i in range(n_steps):
        for r in range(d):
            acc = 0.0
            for c in range(d):
                acc += e_all[i, r, c] * y[c]
            ynew[r] = acc
        if cutting[i]:
            q0 = d + 2 * i
            if full and i + 1 == n_cut:
                r1x, r1y = 0.0, 0.0
                for r in range(n):
                    if r < nx:
                        r1x += z[r]
                    else:
                        r1y += z[r]
            else:
                r1x, r1y = z[q0 + 2], z[q0 + 3]
            for r in range(d):
                ynew[r] += (p_all[i, r, 0] * z[q0] + p_all[i, r, 1] * z[q0 + 1]
                            + s_all[i, r, 0] * r1x + s_all[i, r, 1] * r1y)  # fmt: skip
        for r in range(d):
            y[r] = ynew[r]
        if i + 1 <= n_cut and not (full and i + 1 == n_cut):
            rx = 0.0
            ry = 0.0
            for r in range(n):
                if r < nx:
                    rx += y[r]
                else:
                    ry += y[r]
            out[d + 2 * (i + 1)] = rx
            out[d + 2 * (i + 1) + 1] = ry
    for r in range(d):
        out[r] = y[r]


@jit
def dominant(e_all, p_all, s_all, cutting, n, nx, n_cut, full, kdim, q, hess, y, ynew, w, v0,
             warm):  # fmt: skip
    """Largest-modulus multiplier by Arnoldi; returns (mu, converged).

    From ``v0`` where ``warm`` (the dominant Ritz vector of the previous depth of the same
    pair), else from a fixed generic vector; on convergence ``v0`` takes the new Ritz vector
    (real plus imaginary part: the start of a Krylov space holding the complex pair).
    """
    dim = q.shape[1]
    k = min(kdim, dim)
    for r in range(dim):
        q[0, r] = v0[r] if warm else math.cos(0.7 * r + 0.3) + 0.5
    nrm = 0.0
    for r in range(dim):
        nrm += q[0, r] ** 2
    nrm = math.sqrt(nrm)
    for r in range(dim):
        q[0, r] /= nrm
    hess[:, :] = 0.0
    kk = k
    for j in range(k):
        matvec(q[j], w, e_all, p_all, s_all, cutting, n, nx, n_cut, full, y, ynew)
        for _ in range(2):  # classical Gram-Schmidt, twice
            for i in range(j + 1):
                c = 0.0
                for r in range(dim):
                    c += q[i, r] * w[r]
                hess[i, j] += c
                for r in range(dim):
                    w[r] -= c * q[i, r]
        beta = 0.0
        for r in range(dim):
            beta += w[r] ** 2
        beta = math.sqrt(beta)
        hess[j + 1, j] = beta
        if beta <= 1e-300:
            kk = j + 1
            break
        for r in range(dim):
            q[j + 1, r] = w[r] / beta
    hk = np.empty((kk, kk))
    for r in range(kk):
        for c in range(kk):
            hk[r, c] = hess[r, c]
    wr = np.empty(kk)
    wi = np.empty(kk)
    if hessenberg_eigenvalues(hk, kk, wr, wi):
        best = 0
        for i in range(kk):
            if wr[i] ** 2 + wi[i] ** 2 > wr[best] ** 2 + wi[best] ** 2:
                best = i
        mu = complex(wr[best], wi[best])
        svec = np.empty(kk, np.complex128)
        resid = abs(hess[kk, kk - 1]) * ritz_residual_factor(hess, kk, mu, svec)
        if kk < k or resid <= 1e-8 * max(abs(mu), 1e-3):
            for r in range(dim):
                acc = 0.0
                for i in range(kk):
                    acc += svec[i].real * q[i, r] + 0.618 * svec[i].imag * q[i, r]
                v0[r] = acc
            return mu, True
    return complex(math.nan, math.nan), False


@jit
def dense_dominant(e_all, p_all, s_all, cutting, n, nx, n_cut, full, dim, y, ynew):
    """Largest-modulus multiplier of the monodromy matrix built column by column (LAPACK)."""
    phi = np.empty((dim, dim), np.complex128)
    unit = np.zeros(dim)
    col = np.empty(dim)
    for c in range(dim):
        unit[:] = 0.0
        unit[c] = 1.0
        matvec(unit, col, e_all, p_all, s_all, cutting, n, nx, n_cut, full, y, ynew)
        for r in range(dim):
            phi[r, c] = col[r]
    vals = np.linalg.eigvals(phi)
    best = 0
    for i in range(dim):
        if abs(vals[i]) > abs(vals[best]):
            best = i
    return vals[best]


@jit
def radius(a, wn, zeta, inv_mass, nx, hmat, hs, cutting, n_cut, full, kdim, bufs, counts):
    """Largest multiplier at depth ``a``; counts[0] += 1 evaluation, counts[1] += 1 if dense."""
    e_all, p_all, s_all, work, q, hess, y, ynew, w, v0 = bufs
    n = wn.size
    build_steps(wn, zeta, inv_mass, nx, hmat, hs, cutting, a, e_all, p_all, s_all, work)
    counts[0] += 1
    kmax = hess.shape[1]
    if counts[2] > 0:  # a Ritz vector of this pair: a short Krylov space from it first
        mu, ok = dominant(e_all, p_all, s_all, cutting, n, nx, n_cut, full,
                          max(counts[3] // 2, 4), q, hess, y, ynew, w, v0, True)  # fmt: skip
        if ok:
            return mu
    kk = max(counts[3], kdim)  # the subspace that converged last for this pair
    while True:
        mu, ok = dominant(e_all, p_all, s_all, cutting, n, nx, n_cut, full, kk, q, hess, y,
                          ynew, w, v0, False)  # fmt: skip
        if ok:
            counts[2] = 1
            counts[3] = kk
            return mu
        if 2 * kk > kmax:
            break
        kk *= 2
    counts[1] += 1
    counts[2] = 0
    return dense_dominant(e_all, p_all, s_all, cutting, n, nx, n_cut, full, q.shape[1], y, ynew)


@jit
def search(wn_all, zeta_all, inv_mass_all, nx, hmat, h_all, cutting, n_cut, full, start,
           lo_all, hi_all, scan_ratio, rtol, max_iter, kdim, a_out, mu_out, n_eval,
           n_dense, log_secant=True):  # fmt: skip
    """Lowest unstable depth of every pair p (structure wn_all[p], steps h_all[p])."""
    n_pairs, n = wn_all.shape
    d = 2 * n
    n_steps = cutting.size
    dim = d + 2 * (n_cut + 1) - (2 if full else 0)
    e_all = np.zeros((n_steps, d, d))
    p_all = np.zeros((n_steps, d, 2))
    s_all = np.zeros((n_steps, d, 2))
    work = np.zeros((9, d, d))
    kmax = min(4 * kdim, dim)
    q = np.zeros((kmax + 1, dim))
    hess = np.zeros((kmax + 1, kmax))
    y = np.zeros(d)
    ynew = np.zeros(d)
    w = np.zeros(dim)
    v0 = np.zeros(dim)
    bufs = (e_all, p_all, s_all, work, q, hess, y, ynew, w, v0)
    counts = np.zeros(4, np.int64)  # evaluations, dense ones, Ritz vector held, last k
    log_ratio = math.log(scan_ratio)
    for pi in range(n_pairs):
        counts[:] = 0
        lo = lo_all[pi]
        n_grid = max(math.ceil(math.log(hi_all[pi] / lo) / log_ratio) + 1, 2)
        # The grid of critical_depths: geomspace(lo, hi, n_grid), a ratio a little below
        # scan_ratio (the same depths, so the same unstable windows are met).
        step_log = math.log(hi_all[pi] / lo) / (n_grid - 1)
        wn = wn_all[pi]
        zeta = zeta_all[pi]
        inv_mass = inv_mass_all[pi]
        hs = h_all[pi]

        # Scan grid: lo * ratio^k; first index at or below the start.
        k0 = 0
        if start[pi] > lo and np.isfinite(start[pi]):
            k0 = math.floor(math.log(start[pi] / lo) / step_log * (1 - 1e-12))
            k0 = min(max(k0, 0), n_grid - 1)
        a_lo = 0.0
        f_lo = 0.0
        have_lo = False
        a_hi = math.inf
        f_hi = 0.0
        mu_hi = complex(math.nan, math.nan)
        k = k0
        found = False
        while True:
            found = False
            first = k
            while k < n_grid:
                a = lo * math.exp(k * step_log)
                mu = radius(
                    a, wn, zeta, inv_mass, nx, hmat, hs, cutting, n_cut, full, kdim, bufs, counts
                )
                f = math.log(abs(mu))
                if f >= 0:
                    a_hi, f_hi, mu_hi = a, f, mu
                    found = True
                    break
                a_lo, f_lo, have_lo = a, f, True
                k += 1
            if found and k == first and first > 0:
                # Unstable at the scan's first depth: again from scan_ratio^6 lower.
                k = max(first - 6, 0)
                have_lo = False
                continue
            break
        n_eval[pi] = counts[0]
        n_dense[pi] = counts[1]
        if not found:
            a_out[pi] = math.inf
            mu_out[pi] = complex(math.nan, math.nan)
            continue
        if not have_lo:
            a_lo = 0.0
            mu0 = radius(
                0.0, wn, zeta, inv_mass, nx, hmat, hs, cutting, n_cut, full, kdim, bufs, counts
            )
            f_lo = math.log(abs(mu0))
        # Illinois on log|mu| over [a_lo, a_hi].
        g_lo, g_hi = f_lo, f_hi
        side = 0
        for _ in range(max_iter):
            if a_hi - a_lo <= rtol * a_hi:
                break
            denom = f_hi - f_lo
            if denom > 0 and a_lo > 0 and log_secant:
                # log|mu| is close to linear in log(depth) near the root: secant in log a
                a_new = a_hi * math.exp(-f_hi * math.log(a_hi / a_lo) / denom)
            elif denom > 0:
                a_new = a_hi - f_hi * (a_hi - a_lo) / denom
            else:
                a_new = 0.5 * (a_lo + a_hi)
            if not (a_lo < a_new < a_hi):
                a_new = 0.5 * (a_lo + a_hi)
            mu = radius(
                a_new, wn, zeta, inv_mass, nx, hmat, hs, cutting, n_cut, full, kdim, bufs, counts
            )
            f_new = math.log(abs(mu))
            up = f_new >= 0
            if up:
                g_hi = f_new
            else:
                g_lo = f_new
            if a_lo > 0:
                slope = (g_hi - g_lo) / math.log(a_hi / a_lo)
                if slope > 0:
                    step = -f_new / slope
                    if abs(step) < 0.25 * rtol:
                        a_root = a_new * math.exp(step)
                        a_lo, a_hi, mu_hi = a_root, a_root, mu
                        break
            if up and side == 1:
                f_lo *= 0.5
            if (not up) and side == -1:
                f_hi *= 0.5
            if up:
                a_hi, f_hi, mu_hi, side = a_new, f_new, mu, 1
            else:
                a_lo, f_lo, side = a_new, f_new, -1
        a_out[pi] = 0.5 * (a_lo + a_hi)
        mu_out[pi] = mu_hi
        n_eval[pi] = counts[0]
        n_dense[pi] = counts[1]


def critical_depths_pairs(
    wn_rad_s: np.ndarray,
    zeta: np.ndarray,
    mass_kg: np.ndarray,
    n_feed_modes: int,
    h_n_per_m2: np.ndarray,
    step_s: np.ndarray,
    start_m: np.ndarray,
    depth_range_m: tuple,
    *,
    scan_ratio: float = 1.2,
    rtol: float = 1e-3,
    max_iter: int = 40,
    krylov_dim: int | None = None,
) -> tuple[np.ndarray, np.ndarray, dict]:
    """Lowest unstable depth [m] of every (structure, speed) pair with one step layout.

    Parameters
    ----------
    wn_rad_s, zeta, mass_kg : ndarray (p, n)
        Natural frequencies [rad/s], damping ratios and modal masses [kg] of the ``n`` modes of
        each pair, the ``n_feed_modes`` x (feed) modes first.
    n_feed_modes : int
        Number of x modes.
    h_n_per_m2 : ndarray (n_steps, 2, 2)
        Step-averaged specific force matrices (:func:`~robovib.milling.sdm.
        milling_force_matrices`); the cutting steps (nonzero ``H``) come first, then at most
        one free flight.
    step_s : ndarray (p, n_steps)
        Step lengths [s] (the delay times the step fractions).
    start_m : ndarray (p,)
        Depth where each pair's scan starts (NaN or <= low end: the bottom of the range).
    depth_range_m : (low, high), each float or ndarray (p,)
        Geometric scan range [m] per pair (the scan grid is ``low * scan_ratio^k``); a pair
        stable at its top gets ``inf``.
    scan_ratio, rtol, max_iter
        As in :func:`~robovib.milling.sdm.critical_depths`.
    krylov_dim : int, optional
        Arnoldi steps (doubled up to twice while a Ritz value does not converge, then dense);
        default 12, or 24 with more than two modes (their free multipliers crowd the circle of
        the dominant one: 12 steps rarely converge there).

    Returns
    -------
    a_lim_m : ndarray (p,)
    multiplier : ndarray (p,) complex
        Critical multiplier just above the limit.
    counts : dict
        ``evaluations`` (p,) monodromy evaluations per pair, ``dense`` (p,) of those that fell
        back to the dense eigenvalues.
    """
    wn = np.ascontiguousarray(wn_rad_s, float)
    z = np.ascontiguousarray(zeta, float)
    inv_m = np.ascontiguousarray(1.0 / np.asarray(mass_kg, float))
    hmat = np.ascontiguousarray(h_n_per_m2, float)
    hs = np.ascontiguousarray(step_s, float)
    cut = np.ascontiguousarray(np.any(hmat != 0, axis=(1, 2)))
    n_cut = int(np.sum(cut))
    if not (np.all(cut[:n_cut]) and cut.size - n_cut <= 1):
        raise ValueError("the cutting steps must come first (then at most one free flight)")
    full = bool(cut.size == n_cut)
    p = wn.shape[0]
    if krylov_dim is None:
        krylov_dim = 12 if wn.shape[1] <= 2 else 24
    a_out = np.empty(p)
    mu_out = np.empty(p, complex)
    n_eval = np.zeros(p, np.int64)
    n_dense = np.zeros(p, np.int64)
    lo, hi = (np.ascontiguousarray(np.broadcast_to(np.asarray(v, float), (p,)))
              for v in depth_range_m)  # fmt: skip
    if not np.all((lo > 0) & (hi > lo)):
        raise ValueError("depth_range_m must satisfy 0 < low < high [m]")
    st = np.ascontiguousarray(np.broadcast_to(np.asarray(start_m, float), (p,)))
    search(wn, z, inv_m, int(n_feed_modes), hmat, hs, cut, n_cut, full, st, lo, hi,
           float(scan_ratio), float(rtol), int(max_iter), int(krylov_dim), a_out, mu_out,
           n_eval, n_dense)  # fmt: skip
    return a_out, mu_out, {"evaluations": n_eval, "dense": n_dense}


def step_counts(modes, delay, cut_fraction, steps_per_period, steps_per_vibration, max_steps):
    """Steps across the cutting arc at every delay, as :func:`~robovib.milling.sdm.sdm_lobes`."""
    f_top = max(md.natural_frequency_hz for md in modes)
    need = np.ceil(steps_per_vibration * f_top * delay * cut_fraction / 10) * 10
    return np.clip(need, int(steps_per_period), max(int(steps_per_period), int(max_steps)))


def sdm_limits(
    structures,
    tool,
    conditions,
    coefficients,
    spindle_rpm,
    *,
    start_m=None,
    steps_per_period: int = 40,
    steps_per_vibration: float = 12.0,
    max_steps: int = 200,
    depth_range_m: tuple[float, float] | None = None,
    rtol: float = 1e-3,
    max_iter: int = 40,
    scan_ratio: float = 1.2,
    first_stride: int = 8,
    warm_start: bool = True,
    steps=None,
    solve=None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Critical depths of many structures at every speed by the compiled semi-discretization.

    Each structure gets what :func:`~robovib.milling.sdm.sdm_lobes` would give it with the same
    options (its own steps per speed, its own default depth range, the same scan and Illinois
    refinement), computed pair by pair by :func:`critical_depths_pairs`.

    Parameters
    ----------
    structures : sequence of (modes_x, modes_y)
        Each a pair of sequences of :class:`~robovib.modal.ModalParameters`.
    tool, conditions, coefficients
        As for :func:`~robovib.milling.sdm.sdm_lobes`.
    spindle_rpm : array_like (n_speeds,)
        Speeds [rpm].
    start_m : array_like (n_structures, n_speeds), optional
        Depth [m] where each scan starts (``scan_from_m`` of ``sdm_lobes``; NaN: the bottom of
        the range). Default: ``sdm_lobes``' warm start per structure (every ``first_stride``-th
        speed of a step group from the bottom, the others from two scan steps below the lowest
        limit found among those).
    steps_per_period, steps_per_vibration, max_steps, depth_range_m, rtol, max_iter, scan_ratio
        As for :func:`~robovib.milling.sdm.sdm_lobes`.
    first_stride : int
        Speeds between two scans from the bottom (when ``start_m`` is not given).
    warm_start : bool
        ``False`` (and no ``start_m``): every speed scanned from the bottom of the range.
    steps : array_like (n_speeds,) of int, optional
        Steps across the cutting arc at every speed for every structure, instead of each
        structure's own count (``steps_per_period``, ``steps_per_vibration``, ``max_steps``);
        0 at a speed: the structure's own count there.
    solve : array_like (n_structures, n_speeds) of bool, optional
        Only these (structure, speed) pairs are solved (needs ``start_m``: each pair's scan
        starts there); the others are returned as NaN with 0 evaluations. Default: all.

    Returns
    -------
    a_lim_m : ndarray (n_structures, n_speeds)
        Critical depth [m] (``inf``: stable to the top of the range).
    multiplier : ndarray (n_structures, n_speeds) complex
        Critical Floquet multiplier just above the limit.
    evaluations : ndarray (n_structures, n_speeds) int
        Monodromy evaluations spent on each pair.
    """
    from .forces import engagement_angles
    from .sdm import _modal_matrices, milling_force_matrices, turning_minimum_depth

    rpm = np.atleast_1d(np.asarray(spindle_rpm, float))
    if rpm.ndim != 1 or not (np.all(np.isfinite(rpm)) and np.all(rpm > 0)):
        raise ValueError("spindle_rpm must be a 1-D array of positive speeds [rpm]")
    structs = [(list(mx), list(my)) for mx, my in structures]
    n_s, n_j = len(structs), rpm.size
    if n_s == 0:
        raise ValueError("no structures given")
    starts = None
    mask = None
    if solve is not None:
        if start_m is None:
            raise ValueError("solve (a subset of the pairs) needs start_m")
        mask = np.broadcast_to(np.asarray(solve, bool), (n_s, n_j))
    if start_m is not None:
        starts = np.broadcast_to(np.asarray(start_m, float), (n_s, n_j))
    elif not warm_start:
        starts = np.full((n_s, n_j), np.nan)
    phi_st, phi_ex = engagement_angles(tool, conditions)
    delay = 60.0 / (tool.n_flutes * rpm)
    cut_fraction = min(1.0, (phi_ex - phi_st) / (2 * math.pi / tool.n_flutes))
    forces: dict[int, tuple[np.ndarray, np.ndarray]] = {}
    # Per structure: the mode arrays, its steps at every speed, its depth range.
    groups: dict[tuple[int, int, int], list[tuple[int, np.ndarray]]] = {}
    info = []
    for s, (mx, my) in enumerate(structs):
        modes = mx + my
        _, sel, mass, _ = _modal_matrices(mx, my)
        if steps is None:
            own = step_counts(modes, delay, cut_fraction, steps_per_period,
                               steps_per_vibration, max_steps).astype(int)  # fmt: skip
        else:
            rule = step_counts(modes, delay, cut_fraction, steps_per_period,
                               steps_per_vibration, max_steps).astype(int)  # fmt: skip
            given = np.broadcast_to(np.asarray(steps, int), (n_j,))
            if np.any((given > 0) & (given < 2)):
                raise ValueError("steps must be >= 2 (or <= 0: the structure's own count)")
            own = np.where(given > 0, given, rule)
        info.append((np.array([md.omega_n for md in modes]),
                     np.array([md.damping_ratio for md in modes]), sel, mass))  # fmt: skip
        for m in np.unique(own):
            here = own == m if mask is None else (own == m) & mask[s]
            if here.any():
                groups.setdefault((len(mx), len(my), int(m)), []).append((s, np.flatnonzero(here)))
    a_out = np.full((n_s, n_j), np.inf if mask is None else np.nan)
    mu_out = np.full((n_s, n_j), np.nan + 0j)
    n_eval = np.zeros((n_s, n_j), int)
    for (nx, _, m), members in groups.items():
        if m not in forces:
            forces[m] = milling_force_matrices(tool.n_flutes, phi_st, phi_ex, coefficients, m)
        hmat, frac = forces[m]
        h_avg = float(np.max(np.abs(np.einsum("i,ijk->jk", frac, hmat))))
        rows = []
        for s, idx in members:
            wn, zeta, sel, mass = info[s]
            if depth_range_m is None:
                ref = min(turning_minimum_depth(md, h_avg) for md in structs[s][0] + structs[s][1])
                lo, hi = ref / 10, ref * 1000
            else:
                lo, hi = (float(v) for v in depth_range_m)
            rows.append((s, idx, wn, zeta, mass, lo, hi))

        def solve(sel_rows, start, rows=rows, nx=nx, hmat=hmat, frac=frac):
            """One kernel call over the listed (row, speed indices) with start depths."""
            ss = np.concatenate([np.full(ix.size, rows[r][0]) for r, ix in sel_rows])
            jj = np.concatenate([ix for _, ix in sel_rows])
            wn_p = np.concatenate([np.tile(rows[r][2], (ix.size, 1)) for r, ix in sel_rows])
            z_p = np.concatenate([np.tile(rows[r][3], (ix.size, 1)) for r, ix in sel_rows])
            m_p = np.concatenate([np.tile(rows[r][4], (ix.size, 1)) for r, ix in sel_rows])
            lo_p = np.concatenate([np.full(ix.size, rows[r][5]) for r, ix in sel_rows])
            hi_p = np.concatenate([np.full(ix.size, rows[r][6]) for r, ix in sel_rows])
            a, mu, cnt = critical_depths_pairs(
                wn_p, z_p, m_p, nx, hmat, delay[jj, None] * frac[None, :], start, (lo_p, hi_p),
                scan_ratio=scan_ratio, rtol=rtol, max_iter=max_iter,
            )  # fmt: skip
            a_out[ss, jj], mu_out[ss, jj] = a, mu
            n_eval[ss, jj] += cnt["evaluations"]

        if starts is not None:
            sel_rows = [(r, row[1]) for r, row in enumerate(rows)]
            jj = np.concatenate([row[1] for row in rows])
            ss = np.concatenate([np.full(row[1].size, row[0]) for row in rows])
            solve(sel_rows, starts[ss, jj])
            continue
        # sdm_lobes' warm start: a first pass from the bottom, the rest from below its floor.
        stride = int(first_stride)
        first, rest = [], []
        for r, row in enumerate(rows):
            idx = row[1]
            if stride < 2 or idx.size < 2 * stride:
                first.append((r, idx))
                continue
            order = idx[np.argsort(delay[idx], kind="stable")]
            pick = order[np.unique(np.r_[np.arange(0, idx.size, stride), idx.size - 1])]
            first.append((r, pick))
            rest.append((r, np.setdiff1d(idx, pick)))
        solve(first, np.full(sum(ix.size for _, ix in first), np.nan))
        if rest:
            start = []
            for r, ix in rest:
                lo = rows[r][5]
                floor = np.min(a_out[rows[r][0], first[r][1]])
                if np.isfinite(floor):
                    n_grid = math.ceil(math.log(rows[r][6] / lo) / math.log(scan_ratio)) + 1
                    grid = np.geomspace(lo, rows[r][6], n_grid)
                    k_floor = max(int(np.searchsorted(grid, floor)) - 2, 0)
                    start.append(np.full(ix.size, grid[k_floor] * (1 + 1e-9)))
                else:
                    start.append(np.full(ix.size, np.nan))
            solve(rest, np.concatenate(start))
    return a_out, mu_out, n_eval


#: Options of :func:`~robovib.milling.sdm.sdm_lobes` that :func:`sdm_envelopes` honours.
COMPILED_OPTIONS = frozenset(
    {"steps_per_period", "steps_per_vibration", "max_steps", "depth_range_m", "rtol",
     "max_iter", "scan_ratio", "first_stride", "warm_start", "scan_from_m"}
)  # fmt: skip


def sdm_envelopes(structures, tool, conditions, coefficients, spindle_rpm, **options):
    """:func:`~robovib.milling.sdm.sdm_lobes` of many structures by the compiled kernel.

    Parameters
    ----------
    structures : sequence of (modes_x, modes_y)
        The structures.
    tool, conditions, coefficients, spindle_rpm
        As for :func:`~robovib.milling.sdm.sdm_lobes`.
    **options
        Those of :data:`COMPILED_OPTIONS`, as for ``sdm_lobes`` (``scan_from_m`` may be
        (n_speeds,) for every structure or (n_structures, n_speeds)).

    Returns
    -------
    list of LobeEnvelope
        One per structure, as ``sdm_lobes`` gives it (``settings["solver"] = "compiled"``).

    Raises
    ------
    ValueError
        An option the compiled kernel does not have (e.g. ``eigensolver``, ``n_scan``).
    """
    from .envelope import LobeEnvelope
    from .sdm import _classify, _envelope_settings

    unknown = set(options) - COMPILED_OPTIONS
    if unknown:
        raise ValueError(f"options not available in the compiled SDM: {sorted(unknown)}")
    opts = dict(options)
    start = opts.pop("scan_from_m", None)
    rpm = np.atleast_1d(np.asarray(spindle_rpm, float))
    a_lim, mu, _ = sdm_limits(structures, tool, conditions, coefficients, rpm, start_m=start,
                              **opts)  # fmt: skip
    delay = 60.0 / (tool.n_flutes * rpm)
    envs = []
    for s, (mx, my) in enumerate(structures):
        modes = list(mx) + list(my)
        kind = np.full(rpm.size, "none", dtype=object)
        chatter = np.full(rpm.size, np.nan)
        active = np.flatnonzero(np.isfinite(a_lim[s]))
        if active.size:
            kind[active], chatter[active] = _classify(mu[s, active], delay[active], modes)
        envs.append(
            LobeEnvelope(
                spindle_rpm=rpm,
                a_lim_m=a_lim[s],
                chatter_hz=chatter,
                kind=kind.astype(str),
                method="sdm",
                settings=_envelope_settings(
                    tool,
                    conditions,
                    coefficients,
                    steps_per_period=opts.get("steps_per_period", 40),
                    steps_per_vibration=opts.get("steps_per_vibration", 12.0),
                    rtol=float(opts.get("rtol", 1e-3)),
                    eigensolver="arnoldi",
                    warm_start=opts.get("warm_start", True),
                    scan_ratio=float(opts.get("scan_ratio", 1.2)),
                    solver="compiled",
                ),
            )
        )
    return envs
