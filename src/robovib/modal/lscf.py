"""Multi-mode identification: LSCF poles, stabilization diagram, automatic mode choice, LSFD.

* **LSCF** (least-squares complex frequency domain, Guillaume/Verboven): a common-denominator
  rational model in the z-domain, ``z = exp(i 2 pi f dt)`` with ``dt = 1 / (2 f_max)``, whose
  denominator follows from the reduced normal equations ``sum_o (T_o - S_o^T R^-1 S_o) a = 0``
  (real coefficients, last coefficient fixed to 1). Poles: ``s = ln(z) / dt``.
* **Stabilization**: LSCF at increasing model orders; a pole is *stable* when the previous
  order has one within ``df_rel`` in frequency and ``dzeta_rel`` in damping.
* **Automatic choice**: stable poles are clustered by frequency across orders; a cluster seen at
  no fewer than ``min_fraction`` of the orders is a physical mode (its median pole is kept).
  This replaces the interactive picking of GUI tools, so it runs in scripts and CI.
* **LSFD**: residues of the chosen poles (plus lower and upper residuals) by linear least
  squares; modal mass ``m = -1 / (2 wd Im(A))`` (real modes), modal stiffness ``k = m wn^2``.

Tested against sdypy-EMA (``tests/modal/test_modal.py``), which implements the same LSCF.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from .._threads import single_blas_thread
from ..frf.core import FRF
from .parameters import ModalParameters, remove_exponential_window_damping
from .sdof import MAX_RELATIVE_RMS_ERROR

_FRF_UNIT = {"compliance": "m/N", "mobility": "m/s/N", "accelerance": "m/s^2/N"}

__all__ = [
    "ModalFitWarning",
    "MultiModeFit",
    "StabilizationDiagram",
    "fit_modes",
    "lscf_poles",
    "lsfd_residues",
    "select_stable_modes",
    "stabilization_diagram",
]


class ModalFitWarning(UserWarning):
    """A multi-mode fit produced a questionable mode (e.g. a negative modal mass)."""


def _as_frf_matrix(values) -> np.ndarray:
    h = np.asarray(values, complex)
    return h[None] if h.ndim == 1 else h


def lscf_poles(frequency_hz, values, order: int, f_max_hz: float | None = None) -> np.ndarray:
    """Continuous-time poles (rad/s) of an LSCF model of ``order`` (all roots, unfiltered).

    ``values`` is (n_f,) or (n_outputs, n_f): one or several FRFs sharing the denominator.

    Parameters
    ----------
    frequency_hz : array_like
        (n_f,) frequency axis [Hz].
    values : array_like
        (n_f,) or (n_outputs, n_f) complex FRFs.
    order : int
        Model order (number of denominator coefficients - 1).
    f_max_hz : float, optional
        Frequency mapped to the Nyquist limit of the z-domain basis (default: the last bin).

    Returns
    -------
    numpy.ndarray
        (order,) complex poles [rad/s].
    """
    f = np.asarray(frequency_hz, float)
    r, s, t, dt = _lscf_normal_matrices(f, values, order, f_max_hz)
    return _lscf_poles_of_order(r, s, t, dt, order)


def _lscf_normal_matrices(f, values, max_order: int, f_max_hz: float | None = None):
    """Normal-equation blocks R, S, T of the LSCF model of ``max_order``, summed S/T over outputs.

    The z-domain basis of order ``n`` is the first ``n + 1`` columns of the basis of any higher
    order, so the blocks of every order ``n <= max_order`` are the leading ``(n+1, n+1)``
    sub-blocks of these (the stabilization diagram builds them once, not once per order).
    Returns ``(r, s, t, dt)``: ``s`` and ``t`` have shape (n_outputs, max_order+1, max_order+1).
    """
    h = _as_frf_matrix(values)
    h = h / np.max(np.abs(h))  # conditioning only; poles are scale-free
    f_max = float(f[-1] if f_max_hz is None else f_max_hz)
    dt = 1.0 / (2.0 * f_max)
    z = np.exp(1j * 2 * np.pi * f * dt)
    basis = z[:, None] ** np.arange(max_order + 1)[None, :]  # (n_f, n+1)
    r = np.real(basis.conj().T @ basis)
    y = -h[:, :, None] * basis[None]  # (n_outputs, n_f, n+1)
    s = np.real(basis.conj().T[None] @ y)
    t = np.real(np.swapaxes(y.conj(), 1, 2) @ y)
    return r, s, t, dt


def _lscf_poles_of_order(r, s, t, dt: float, order: int) -> np.ndarray:
    """Poles (rad/s) of the LSCF model of ``order`` from the blocks of a model of order >= it."""
    k = order + 1
    r, s, t = r[:k, :k], s[:, :k, :k], t[:, :k, :k]
    r_inv = np.linalg.pinv(r)
    m = np.zeros((k, k))
    for s_o, t_o in zip(s, t, strict=True):
        m += t_o - s_o.T @ r_inv @ s_o
    a = np.linalg.lstsq(m[:order, :order], -m[:order, order], rcond=None)[0]
    coeffs = np.concatenate([a, [1.0]])
    roots = np.roots(coeffs[::-1])
    roots = roots[np.abs(roots) > 0]
    return np.log(roots) / dt


def _physical(poles: np.ndarray, f_lo: float, f_hi: float, max_zeta: float):
    poles = poles[np.imag(poles) > 0]
    wn = np.abs(poles)
    fn = wn / (2 * np.pi)
    zeta = -np.real(poles) / wn
    keep = (fn >= f_lo) & (fn <= f_hi) & (zeta > 0) & (zeta < max_zeta)
    order = np.argsort(fn[keep])
    return fn[keep][order], zeta[keep][order]


@dataclass(frozen=True)
class StabilizationDiagram:
    """Poles per model order: ``fn[i]``, ``zeta[i]``, ``stable[i]`` for ``orders[i]``.

    Attributes
    ----------
    orders
        Model orders.
    fn, zeta
        Per order: natural frequencies [Hz] and damping ratios of its physical poles.
    stable
        Per order: whether each pole repeats the previous order's (within the tolerances).
    """

    orders: tuple[int, ...]
    fn: tuple[np.ndarray, ...]
    zeta: tuple[np.ndarray, ...]
    stable: tuple[np.ndarray, ...]

    def plot(self, ax=None, frf: FRF | None = None):
        """Stabilization diagram (orders vs frequency), optionally over |FRF| (matplotlib).

        Parameters
        ----------
        ax : matplotlib.axes.Axes, optional
            Axes to draw on (default: a new figure).
        frf : FRF, optional
            Drawn as |H| on a second axis.

        Returns
        -------
        matplotlib.axes.Axes
            The axes drawn on.
        """
        import matplotlib.pyplot as plt

        if ax is None:
            _, ax = plt.subplots(figsize=(8, 4))
        for n, fn, st in zip(self.orders, self.fn, self.stable, strict=True):
            ax.plot(fn[~st], np.full((~st).sum(), n), "x", color="0.6", ms=4)
            ax.plot(fn[st], np.full(st.sum(), n), "o", color="C0", ms=4, mfc="none")
        ax.set_xlabel("frequency [Hz]")
        ax.set_ylabel("model order [-]")
        if frf is not None:
            ax2 = ax.twinx()
            ax2.semilogy(frf.frequency_hz, np.abs(frf.values), color="C3", lw=1)
            ax2.set_ylabel(f"|H| [{_FRF_UNIT.get(frf.quantity, '?')}]")
        return ax


MAX_LSCF_ORDER = 200  #: highest LSCF model order accepted (a few seconds per diagram)


def stabilization_diagram(
    frequency_hz,
    values,
    max_order: int = 40,
    *,
    min_order: int = 2,
    df_rel: float = 0.01,
    dzeta_rel: float = 0.05,
    max_zeta: float = 0.5,
) -> StabilizationDiagram:
    """LSCF poles for orders ``min_order..max_order`` with stability flags.

    Parameters
    ----------
    frequency_hz : array_like
        (n_f,) frequency axis [Hz].
    values : array_like
        (n_f,) or (n_outputs, n_f) complex FRFs.
    max_order, min_order : int
        Range of model orders.
    df_rel, dzeta_rel : float
        A pole is stable when its frequency and damping ratio repeat the previous order's
        within these relative tolerances.
    max_zeta : float
        Poles with a larger damping ratio are not physical (dropped).

    Returns
    -------
    StabilizationDiagram
        Poles and stability flags per order.

    Raises
    ------
    ValueError
        ``max_order`` outside ``[min_order, MAX_LSCF_ORDER]`` or more than the band can carry
        (an order-n LSCF has about 2n unknowns per bin pair; more is slow and meaningless).
    """
    from .._checks import check_int

    f = np.asarray(frequency_hz, float)
    min_order = check_int("min_order", min_order, lo=1, hi=MAX_LSCF_ORDER)
    max_order = check_int("max_order", max_order, lo=min_order, hi=MAX_LSCF_ORDER)
    if max_order >= f.size:
        raise ValueError(
            f"max_order={max_order} needs more than {max_order} frequency bins; the band has "
            f"{f.size} (lower max_order or widen the band)"
        )
    orders, fns, zetas, stables = [], [], [], []
    prev_fn = prev_zeta = None
    # Small matrices (max_order + 1 square): BLAS threads only contend, and a busy machine
    # multiplied the multi-mode campaign processing time by 10 (issue 37).
    with single_blas_thread():
        blocks = _lscf_normal_matrices(f, values, max_order)
    for n in range(int(min_order), int(max_order) + 1):
        with warnings.catch_warnings(), single_blas_thread():
            warnings.simplefilter("ignore", RuntimeWarning)
            fn, zeta = _physical(_lscf_poles_of_order(*blocks, n), f[0], f[-1], max_zeta)
        stable = np.zeros(fn.size, bool)
        if prev_fn is not None and prev_fn.size:
            for i in range(fn.size):
                j = np.argmin(np.abs(prev_fn - fn[i]))
                stable[i] = (
                    abs(prev_fn[j] - fn[i]) <= df_rel * fn[i]
                    and abs(prev_zeta[j] - zeta[i]) <= dzeta_rel * zeta[i]
                )
        orders.append(n)
        fns.append(fn)
        zetas.append(zeta)
        stables.append(stable)
        prev_fn, prev_zeta = fn, zeta
    return StabilizationDiagram(tuple(orders), tuple(fns), tuple(zetas), tuple(stables))


def select_stable_modes(
    diagram: StabilizationDiagram, min_fraction: float = 0.3, df_rel: float = 0.01
):
    """Automatic choice of physical modes: (fn, zeta) arrays of frequency clusters of stable poles.

    Parameters
    ----------
    diagram : StabilizationDiagram
        The poles per order.
    min_fraction : float
        A cluster is a mode when its stable poles come from at least this fraction of the
        orders.
    df_rel : float
        Relative frequency gap that separates clusters.

    Returns
    -------
    fn : numpy.ndarray
        Natural frequencies [Hz] of the modes (median of the higher-order half of a cluster).
    zeta : numpy.ndarray
        Their damping ratios.
    """
    pts = [
        (fn[i], z[i], n)
        for n, fn, z, st in zip(
            diagram.orders, diagram.fn, diagram.zeta, diagram.stable, strict=True
        )
        for i in np.flatnonzero(st)
    ]
    if not pts:
        return np.array([]), np.array([])
    pts.sort()
    clusters, current = [], [pts[0]]
    for p in pts[1:]:
        if p[0] - current[-1][0] <= df_rel * p[0]:
            current.append(p)
        else:
            clusters.append(current)
            current = [p]
    clusters.append(current)
    n_orders = len(diagram.orders)
    fns, zetas = [], []
    for c in clusters:
        orders_seen = {p[2] for p in c}
        if len(orders_seen) >= min_fraction * n_orders:
            top = sorted(c, key=lambda p: p[2])[len(c) // 2 :]
            fns.append(float(np.median([p[0] for p in top])))
            zetas.append(float(np.median([p[1] for p in top])))
    return np.array(fns), np.array(zetas)


def lsfd_residues(
    frequency_hz, values, poles, *, lower_residual: bool = True, upper_residual: bool = True
):
    """Residues A (n_outputs, n_modes) of ``H = sum A/(iw - p) + conj(A)/(iw - conj p) + UR + LR/(iw)^2``.

    Parameters
    ----------
    frequency_hz : array_like
        (n_f,) frequency axis [Hz].
    values : array_like
        (n_f,) or (n_outputs, n_f) complex FRFs.
    poles : array_like
        (n_modes,) complex poles [rad/s] (one of each conjugate pair).
    lower_residual, upper_residual : bool
        Fit the ``LR / (iw)^2`` and ``UR`` terms of out-of-band modes.

    Returns
    -------
    A : numpy.ndarray
        (n_outputs, n_modes) complex residues.
    UR, LR : numpy.ndarray
        (n_outputs,) complex residual terms (zero where not fitted).
    """
    f = np.asarray(frequency_hz, float)
    h = _as_frf_matrix(values)
    s = 1j * 2 * np.pi * f
    poles = np.asarray(poles, complex)
    cols = []
    for p in poles:
        cols.append(1 / (s - p) + 1 / (s - np.conj(p)))  # coefficient of Re A
        cols.append(1j / (s - p) - 1j / (s - np.conj(p)))  # coefficient of Im A
    if upper_residual:
        cols += [np.ones_like(s), 1j * np.ones_like(s)]
    if lower_residual:
        cols += [1 / s**2, 1j / s**2]
    basis = np.column_stack(cols)
    a_real = np.vstack([basis.real, basis.imag])
    residues = np.zeros((h.shape[0], poles.size), complex)
    ur = np.zeros(h.shape[0], complex)
    lr = np.zeros(h.shape[0], complex)
    for o, h_o in enumerate(h):
        scale = np.max(np.abs(h_o))
        b = np.concatenate([h_o.real, h_o.imag]) / scale
        x = np.linalg.lstsq(a_real, b, rcond=None)[0] * scale
        residues[o] = x[0 : 2 * poles.size : 2] + 1j * x[1 : 2 * poles.size : 2]
        k = 2 * poles.size
        if upper_residual:
            ur[o] = x[k] + 1j * x[k + 1]
            k += 2
        if lower_residual:
            lr[o] = x[k] + 1j * x[k + 1]
    return residues, ur, lr


@dataclass(frozen=True)
class MultiModeFit:
    """All physical modes of an FRF in a band (:func:`fit_modes`).

    Attributes
    ----------
    modes
        The modes kept, by frequency.
    residues
        (n_modes,) complex LSFD residues.
    diagram
        The stabilization diagram they were chosen from.
    band_hz
        The band fitted [Hz].
    relative_rms_error
        RMS of the fit residual over the RMS of the FRF in the band.
    flags
        Reasons not to trust the fit.
    """

    modes: tuple[ModalParameters, ...]
    residues: np.ndarray  #: (n_modes,) complex LSFD residues
    diagram: StabilizationDiagram
    band_hz: tuple[float, float]
    relative_rms_error: float
    #: reasons not to trust the fit: modes left out (negative modal mass: inverted sign or not
    #: a driving point), no mode kept, a mode at the band edge, a large residual
    flags: tuple[str, ...] = ()

    @property
    def flagged(self) -> bool:
        return bool(self.flags)

    def reconstruct(self, frequency_hz) -> np.ndarray:
        """Compliance of the fitted modes alone (no residual terms).

        Parameters
        ----------
        frequency_hz : array_like
            Frequencies [Hz].

        Returns
        -------
        numpy.ndarray
            Complex compliance [m/N].
        """
        return sum(m.compliance(frequency_hz) for m in self.modes)


def fit_modes(
    frf: FRF,
    band_hz: tuple[float, float] | None = None,
    *,
    max_order: int = 30,
    min_fraction: float = 0.3,
    min_frequency_hz: float = 1.0,
    correct_exp_window: bool = True,
) -> MultiModeFit:
    """Identify all physical modes of a driving-point FRF in a band (LSCF + LSFD).

    A mode with a negative modal mass (not a driving-point mode) is reported with a
    :class:`ModalFitWarning` and left out. See ``docs/methods.md`` section 2.

    Parameters
    ----------
    frf : FRF
        Driving-point FRF, any form (converted to compliance [m/N] first).
    band_hz : tuple of float, optional
        (f_min, f_max) fit band [Hz]; default: the whole FRF.
    max_order : int
        Highest model order of the stabilisation diagram.
    min_fraction : float
        A pole must be stable in at least this fraction of the orders, in (0, 1].
    min_frequency_hz : float
        Bins below this frequency [Hz] are dropped before integrating to compliance.
    correct_exp_window : bool
        Remove the damping added by an exponential window recorded on the FRF.

    Returns
    -------
    MultiModeFit
        ``modes`` (:class:`ModalParameters`: fn [Hz], modal stiffness [N/m], zeta) sorted by
        frequency, residues, the stabilisation diagram, band, relative RMS error and flags.

    Raises
    ------
    ValueError
        Too few bins in the band or a bad ``max_order`` / ``min_fraction``.

    Examples
    --------
    >>> import numpy as np
    >>> from robovib.frf import FRF
    >>> from robovib.modal import ModalParameters, fit_modes
    >>> f = np.linspace(5, 120, 1200)
    >>> modes = [ModalParameters(30.0, 2e6, 0.03), ModalParameters(80.0, 5e6, 0.03)]
    >>> fit = fit_modes(FRF(f, sum(m.compliance(f) for m in modes)))
    >>> [round(m.natural_frequency_hz) for m in fit.modes]
    [30, 80]
    """
    h = frf.to_compliance(min_frequency_hz)
    if band_hz is not None:
        h = h.band(*band_hz)
    f, v = h.frequency_hz, h.values
    diagram = stabilization_diagram(f, v, max_order)
    fns, zetas = select_stable_modes(diagram, min_fraction)
    if fns.size == 0:
        raise ValueError("no stable mode found in the band; widen it or raise max_order")
    wn = 2 * np.pi * fns
    poles = -zetas * wn + 1j * wn * np.sqrt(1 - zetas**2)
    with single_blas_thread():
        residues, ur, lr = lsfd_residues(f, v, poles)
    modes, kept, flags = [], [], []
    for r, (fn, zeta, p) in enumerate(zip(fns, zetas, poles, strict=True)):
        wd = p.imag
        a = residues[0, r]
        if a.imag >= 0:
            warnings.warn(
                f"mode at {fn:.3g} Hz has a non-positive modal mass; left out",
                ModalFitWarning,
                stacklevel=2,
            )
            flags.append(
                f"mode at {fn:.4g} Hz left out: negative modal mass (inverted sign, or not a "
                "driving-point FRF)"
            )
            continue
        df = float(f[1] - f[0])
        if fn - f[0] <= 2 * df or f[-1] - fn <= 2 * df:
            flags.append(f"mode at {fn:.4g} Hz at the edge of the band {f[0]:.4g}-{f[-1]:.4g} Hz")
        mass = -1.0 / (2 * wd * a.imag)
        mode = ModalParameters(float(fn), float(mass * wn[r] ** 2), float(zeta))
        if correct_exp_window and frf.exp_window_tau_s is not None:
            mode = remove_exponential_window_damping(mode, frf.exp_window_tau_s)
        modes.append(mode)
        kept.append(a)
    s = 1j * 2 * np.pi * f
    synth = (
        sum(
            a / (s - p) + np.conj(a) / (s - np.conj(p))
            for a, p in zip(residues[0], poles, strict=True)
        )
        + ur[0]
        + lr[0] / s**2
    )
    rel = float(np.sqrt(np.mean(np.abs(synth - v) ** 2)) / np.max(np.abs(v)))
    if not modes:
        flags.append("no physical mode kept")
    if rel > MAX_RELATIVE_RMS_ERROR:
        flags.append(f"large residual: relative RMS error {rel:.2f} > {MAX_RELATIVE_RMS_ERROR:g}")
    return MultiModeFit(
        tuple(modes), np.array(kept), diagram, (float(f[0]), float(f[-1])), rel, tuple(flags)
    )
