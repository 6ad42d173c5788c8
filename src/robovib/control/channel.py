"""What a command channel allows a state-feedback controller (thesis §4.3.2).

The closed/open amplitude ratio of the thesis' offset-mass experiment through a command channel:
:func:`sensitivity_bound` (the floor any non-amplifying channel allows, or one channel's),
:func:`required_channel_gain` (the channel gain a target ratio needs) and
:func:`operating_mode` (the single mode behind measured open-loop amplitudes). A channel is
anything with ``frequency_response(f_hz, period_s)``, e.g. :class:`robovib.sim.CommandChannel`;
the studies (:mod:`robovib.studies.control`) run them on the virtual robot.
"""

from __future__ import annotations

import math

import numpy as np

from ..modal.parameters import ModalParameters

__all__ = [
    "THESIS_OFFSET_MASS_GAINS",
    "THESIS_OFFSET_MASS_MODE",
    "operating_mode",
    "required_channel_gain",
    "sensitivity_bound",
]

#: §4.3.2: the Y-direction mode measured at the offset-mass pose (8.5 Hz, 0.775 MN/m, 0.179).
THESIS_OFFSET_MASS_MODE = ModalParameters(8.5, 0.775e6, 0.179)
#: §4.3.2 gains (w1, w2) the thesis computed for that mode.
THESIS_OFFSET_MASS_GAINS = (0.079, 0.0059)


def _thesis_loop(speeds_hz, mode: ModalParameters, gains, period_s: float):
    """``(P, C)`` at ``speeds_hz``: the mode's correction-to-tip FRF and the thesis controller
    (w1 + w2 x backward difference over one command period, half a period of ZOH lag)."""
    f = np.asarray(speeds_hz, float)
    s = 2j * np.pi * f
    wn, z = mode.omega_n, mode.damping_ratio
    p = wn**2 / (s**2 + 2 * z * wn * s + wn**2)
    c = (gains[0] + gains[1] * (1 - np.exp(-s * period_s)) / period_s) * np.exp(-s * period_s / 2)
    return p, c


def sensitivity_bound(
    speeds_hz,
    mode: ModalParameters = THESIS_OFFSET_MASS_MODE,
    gains=THESIS_OFFSET_MASS_GAINS,
    period_s: float = 0.004,
    channel=None,
) -> np.ndarray:
    """Closed/open amplitude ratio ``|S|`` of ``gains`` at ``speeds_hz``: a floor, or one channel's.

    Without ``channel``: the smallest ratio any channel that does not amplify
    (``|G_a| <= 1``: any delay, lag, rate limit or breakaway) allows,
    ``|S| = 1 / |1 + P G_a C| >= 1 / (1 + |P| |C|)``, with ``P`` the mode's correction-to-tip
    FRF and ``C`` the controller (w1 + w2 x backward difference, ZOH). With ``channel``: the
    ratio through its linear part (:meth:`~robovib.sim.CommandChannel.frequency_response`),
    a frequency-domain approximation of the sampled loop.

    Parameters
    ----------
    speeds_hz
        Excitation frequencies [Hz] (spindle speed / 60 for the offset mass).
    mode
        The plant mode (default §4.3.2's measured mode).
    gains
        State-feedback gains (w1, w2).
    period_s
        Command period [s].
    channel
        A command channel (anything with ``frequency_response(f_hz, period_s)``, e.g.
        :class:`robovib.sim.CommandChannel`); None: the bound over every non-amplifying
        channel.

    Returns
    -------
    ndarray
        Closed/open amplitude ratio at each of ``speeds_hz``.
    """
    p, c = _thesis_loop(speeds_hz, mode, gains, period_s)
    if channel is None:
        return 1.0 / (1.0 + np.abs(p) * np.abs(c))
    return 1.0 / np.abs(1.0 + p * c * channel.frequency_response(speeds_hz, period_s))


def required_channel_gain(
    speeds_hz,
    target_ratios,
    mode: ModalParameters = THESIS_OFFSET_MASS_MODE,
    gains=THESIS_OFFSET_MASS_GAINS,
    period_s: float = 0.004,
) -> np.ndarray:
    """Smallest channel gain ``|G_a|`` for which ``gains`` can reach ``target_ratios``.

    ``|1 + P G_a C| >= 1 / ratio`` needs ``|G_a| >= (1 / ratio - 1) / (|P| |C|)``, with ``P``
    the mode's correction-to-tip FRF and ``C`` the controller (see :func:`sensitivity_bound`).
    Above 1 the channel must amplify there.

    Parameters
    ----------
    speeds_hz
        Excitation frequencies [Hz].
    target_ratios
        Closed/open amplitude ratios to reach, in (0, 1], broadcast with ``speeds_hz``.
    mode
        The plant mode (default §4.3.2's measured mode).
    gains
        State-feedback gains (w1, w2).
    period_s
        Command period [s].

    Returns
    -------
    ndarray
        The smallest channel gain magnitude at each speed.

    Raises
    ------
    ValueError
        A target ratio outside (0, 1].
    """
    p, c = _thesis_loop(speeds_hz, mode, gains, period_s)
    ratio = np.asarray(target_ratios, float)
    if np.any(~np.isfinite(ratio) | (ratio <= 0) | (ratio > 1)):
        raise ValueError(f"target ratios must lie in (0, 1], got {ratio.tolist()}")
    return (1.0 / ratio - 1.0) / (np.abs(p) * np.abs(c))


def operating_mode(
    open_ptp_mm: dict[float, float],
    natural_frequency_hz: float = THESIS_OFFSET_MASS_MODE.natural_frequency_hz,
    *,
    mass_kg: float = 1.0,
    radius_m: float = 0.0508,
) -> ModalParameters:
    """Single mode (stiffness, damping) that gives measured open-loop offset-mass amplitudes.

    ``open_ptp_mm`` maps spindle speed [rpm] to the peak-to-peak open-loop vibration [mm]
    (two or more speeds); ``natural_frequency_hz`` is held (the hammer test's). With the
    force amplitude ``F = m_o L w^2`` (Eq. 27), ``ptp = 2 F |H|`` and
    ``1 / |H|^2 = k^2 (1 - r^2)^2 + 4 r^2 (k zeta)^2`` is linear in ``k^2`` and
    ``(k zeta)^2``: solved by least squares on the relative error (each row scaled by
    ``|H|^2``; exact for two speeds). §4.3.2's 0.93 / 0.36 mm give 1.105 MN/m and zeta 0.118
    at 8.5 Hz, against the hammer test's 0.775 MN/m and 0.179 (which give 0.93 / 0.50 mm).

    Parameters
    ----------
    open_ptp_mm
        Spindle speed [rpm] -> peak-to-peak open-loop amplitude [mm], two or more speeds.
    natural_frequency_hz
        Natural frequency held fixed [Hz].
    mass_kg
        Offset mass [kg].
    radius_m
        Its radius of rotation [m].

    Returns
    -------
    ModalParameters
        ``natural_frequency_hz``, the fitted stiffness [N/m] and damping ratio.

    Raises
    ------
    ValueError
        Fewer than two speeds, non-positive amplitudes, mass or radius, speeds that cannot
        separate stiffness from damping, or amplitudes no single underdamped mode at
        ``natural_frequency_hz`` can produce.
    """
    if len(open_ptp_mm) < 2:
        raise ValueError("operating_mode needs open-loop amplitudes at two or more speeds")
    rpm = np.array(list(open_ptp_mm), float)
    ptp = np.array(list(open_ptp_mm.values()), float) * 1e-3
    if not (np.all(np.isfinite(ptp)) and np.all(ptp > 0) and np.all(rpm > 0)):
        raise ValueError("open-loop amplitudes [mm] and speeds [rpm] must be finite and > 0")
    for name, v in (("mass_kg", mass_kg), ("radius_m", radius_m),
                    ("natural_frequency_hz", natural_frequency_hz)):  # fmt: skip
        if not (math.isfinite(v) and v > 0):
            raise ValueError(f"{name} must be a finite number > 0, got {v!r}")
    w = 2 * np.pi * rpm / 60.0
    h = ptp / (2 * mass_kg * radius_m * w**2)
    r = w / (2 * np.pi * natural_frequency_hz)
    design = np.column_stack([(1 - r**2) ** 2, 4 * r**2]) * (h**2)[:, None]
    if np.linalg.matrix_rank(design, tol=1e-9 * np.abs(design).max()) < 2:
        raise ValueError(
            "these speeds cannot separate stiffness from damping (their frequency ratios "
            f"to {natural_frequency_hz:g} Hz give the same equation); add another speed"
        )
    (k2, kz2), *_ = np.linalg.lstsq(design, np.ones_like(h), rcond=None)
    if not (k2 > 0 and kz2 > 0) or not np.sqrt(kz2 / k2) < 1:
        raise ValueError(
            "no single underdamped mode at "
            f"{natural_frequency_hz:g} Hz gives these open-loop amplitudes"
        )
    return ModalParameters(natural_frequency_hz, float(np.sqrt(k2)), float(np.sqrt(kz2 / k2)))
