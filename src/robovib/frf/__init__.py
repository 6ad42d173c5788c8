"""Frequency response functions from force/response time series (thesis §3.2.1, Eq. 3-5)."""

from .core import FRF, RESPONSE_TO_QUANTITY, to_compliance
from .estimate import SpectralDensities, estimate_frf, spectral_densities
from .impact import HitReport, ImpactResult, check_hit, impact_frf, noise_level, overload_reason
from .plausibility import PlausibleRanges, check_frf_level, check_levels
from .plot import FRFCurve, plot_frf, unwrapped_phase_deg
from .segment import HitSegmentation, segment_hits

__all__ = [
    "FRF",
    "RESPONSE_TO_QUANTITY",
    "FRFCurve",
    "HitReport",
    "HitSegmentation",
    "ImpactResult",
    "PlausibleRanges",
    "SpectralDensities",
    "check_frf_level",
    "check_hit",
    "check_levels",
    "estimate_frf",
    "impact_frf",
    "noise_level",
    "overload_reason",
    "plot_frf",
    "segment_hits",
    "spectral_densities",
    "to_compliance",
    "unwrapped_phase_deg",
]
