"""Regenerative milling on the virtual robot: the time-domain simulation of
:mod:`robovib.milling.time_domain`, re-exported where the virtual robot's other simulations live."""

from ..milling.time_domain import (
    RegenerativeCut,
    simulate_regenerative_cut,
    simulated_stability_limit,
)

__all__ = ["RegenerativeCut", "simulate_regenerative_cut", "simulated_stability_limit"]
