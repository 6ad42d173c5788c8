"""Are the levels of a hammer test physically plausible? Unit mix-ups are caught here.

A force channel in kN labelled N reads 1000x too small and gives an FRF 1000x too large;
an accelerometer in g labelled m/s² reads 9.81x too small. The file cannot say so, but the
levels can: the defaults below are what hammers and robots give (all overridable):

============================  ===================  ================================================
level                         default range        why
============================  ===================  ================================================
peak hammer force             5 N - 50 kN          below 5 N a robot is not excited above the
                                                   noise; 50 kN is beyond the largest modal
                                                   hammers (sledges: 22 kN range)
peak acceleration             1e-3 - 1e4 m/s²      accelerometer noise floor to 1000 g
peak velocity                 1e-6 - 10 m/s        vibrometer noise floor to 10 m/s
peak displacement             1e-9 - 1e-2 m        1 nm to 10 mm
peak compliance (FRF)         1e-10 - 1e-3 m/N     machine-tool spindles (1e-8) to very soft
                                                   robots (1e-5 at the dominant mode; thesis:
                                                   stiffness 1e6-1e7 N/m, damping 2-10 %)
============================  ===================  ================================================

A level outside its range is reported with the unit mix-ups that would bring it inside
(``kN labelled N`` and so on); the campaign and ``robovib frf compute`` make it an error that
names them (``--no-level-check`` or other ranges to override).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["PlausibleRanges", "check_frf_level", "check_levels"]

_G = 9.80665

#: quantity -> [(mix-up in words, factor the true value is of the value read)]
_MIXUPS = {
    "force": [
        ("a force in kN labelled N", 1e3),
        ("a force in N labelled kN", 1e-3),
        ("a force in mV/V without the hammer sensitivity", None),
    ],
    "acceleration": [
        ("a response in g labelled m/s^2", _G),
        ("a response in m/s^2 labelled g", 1 / _G),
        ("a response in mm/s^2 labelled m/s^2", 1e-3),
        ("a response in m/s^2 labelled mm/s^2", 1e3),
    ],
    "velocity": [
        ("a response in mm/s labelled m/s", 1e-3),
        ("a response in m/s labelled mm/s", 1e3),
    ],
    "displacement": [
        ("a response in mm labelled m", 1e-3),
        ("a response in um labelled m", 1e-6),
        ("a response in m labelled mm", 1e3),
    ],
    "compliance": [
        ("a force in kN labelled N", 1e-3),
        ("a force in N labelled kN", 1e3),
        ("a response in g labelled m/s^2", _G),
        ("a response in m/s^2 labelled g", 1 / _G),
        ("a response in mm/s^2 labelled m/s^2 (or mm labelled m)", 1e-3),
    ],
}
_UNIT = {"force": "N", "acceleration": "m/s^2", "velocity": "m/s", "displacement": "m",
         "compliance": "m/N"}  # fmt: skip


@dataclass(frozen=True)
class PlausibleRanges:
    """Plausible peak levels of a hammer test on a robot (SI; see the module table).

    Attributes
    ----------
    peak_force_n
        Peak hammer force [N].
    peak_acceleration_m_per_s2, peak_velocity_m_per_s, peak_displacement_m
        Peak response of the measured quantity.
    peak_compliance_m_per_n
        Largest FRF magnitude as compliance in the analysed band [m/N].
    """

    peak_force_n: tuple[float, float] = (5.0, 5e4)
    peak_acceleration_m_per_s2: tuple[float, float] = (1e-3, 1e4)
    peak_velocity_m_per_s: tuple[float, float] = (1e-6, 10.0)
    peak_displacement_m: tuple[float, float] = (1e-9, 1e-2)
    peak_compliance_m_per_n: tuple[float, float] = (1e-10, 1e-3)

    def __post_init__(self) -> None:
        for name in self.__dataclass_fields__:
            lo, hi = getattr(self, name)
            if not (np.isfinite(lo) and np.isfinite(hi) and 0 <= lo < hi):
                raise ValueError(f"{name} must be a range 0 <= low < high, got ({lo}, {hi})")

    def range_of(self, quantity: str) -> tuple[float, float]:
        """The range of ``force``, ``acceleration``, ``velocity``, ``displacement`` or
        ``compliance``."""
        return {
            "force": self.peak_force_n,
            "acceleration": self.peak_acceleration_m_per_s2,
            "velocity": self.peak_velocity_m_per_s,
            "displacement": self.peak_displacement_m,
            "compliance": self.peak_compliance_m_per_n,
        }[quantity]


def _message(what: str, quantity: str, value: float, ranges: PlausibleRanges) -> str | None:
    lo, hi = ranges.range_of(quantity)
    if lo <= value <= hi:
        return None
    unit = _UNIT[quantity]
    side = "below" if value < lo else "above"
    likely = [
        words
        for words, factor in _MIXUPS[quantity]
        if factor is not None and lo <= value * factor <= hi
    ]
    if quantity == "force" and value < lo and not likely:
        likely = [_MIXUPS["force"][2][0]]
    hint = f"; likely {' or '.join(likely)}" if likely else ""
    return (
        f"{what} {value:.3g} {unit} is {side} the plausible {lo:g}-{hi:g} {unit} of a hammer "
        f"test on a robot{hint} (check the file's units, or override the range)"
    )


def check_levels(
    forces_n, responses, response_quantity: str, ranges: PlausibleRanges | None = None
) -> tuple[str, ...]:
    """Implausible levels of a hammer recording, each with the likely unit mix-up.

    Parameters
    ----------
    forces_n
        (n_hits, n) forces [N].
    responses
        (n_hits, n) responses in SI of ``response_quantity``.
    response_quantity
        ``"acceleration"``, ``"velocity"`` or ``"displacement"``.
    ranges
        The plausible ranges (default :class:`PlausibleRanges`).

    Returns
    -------
    tuple of str
        One message per implausible level (median over the hits of each hit's peak); empty
        when all are plausible.

    Examples
    --------
    >>> import numpy as np
    >>> f = np.zeros((2, 64)); f[:, 3] = 0.6  # a 600 N hit written in kN, labelled N
    >>> "kN labelled N" in check_levels(f, 0.01 * f, "acceleration")[0]
    True
    """
    ranges = ranges or PlausibleRanges()
    f = np.atleast_2d(np.asarray(forces_n, float))
    r = np.atleast_2d(np.asarray(responses, float))
    out = []
    msg = _message(
        "peak hammer force", "force", float(np.median(np.max(np.abs(f), axis=1))), ranges
    )
    if msg:
        out.append(msg)
    if response_quantity not in ("acceleration", "velocity", "displacement"):
        raise ValueError(f"unknown response quantity {response_quantity!r}")
    peak_r = float(np.median(np.max(np.abs(r), axis=1)))
    msg = _message(f"peak {response_quantity}", response_quantity, peak_r, ranges)
    if msg:
        out.append(msg)
    return tuple(out)


def check_frf_level(frf, ranges: PlausibleRanges | None = None) -> str | None:
    """An implausible FRF magnitude (as compliance), with the likely unit mix-up, or None.

    Parameters
    ----------
    frf
        :class:`robovib.frf.FRF` of quantity ``"compliance"``.
    ranges
        The plausible ranges (default :class:`PlausibleRanges`).

    Returns
    -------
    str or None
        The message when the largest |H| lies outside ``peak_compliance_m_per_n``.
    """
    ranges = ranges or PlausibleRanges()
    if frf.quantity != "compliance":
        raise ValueError(f"check_frf_level needs a compliance FRF, got {frf.quantity!r}")
    return _message("peak compliance", "compliance", float(np.max(np.abs(frf.values))), ranges)
