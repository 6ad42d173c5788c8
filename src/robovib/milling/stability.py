"""Chatter stability: zero-order (frequency-domain) lobes of Altintas & Budak (1995).

Y. Altintas, E. Budak, "Analytical prediction of stability lobes in milling", CIRP Annals 44(1),
1995; also Altintas, *Manufacturing Automation* (2nd ed.), §3.4. With the average directional
coefficients over the engagement [phi_st, phi_ex] (K_r = K_rc / K_tc)::

    a_xx = 1/2 [ cos 2p - 2 K_r p + K_r sin 2p ]      a_xy = 1/2 [-sin 2p - 2 p + K_r cos 2p ]
    a_yx = 1/2 [-sin 2p + 2 p + K_r cos 2p ]          a_yy = 1/2 [-cos 2p - 2 K_r p - K_r sin 2p ]

and the direct FRFs Gxx, Gyy of the tool tip (feed along x, normal along y), the eigenvalue of
the oriented transfer function solves ``a0 L^2 + a1 L + 1 = 0`` with
``a0 = Gxx Gyy (a_xx a_yy - a_xy a_yx)``, ``a1 = a_xx Gxx + a_yy Gyy``. For every chatter
frequency ``w_c``::

    a_lim = -2 pi L_R (1 + kappa^2) / (N K_tc),  kappa = L_I / L_R,
    eps = pi - 2 atan(kappa),  n [rpm] = 60 w_c / (N (2 pi k + eps)),  k = 0, 1, 2, ...

A single flexible direction (Gxx = 0) reduces to ``a_lim = 2 pi / (N K_tc a_yy Re G)``, whose
minimum over frequency is the classical ``a_lim,min = 2 pi / (N K_tc a_yy min Re G)`` (both
factors negative, e.g. ``a_yy = -K_r pi`` in slotting).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from ..modal.parameters import ModalParameters
from .forces import CuttingCoefficients, CuttingConditions, MillingTool, engagement_angles

__all__ = ["StabilityLobes", "directional_coefficients", "stability_lobes"]


def directional_coefficients(
    phi_st: float, phi_ex: float, kr: float
) -> tuple[float, float, float, float]:
    """Average directional factors (a_xx, a_xy, a_yx, a_yy) over the engagement.

    Parameters
    ----------
    phi_st, phi_ex : float
        Engagement start and exit angles [rad].
    kr : float
        Ratio of radial to tangential cutting coefficient.

    Returns
    -------
    a_xx, a_xy, a_yx, a_yy : float
        The factors.
    """

    def at(p):
        s2, c2 = math.sin(2 * p), math.cos(2 * p)
        return np.array(
            [
                c2 - 2 * kr * p + kr * s2,
                -s2 - 2 * p + kr * c2,
                -s2 + 2 * p + kr * c2,
                -c2 - 2 * kr * p - kr * s2,
            ]
        )

    return tuple(0.5 * (at(phi_ex) - at(phi_st)))


@dataclass(frozen=True)
class StabilityLobes:
    """Lobes as separate branches: speeds [rpm] and critical axial depths [m], one row per lobe.

    Attributes
    ----------
    spindle_rpm
        Speeds [rpm] of each lobe.
    depth_m
        Critical depths [m] of each lobe.
    chatter_hz
        Chatter frequency of each lobe [Hz].
    branch_chatter_hz
        Chatter frequency along each lobe [Hz], if computed.
    """

    spindle_rpm: list[np.ndarray]
    depth_m: list[np.ndarray]
    chatter_hz: np.ndarray
    branch_chatter_hz: list[np.ndarray] | None = None

    def critical_depth(self, spindle_rpm) -> np.ndarray:
        """Lowest critical depth over all lobes at the given speeds (inf where no lobe covers).

        Parameters
        ----------
        spindle_rpm : array_like
            Speeds [rpm].

        Returns
        -------
        numpy.ndarray
            Critical depths [m].
        """
        s = np.atleast_1d(np.asarray(spindle_rpm, float))
        out = np.full(s.shape, np.inf)
        for rpm, depth in zip(self.spindle_rpm, self.depth_m, strict=True):
            order = np.argsort(rpm)
            r, d = rpm[order], depth[order]
            inside = (s >= r[0]) & (s <= r[-1])
            out[inside] = np.minimum(out[inside], np.interp(s[inside], r, d))
        return out

    @property
    def minimum_depth_m(self) -> float:
        return float(min(np.min(d) for d in self.depth_m))

    def plot(self, ax=None, rpm_range=None):
        """Critical axial depth vs spindle speed, one line per lobe.

        Parameters
        ----------
        ax : matplotlib.axes.Axes, optional
            Axes to draw into; a new figure when omitted.
        rpm_range : tuple of float, optional
            Spindle-speed limits of the x axis [rpm].

        Returns
        -------
        matplotlib.figure.Figure
            The figure holding the axes (saving is the caller's: ``robovib.io.save_figure``).
        """
        import matplotlib.pyplot as plt

        if ax is None:
            _, ax = plt.subplots(figsize=(7, 4))
        for rpm, depth in zip(self.spindle_rpm, self.depth_m, strict=True):
            ax.plot(rpm, depth * 1e3, color="C0", lw=1)
        if rpm_range is not None:
            ax.set_xlim(*rpm_range)
        ax.set_ylim(0, 4 * self.minimum_depth_m * 1e3)
        ax.set_xlabel("spindle speed [rpm]")
        ax.set_ylabel("critical axial depth [mm]")
        ax.set_title("stability lobes (zero-order method)")
        ax.figure.tight_layout()
        return ax.figure


def stability_lobes(
    modes_x: Sequence[ModalParameters],
    modes_y: Sequence[ModalParameters],
    tool: MillingTool,
    conditions: CuttingConditions,
    coefficients: CuttingCoefficients,
    *,
    n_lobes: int = 8,
    frequency_range_hz: tuple[float, float] | None = None,
    n_frequencies: int = 4000,
    frf: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]] | None = None,
) -> StabilityLobes:
    """Zero-order stability lobes (see module docs and ``docs/methods.md`` section 5).

    Parameters
    ----------
    modes_x, modes_y : sequence of ModalParameters
        Tool-tip modes along the feed (x) and normal (y) directions (empty: rigid).
    tool : MillingTool
        Number of flutes and diameter [m].
    conditions : CuttingConditions
        Radial immersion and milling mode (its axial depth and speed are what the lobes are
        about, so they are not used).
    coefficients : CuttingCoefficients
        Cutting coefficients ``ktc``, ``krc`` [N/m²].
    n_lobes : int
        Number of lobes computed.
    frequency_range_hz : tuple of float, optional
        Chatter frequencies scanned [Hz]; default around the modes.
    n_frequencies : int
        Points of the chatter-frequency scan.
    frf : callable, optional
        ``f_hz (n,) -> (Gxx, Gyy)`` complex compliances [m/N] replacing the modes (a measured
        FRF).

    Returns
    -------
    StabilityLobes
        Per lobe: spindle speed [rpm], critical axial depth [m] and chatter frequency [Hz].

    Raises
    ------
    ValueError
        No mode and no FRF, or no negative real part of the oriented FRF in the scanned range.

    Examples
    --------
    >>> from robovib.milling import CuttingConditions, MillingTool, ALUMINIUM_7075
    >>> from robovib.milling.stability import stability_lobes
    >>> from robovib.modal import ModalParameters
    >>> lobes = stability_lobes([ModalParameters(30.0, 2e6, 0.05)], [], MillingTool(0.0254, 2),
    ...                         CuttingConditions(1750.0, 1e-4, 1e-3, 6e-3), ALUMINIUM_7075)
    >>> lobes.minimum_depth_m > 0
    True
    """
    if not modes_x and not modes_y and frf is None:
        raise ValueError("at least one flexible direction (modes or frf) is needed")
    phi_st, phi_ex = engagement_angles(tool, conditions)
    kr = coefficients.krc / coefficients.ktc
    axx, axy, ayx, ayy = directional_coefficients(phi_st, phi_ex, kr)
    all_modes = list(modes_x) + list(modes_y)
    if frequency_range_hz is None:
        if not all_modes:
            raise ValueError("frequency_range_hz is required with an frf callable")
        fmin = 0.5 * min(m.natural_frequency_hz for m in all_modes)
        fmax = 2.0 * max(m.natural_frequency_hz for m in all_modes)
    else:
        fmin, fmax = frequency_range_hz
    f = np.linspace(fmin, fmax, n_frequencies)
    if frf is not None:
        gxx, gyy = frf(f)
    else:
        gxx = (
            np.sum([m.compliance(f) for m in modes_x], axis=0)
            if modes_x
            else np.zeros_like(f, complex)
        )
        gyy = (
            np.sum([m.compliance(f) for m in modes_y], axis=0)
            if modes_y
            else np.zeros_like(f, complex)
        )
    a0 = gxx * gyy * (axx * ayy - axy * ayx)
    a1 = axx * gxx + ayy * gyy
    with np.errstate(divide="ignore", invalid="ignore"):
        if np.all(np.abs(a0) < 1e-300):
            lam = -1.0 / a1
            lam = lam[None, :]
        else:
            disc = np.sqrt(a1**2 - 4 * a0)
            lam = np.stack([-(a1 + disc) / (2 * a0), -(a1 - disc) / (2 * a0)])
    n_fl = tool.n_flutes
    rpms, depths, freqs = [], [], []
    wc = 2 * np.pi * f
    for branch in lam:
        lr, li = branch.real, branch.imag
        with np.errstate(divide="ignore", invalid="ignore"):
            kappa = li / lr
            depth = -2 * np.pi * lr * (1 + kappa**2) / (n_fl * coefficients.ktc)
            eps = np.pi - 2 * np.arctan(kappa)
        valid = np.isfinite(depth) & (depth > 0)
        if not np.any(valid):
            continue
        for k in range(int(n_lobes)):
            with np.errstate(divide="ignore"):
                rpm = 60 * wc / (n_fl * (2 * np.pi * k + eps))
            ok = valid & np.isfinite(rpm) & (rpm > 0)
            rpms.append(rpm[ok])
            depths.append(depth[ok])
            freqs.append(f[ok])
    if not depths:
        raise ValueError("no positive critical depth: check the modes and the engagement")
    return StabilityLobes(rpms, depths, f, freqs)
