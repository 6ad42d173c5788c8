"""Modal parameters and their identification from FRFs (thesis §3.2.1, Eq. 17).

Names are imported on first use (PEP 562): ``robovib.modal.parameters`` (NumPy only) does not pay
for the FRF estimators and SciPy's signal module, which the fits need.
"""

from .._lazy import lazy_exports

_WHERE = {
    "FRFFits": "fits",
    "ModalFit": "sdof",
    "ModalFitWarning": "lscf",
    "ModalParameters": "parameters",
    "MultiModeFit": "lscf",
    "StabilizationDiagram": "lscf",
    "fit_dominant_mode": "sdof",
    "fit_frfs": "fits",
    "fit_modes": "lscf",
    "half_power_estimate": "sdof",
    "lscf_poles": "lscf",
    "lsfd_residues": "lscf",
    "remove_exponential_window_damping": "parameters",
    "select_stable_modes": "lscf",
    "stabilization_diagram": "lscf",
}

__all__ = sorted(_WHERE)


__getattr__, __dir__ = lazy_exports(__name__, _WHERE)
