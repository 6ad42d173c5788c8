"""The two protocols a vibration controller follows (structural typing, no base class).

* :class:`Controller` — a controller of a *planned* run (the simulator's and the studies'):
  ``reset(coords, period_s, sample_rate_hz)`` once with the pose coordinates of every command
  instant (path distances (n_cmd,) [m], workspace poses (n_cmd, 3), or a
  :class:`~robovib.control.controllers.PathCursor` that is moved at each step), then
  ``command(k, tracker_m, force_n) -> (3,)`` at command instant ``k`` with the tracker [m]
  and force [N] samples (m, 3) of the period that ends now, returning the correction [m].
  Every class of :mod:`robovib.control.controllers` and :mod:`robovib.control.adaptive`
  follows it, and :class:`~robovib.control.guard.FadeGuard`.
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
        """Prepare a run with the coordinates of every command instant.

        Parameters
        ----------
        coords : array_like or PathCursor
            (n_cmd,) path distances [m], (n_cmd, 3) poses, or a cursor.
        period_s : float
            Command period [s].
        sample_rate_hz : float
            Sensor sample rate [Hz].
        """

    def command(self, k: int, tracker_m: np.ndarray, force_n: np.ndarray) -> np.ndarray:
        """The correction at command instant ``k``.

        Parameters
        ----------
        k : int
            Command instant.
        tracker_m : numpy.ndarray
            (m, 3) tracker samples of the period [m].
        force_n : numpy.ndarray
            (m, 3) force samples of the period [N].

        Returns
        -------
        numpy.ndarray
            (3,) correction [m].
        """


@runtime_checkable
class StepController(Protocol):
    """A run-time controller, one call per command cycle (see the module docs)."""

    def reset(self) -> None:
        """Forget the past: a new cut starts."""

    def step(self, measurement) -> np.ndarray:
        """The correction for this cycle's measurement.

        Parameters
        ----------
        measurement : object
            Force [N] and tracker [mm] samples and the path coordinate [m].

        Returns
        -------
        numpy.ndarray
            (3,) correction [mm].
        """
