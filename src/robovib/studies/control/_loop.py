"""One closed-loop run of the virtual robot, as the studies read it."""

from __future__ import annotations

from ...sim import run_closed_loop

__all__ = ["true_displacement"]


def true_displacement(robot, move, force, controller, rng, channel, **sensor):
    """The true displacement record (n, 3) [m] of one closed-loop run at 1 kHz, or the error.

    Parameters
    ----------
    robot, move, force, controller, rng, channel, **sensor
        As :func:`robovib.sim.run_closed_loop` (1 kHz, ``controller`` None = open loop).

    Returns
    -------
    tuple
        ``(displacement, None)``, or ``(None, message)`` when the loop went unstable.
    """
    try:
        rec = run_closed_loop(robot, move, force, 1000.0, controller, channel=channel, rng=rng,
                              **sensor)  # fmt: skip
        return rec.true_displacement_m, None
    except ValueError as exc:
        return None, str(exc)
