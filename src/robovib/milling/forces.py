"""Mechanistic milling forces (Altintas, *Manufacturing Automation*, 2nd ed., ch. 2).

For flute ``j`` at immersion angle ``phi_j(t, z) = phi0 + 2 pi n t / 60 + 2 pi j / N - 2 tan(beta) z / D``
(measured clockwise from the +normal axis, feed along +feed), the chip thickness is
``h = f_z sin(phi) + (R_j - R_{j-1})`` with radial runout ``R_j = rho cos(lambda - 2 pi j / N)``
(clipped at 0: the flute is out of the cut), and the differential edge forces on an axial
slice ``dz`` are::

    dF_t = (K_tc h + K_te) dz,   dF_r = (K_rc h + K_re) dz,   dF_a = (K_ac h + K_ae) dz

inside the engagement ``phi_st <= phi <= phi_ex``. Projected on the tool frame
(feed, normal, axial)::

    F_feed = sum(-dF_t cos(phi) - dF_r sin(phi)),  F_normal = sum(dF_t sin(phi) - dF_r cos(phi)),
    F_axial = sum(dF_a)

These are the forces of the workpiece on the tool (Altintas' convention). The model ignores
the regenerative feedback of vibration into the chip thickness (forced vibration only).

Coefficient presets are typical literature values, stated as assumptions: Al 7075 from
Altintas' tables for a similar end mill; Acetal (POM) scaled from published polymer-milling
data (roughly 1/8 of aluminium). Replace them with calibrated values where you have them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = [
    "ACETAL",
    "ALUMINIUM_7075",
    "CuttingCoefficients",
    "CuttingConditions",
    "MillingTool",
    "engagement_angles",
    "milling_forces",
]


@dataclass(frozen=True)
class CuttingCoefficients:
    """Cutting (N/m²) and edge (N/m) coefficients: tangential, radial, axial.

    Attributes
    ----------
    ktc, krc, kac
        Tangential, radial and axial cutting coefficients [N/m²].
    kte, kre, kae
        Tangential, radial and axial edge coefficients [N/m].
    """

    ktc: float
    krc: float
    kac: float
    kte: float = 0.0
    kre: float = 0.0
    kae: float = 0.0


ALUMINIUM_7075 = CuttingCoefficients(
    ktc=796e6, krc=168e6, kac=222e6, kte=27.7e3, kre=15.8e3, kae=1.4e3
)
ACETAL = CuttingCoefficients(ktc=100e6, krc=40e6, kac=20e6, kte=3.0e3, kre=2.0e3, kae=0.5e3)


@dataclass(frozen=True)
class MillingTool:
    """An end mill.

    Attributes
    ----------
    diameter_m
        Diameter [m].
    n_flutes
        Number of flutes.
    helix_deg
        Helix angle [deg].
    runout_m, runout_angle_deg
        Radial runout [m] and its angle [deg].
    """

    diameter_m: float = 0.0254
    n_flutes: int = 2
    helix_deg: float = 30.0
    runout_m: float = 0.0
    runout_angle_deg: float = 0.0

    def __post_init__(self) -> None:
        if not self.diameter_m > 0:
            raise ValueError(f"tool diameter must be positive, got {self.diameter_m}")
        if int(self.n_flutes) < 1:
            raise ValueError(f"n_flutes must be >= 1, got {self.n_flutes}")
        if not 0 <= self.helix_deg < 90:
            raise ValueError(f"helix angle must be in [0, 90) degrees, got {self.helix_deg}")
        if self.runout_m < 0:
            raise ValueError(f"runout must be >= 0, got {self.runout_m}")


@dataclass(frozen=True)
class CuttingConditions:
    """Spindle speed [rpm], feed per tooth [m], axial and radial depth [m], milling mode.

    Attributes
    ----------
    spindle_rpm
        Spindle speed [rpm].
    feed_per_tooth_m
        Feed per tooth [m].
    axial_depth_m, radial_depth_m
        Axial and radial depth of cut [m].
    down_milling
        Down (climb) milling, else up milling.
    """

    spindle_rpm: float
    feed_per_tooth_m: float
    axial_depth_m: float
    radial_depth_m: float
    down_milling: bool = True

    def __post_init__(self) -> None:
        for name in ("spindle_rpm", "feed_per_tooth_m", "axial_depth_m", "radial_depth_m"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be a positive number, got {value!r}")

    def feed_speed_m_per_s(self, tool: MillingTool) -> float:
        return self.feed_per_tooth_m * tool.n_flutes * self.spindle_rpm / 60.0

    def tooth_passing_hz(self, tool: MillingTool) -> float:
        return self.spindle_rpm / 60.0 * tool.n_flutes


def engagement_angles(tool: MillingTool, cond: CuttingConditions) -> tuple[float, float]:
    """(phi_start, phi_exit) [rad] for the radial depth and the milling mode (slotting: 0, pi).

    Parameters
    ----------
    tool : MillingTool
        The cutter.
    cond : CuttingConditions
        Radial depth and milling mode.

    Returns
    -------
    phi_start, phi_exit : float
        Engagement angles [rad].
    """
    ratio = cond.radial_depth_m / tool.diameter_m
    if ratio > 1 + 1e-12:
        raise ValueError(
            f"radial depth {cond.radial_depth_m} m exceeds the tool diameter {tool.diameter_m} m"
        )
    if ratio >= 1 - 1e-12:
        return 0.0, math.pi
    if cond.down_milling:
        return math.pi - math.acos(1 - 2 * ratio), math.pi
    return 0.0, math.acos(1 - 2 * ratio)


def milling_forces(
    time_s,
    tool: MillingTool,
    cond: CuttingConditions,
    coeffs: CuttingCoefficients,
    *,
    n_slices: int = 12,
    start_angle_rad: float = 0.0,
    n_angles: int | None = 3600,
) -> np.ndarray:
    """Cutting force (n, 3) in the tool frame (feed, normal, axial) [N] at the times ``time_s``.

    At constant spindle speed the force is periodic in the spindle angle: with ``n_angles``
    (default 3600, 0.1°) it is evaluated on that angle grid over one revolution and
    interpolated (periodic, linear) at the samples; ``n_angles=None`` evaluates every sample.

    Parameters
    ----------
    time_s : array_like
        (n,) times [s].
    tool : MillingTool
        The cutter.
    cond : CuttingConditions
        Cutting conditions.
    coeffs : CuttingCoefficients
        Cutting coefficients.
    n_slices : int
        Axial slices of the helical flutes.
    start_angle_rad : float
        Spindle angle at t = 0 [rad].
    n_angles : int or None
        Angle grid over one revolution (None: every sample).

    Returns
    -------
    numpy.ndarray
        (n, 3) force [N].
    """
    t = np.asarray(time_s, float)
    if t.ndim != 1 or not np.all(np.isfinite(t)):
        raise ValueError("time_s must be a finite 1-D array")
    rot = start_angle_rad + 2 * math.pi * cond.spindle_rpm / 60.0 * t
    if n_angles is not None and t.size > n_angles:
        grid = np.linspace(0.0, 2 * math.pi, int(n_angles), endpoint=False)
        table = _forces_at_angles(grid, tool, cond, coeffs, n_slices)
        wrapped = rot % (2 * math.pi)
        return np.column_stack(
            [np.interp(wrapped, grid, table[:, i], period=2 * math.pi) for i in range(3)]
        )
    return _forces_at_angles(rot, tool, cond, coeffs, n_slices)


def _forces_at_angles(rot, tool, cond, coeffs, n_slices):
    phi_st, phi_ex = engagement_angles(tool, cond)
    n_fl = int(tool.n_flutes)
    dz = cond.axial_depth_m / n_slices
    z = (np.arange(n_slices) + 0.5) * dz
    lag = 2 * math.tan(math.radians(tool.helix_deg)) / tool.diameter_m * z  # (n_slices,)
    pitch = 2 * math.pi / n_fl
    lam = math.radians(tool.runout_angle_deg)
    radius = tool.runout_m * np.cos(lam - pitch * np.arange(n_fl))
    dr = radius - np.roll(radius, 1)  # R_j - R_{j-1}
    out = np.zeros((rot.size, 3))
    for j in range(n_fl):
        phi = (rot[:, None] + pitch * j - lag[None, :]) % (2 * math.pi)  # (n, n_slices)
        engaged = (phi >= phi_st) & (phi <= phi_ex)
        h = cond.feed_per_tooth_m * np.sin(phi) + dr[j]
        cutting = engaged & (h > 0)
        h = np.where(cutting, h, 0.0)
        on = cutting.astype(float)
        dft = (coeffs.ktc * h + coeffs.kte * on) * dz
        dfr = (coeffs.krc * h + coeffs.kre * on) * dz
        dfa = (coeffs.kac * h + coeffs.kae * on) * dz
        c, s = np.cos(phi), np.sin(phi)
        out[:, 0] += np.sum(-dft * c - dfr * s, axis=1)
        out[:, 1] += np.sum(dft * s - dfr * c, axis=1)
        out[:, 2] += np.sum(dfa, axis=1)
    return out
