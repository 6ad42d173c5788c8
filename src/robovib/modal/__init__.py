"""Modal parameters and their identification from FRFs (thesis §3.2.1, Eq. 17).

Names are imported on first use (PEP 562): ``robovib.modal.parameters`` (NumPy only) does not pay
for the FRF estimators and SciPy's signal module, which the fits need.
"""

from importlib import import_module

_WHERE = {
    "ModalFit": "sdof",
    "ModalFitWarning": "lscf",
    "ModalParameters": "parameters",
    "MultiModeFit": "lscf",
    "StabilizationDiagram": "lscf",
    "fit_dominant_mode": "sdof",
    "fit_modes": "lscf",
    "half_power_estimate": "sdof",
    "lscf_poles": "lscf",
    "lsfd_residues": "lscf",
    "remove_exponential_window_damping": "parameters",
    "select_stable_modes": "lscf",
    "stabilization_diagram": "lscf",
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
