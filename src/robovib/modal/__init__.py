"""Modal parameters and their identification from FRFs (thesis §3.2.1, Eq. 17)."""

from .lscf import (
    ModalFitWarning,
    MultiModeFit,
    StabilizationDiagram,
    fit_modes,
    lscf_poles,
    lsfd_residues,
    select_stable_modes,
    stabilization_diagram,
)
from .parameters import ModalParameters, remove_exponential_window_damping
from .sdof import ModalFit, fit_dominant_mode, half_power_estimate

__all__ = [
    "ModalFit",
    "ModalFitWarning",
    "ModalParameters",
    "MultiModeFit",
    "StabilizationDiagram",
    "fit_dominant_mode",
    "fit_modes",
    "half_power_estimate",
    "lscf_poles",
    "lsfd_residues",
    "remove_exponential_window_damping",
    "select_stable_modes",
    "stabilization_diagram",
]
