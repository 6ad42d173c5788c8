"""Frequency response functions from force/response time series (thesis §3.2.1, Eq. 3-5)."""

from .core import FRF, RESPONSE_TO_QUANTITY, to_compliance
from .estimate import SpectralDensities, estimate_frf, spectral_densities
from .impact import HitReport, ImpactResult, check_hit, impact_frf

__all__ = [
    "FRF",
    "RESPONSE_TO_QUANTITY",
    "HitReport",
    "ImpactResult",
    "SpectralDensities",
    "check_hit",
    "estimate_frf",
    "impact_frf",
    "spectral_densities",
    "to_compliance",
]
