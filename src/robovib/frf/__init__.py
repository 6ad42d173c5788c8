"""Frequency response functions from force/response time series (thesis §3.2.1, Eq. 3-5).

Names are imported on first use (PEP 562): ``robovib.frf.core`` (NumPy only) does not pay for
SciPy's signal module, which the estimators need.
"""

from importlib import import_module

_WHERE = {
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
    "check_levels": "plausibility",
    "estimate_frf": "estimate",
    "impact_frf": "impact",
    "noise_level": "impact",
    "overload_reason": "impact",
    "plot_frf": "plot",
    "segment_hits": "segment",
    "spectral_densities": "estimate",
    "to_compliance": "core",
    "unwrapped_phase_deg": "plot",
}

__all__ = sorted(_WHERE)


def __getattr__(name: str):
    if name in _WHERE:
        value = getattr(import_module(f".{_WHERE[name]}", __name__), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(_WHERE))
