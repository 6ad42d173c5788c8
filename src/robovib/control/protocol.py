"""The two protocols a vibration controller follows (structural typing, no base class).

* :class:`Controller` — a controller of a *planned* run (the simulator's and the studies'):
  ``reset(coords, period_s, sample_rate_hz)`` once with the pose coordinates of every command
  instant (path distances (n_cmd,) [m], workspace poses (n_cmd, 3), or a
  :class:`~robovib.control.controllers.PathCursor` that is moved at each step), then
  ``command(k, tracker_m, force_n) -> (3,)`` at command instant ``k`` with the tracker [m]
  and force [N] samples (m, 3) of the period that ends now, returning the correction [m].
  Every class of :mod:`robovib.control.controllers` and :mod:`robovib.control.adaptive`
  follows it.
* :class:`StepController` — a controller at run time (what a KUKA RSI/EKI bridge calls):
  ``reset()`` then ``step(measurement) -> (3,)`` correction [mm], one call per command
  cycle; :class:`~robovib.control.runtime.RuntimeController` follows it.
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np

__all__ = ["Controller", "StepController"]


@runtime_checkable
class Controller(Protocol):
    """A controller of a planned run (see the module docs)."""

    def reset(self, coords, period_s: float, sample_rate_hz: float) -> None:
        """Prepare a run with the coordinates of every command instant."""

    def command(self, k: int, tracker_m: np.ndarray, force_n: np.ndarray) -> np.ndarray:
        """The correction [m] (3,) at command instant ``k``."""


@runtime_checkable
class StepController(Protocol):
    """A run-time controller, one call per command cycle (see the module docs)."""

    def reset(self) -> None:
        """Forget the past: a new cut starts."""

    def step(self, measurement) -> np.ndarray:
        """The correction [mm] (3,) for this cycle's measurement."""
