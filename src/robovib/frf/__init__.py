"""Frequency response functions from force/response time series (thesis §3.2.1, Eq. 3-5).

Names are imported on first use (PEP 562): ``robovib.frf.core`` (NumPy only) does not pay for
SciPy's signal module, which the estimators need.
"""

from .._lazy import lazy_exports

_WHERE = {
    "BandTooShortError": "resolution",
    "FRF": "core",
    "FRFCurve": "plot",
    "HitReport": "impact",
    "HitSegmentation": "segment",
    "ImpactResult": "impact",
    "PlausibleRanges": "plausibility",
    "RESPONSE_TO_QUANTITY": "core",
    "SpectralDensities": "estimate",
    "check_frf_level": "plausibility",
    "check_hit": "impact",
    "check_lines_in_band": "resolution",
    "check_levels": "plausibility",
    "estimate_frf": "estimate",
    "impact_frf": "impact",
    "impact_compliance_frf": "impact",
    "noise_level": "impact",
    "overload_reason": "impact",
    "plot_frf": "plot",
    "segment_hits": "segment",
    "spectral_densities": "estimate",
    "to_compliance": "core",
    "unwrapped_phase_deg": "plot",
}

__all__ = sorted(_WHERE)


__getattr__, __dir__ = lazy_exports(__name__, _WHERE)
