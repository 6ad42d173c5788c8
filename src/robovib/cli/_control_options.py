"""Options shared by the closed-loop commands (``control simulate``, ``sim mill``)."""

from __future__ import annotations

from typing import Annotated

import typer

from ._common import fail

__all__ = ["ActuatorOpt", "ControllerOpt", "DisturbanceOpt", "parse_disturbances"]

ControllerOpt = Annotated[
    list[str] | None,
    typer.Option(
        "--controller",
        help="Controller(s), repeatable: thesis, constant-start, constant-end, tuned, lqg, "
        "robust, feedforward, feedforward+robust, repetitive, adaptive (period tracking, "
        "adaptive harmonics, fade-out guard), adaptive+robust, adaptive-feedforward, "
        "adaptive+force (adaptive + runout lines + feedforward of the measured force through "
        "the pose model; recommended for real cuts). Default: all.",
    ),
]
ActuatorOpt = Annotated[
    str,
    typer.Option(
        help="Command channel: pure-delay (32 ms; the §4.3.2 'calibrated' channel is "
        "withdrawn: no channel of gain <= 1 reproduces it)."
    ),
]
DisturbanceOpt = Annotated[
    list[str] | None,
    typer.Option(
        "--disturbance",
        help="A real-cut disturbance NAME=VALUE, repeatable. speed_error_pct, speed_drift_pct "
        "(%), runout_um (µm), nonperiodic_rel (x force std), engagement_pct (%), force_noise_n, "
        "force_bias_n (N), actuator_gain_pct (%), delay_error_ms (ms); all=F: every one at F x "
        "its realistic level. All off by default.",
    ),
]


def parse_disturbances(items: list[str] | None):
    """The :class:`~robovib.sim.CutDisturbances` of ``--disturbance`` items (error: exit 1)."""
    from ..sim import CutDisturbances

    try:
        return CutDisturbances.parse(items or [])
    except ValueError as exc:
        fail(str(exc))


def pose_option(text: str, option: str) -> list[float]:
    """Comma-separated numbers of a pose option (``--start``, ``--end``); a one-line error else.

    Parameters
    ----------
    text : str
        The option's value.
    option : str
        The option's name, for the message.

    Returns
    -------
    list of float
        The numbers.
    """
    try:
        return [float(v) for v in text.split(",")]
    except ValueError:
        fail(f"{option} must be comma-separated numbers, got {text!r}")
