"""Modal parameters of one mode as an immutable value with correct conversions (thesis Eq. 17, 21-22).

A single-degree-of-freedom mode in one direction::

    m x'' + c x' + k x = F,   wn = sqrt(k / m),   zeta = c / (2 m wn) = c / (2 sqrt(k m))

so ``c = 2 zeta m wn`` — the thesis prints ``c = 2 m wn / zeta`` (Eq. 22), a typo; the
physically correct relation is implemented here and everywhere in robovib.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["ModalParameters", "remove_exponential_window_damping"]


def _positive(name: str, value: float) -> float:
    value = float(value)
    if not math.isfinite(value) or value <= 0:
        raise ValueError(f"{name} must be a positive finite number, got {value!r}")
    return value


@dataclass(frozen=True)
class ModalParameters:
    """One mode: natural frequency [Hz], modal stiffness [N/m] and damping ratio [-].

    Build it from whichever triple you have: :meth:`from_mkc`, :meth:`from_fn_k_c`,
    :meth:`from_fn_k_zeta` (the constructor). All derived quantities are SI.

    Parameters
    ----------
    natural_frequency_hz : float
        Undamped natural frequency [Hz], > 0.
    stiffness_n_per_m : float
        Modal stiffness [N/m], > 0.
    damping_ratio : float
        Viscous damping ratio [-], >= 0.
    """

    natural_frequency_hz: float
    stiffness_n_per_m: float
    damping_ratio: float

    def __post_init__(self) -> None:
        _positive("natural_frequency_hz", self.natural_frequency_hz)
        _positive("stiffness_n_per_m", self.stiffness_n_per_m)
        zeta = float(self.damping_ratio)
        if not math.isfinite(zeta) or zeta < 0:
            raise ValueError(f"damping_ratio must be a finite number >= 0, got {zeta!r}")

    # -- alternative constructors --------------------------------------------------------------
    @classmethod
    def from_fn_k_zeta(cls, fn_hz: float, k_n_per_m: float, zeta: float) -> ModalParameters:
        return cls(float(fn_hz), float(k_n_per_m), float(zeta))

    @classmethod
    def from_mkc(
        cls, mass_kg: float, stiffness_n_per_m: float, damping_ns_per_m: float
    ) -> ModalParameters:
        """From modal mass m, stiffness k and damping coefficient c.

        Parameters
        ----------
        mass_kg : float
            Modal mass [kg], > 0.
        stiffness_n_per_m : float
            Modal stiffness [N/m], > 0.
        damping_ns_per_m : float
            Damping coefficient [N·s/m].

        Returns
        -------
        ModalParameters
            The mode.
        """
        m = _positive("mass_kg", mass_kg)
        k = _positive("stiffness_n_per_m", stiffness_n_per_m)
        wn = math.sqrt(k / m)
        return cls(wn / (2 * math.pi), k, float(damping_ns_per_m) / (2 * m * wn))

    @classmethod
    def from_fn_k_c(
        cls, fn_hz: float, stiffness_n_per_m: float, damping_ns_per_m: float
    ) -> ModalParameters:
        """From natural frequency, stiffness and damping coefficient (the thesis' Table A1 triple).

        Parameters
        ----------
        fn_hz : float
            Natural frequency [Hz], > 0.
        stiffness_n_per_m : float
            Modal stiffness [N/m], > 0.
        damping_ns_per_m : float
            Damping coefficient [N·s/m].

        Returns
        -------
        ModalParameters
            The mode.
        """
        fn = _positive("fn_hz", fn_hz)
        k = _positive("stiffness_n_per_m", stiffness_n_per_m)
        wn = 2 * math.pi * fn
        return cls(fn, k, float(damping_ns_per_m) * wn / (2 * k))

    # -- derived quantities --------------------------------------------------------------------
    @property
    def omega_n(self) -> float:
        """Undamped natural angular frequency [rad/s]."""
        return 2 * math.pi * self.natural_frequency_hz

    @property
    def mass_kg(self) -> float:
        """Modal mass m = k / wn^2 [kg]."""
        return self.stiffness_n_per_m / self.omega_n**2

    @property
    def damping_ns_per_m(self) -> float:
        """Damping coefficient c = 2 zeta m wn = 2 zeta k / wn [N·s/m]."""
        return 2 * self.damping_ratio * self.stiffness_n_per_m / self.omega_n

    @property
    def damped_frequency_hz(self) -> float:
        """fd = fn sqrt(1 - zeta^2) (NaN above critical damping)."""
        return (
            self.natural_frequency_hz * math.sqrt(1 - self.damping_ratio**2)
            if self.damping_ratio < 1
            else math.nan
        )

    @property
    def pole(self) -> complex:
        """Continuous-time pole -zeta wn + i wn sqrt(1 - zeta^2) [rad/s]."""
        wn, z = self.omega_n, self.damping_ratio
        return complex(-z * wn, wn * math.sqrt(max(0.0, 1 - z * z)))

    def compliance(self, frequency_hz) -> np.ndarray:
        """Receptance x/F = 1 / (k (1 - r^2 + 2 i zeta r)), r = f / fn [m/N].

        Parameters
        ----------
        frequency_hz : array_like
            Frequencies [Hz].

        Returns
        -------
        numpy.ndarray
            Complex compliance [m/N].
        """
        r = np.asarray(frequency_hz, float) / self.natural_frequency_hz
        return 1.0 / (self.stiffness_n_per_m * (1 - r**2 + 2j * self.damping_ratio * r))

    def to_dict(self) -> dict[str, float]:
        return {
            "natural_frequency_hz": self.natural_frequency_hz,
            "stiffness_n_per_m": self.stiffness_n_per_m,
            "damping_ratio": self.damping_ratio,
            "damping_ns_per_m": self.damping_ns_per_m,
            "mass_kg": self.mass_kg,
        }


def remove_exponential_window_damping(params: ModalParameters, tau_s: float) -> ModalParameters:
    """Undo the damping an exponential window ``exp(-t / tau)`` adds to a fitted mode.

    Windowing force and response with the same exponential (from the trigger) multiplies the
    impulse response by ``exp(-t/tau)``: the decay rate sigma = zeta wn grows by ``1/tau`` while
    the damped frequency and the residue (hence the modal mass) stay. So
    ``sigma = sigma' - 1/tau``, ``wn = sqrt(wd^2 + sigma^2)``, ``zeta = sigma / wn``,
    ``k = m wn^2`` with ``m`` unchanged.

    Parameters
    ----------
    params : ModalParameters
        The mode fitted to the windowed FRF.
    tau_s : float
        Time constant of the exponential window [s], > 0.

    Returns
    -------
    ModalParameters
        The mode without the window's damping.
    """
    tau = _positive("tau_s", tau_s)
    wn_w = params.omega_n
    sigma_w = params.damping_ratio * wn_w
    wd = wn_w * math.sqrt(max(0.0, 1 - params.damping_ratio**2))
    sigma = sigma_w - 1.0 / tau
    if sigma < 0:
        raise ValueError(
            f"the exponential window (tau = {tau:g} s) adds more damping (sigma = {1 / tau:.4g} 1/s) "
            f"than was fitted (sigma = {sigma_w:.4g} 1/s): the fit or tau is wrong"
        )
    wn = math.sqrt(wd**2 + sigma**2)
    mass = params.mass_kg
    return ModalParameters(wn / (2 * math.pi), mass * wn**2, sigma / wn)
