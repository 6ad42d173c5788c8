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
peak compliance (FRF)         6e-7 - 1e-3 m/N      the resonance peak of a robot's tool tip
                                                   (see below); 1e-3 m/N: very soft robots
============================  ===================  ================================================

**Peak compliance, the lower bound.** A normal-level accelerometer in g labelled m/s² passes
the level checks (its peak reads 9.81x low but inside the wide sensor range) and gives an FRF
9.81x too small: the robot looks 9.81x stiffer. Only the FRF itself can tell, at the dominant
resonance, where the peak compliance ``1 / (2 zeta k) = 1 / (c w_n)`` is set by the robot's
structure. The thesis' KR500-3 (Table A1, 180 rows x 3 directions, corrected stiffness
reading): 0.79-4.0 µm/N (stiffness 0.65-7 MN/m, damping ratio 5-25 %); the virtual robot
(:mod:`robovib.sim`, workspace and path, dominant mode): 0.82-4.6 µm/N. Read 9.81x too small
the same modes give 0.08-0.47 µm/N, all below the default 0.6 µm/N, which sits between the
two (about 1.3x below the stiffest thesis mode, 1.3x above the most compliant one read in
g). A machine-tool spindle (1e-8 - 1e-7 m/N) — or a robot ~50x stiffer than an industrial
one — is not what this toolkit measures. A stiffer robot (a machining robot near
0.5 µm/N) sets its own range: ``--compliance-range LOW HIGH`` on ``robovib frf compute`` and
``robovib campaign process``, or :class:`PlausibleRanges` in code; ``--no-level-check`` turns
every level check off. The lower bound is applied only where the largest |H| is a
resonance peak inside the band (not at its first or last line): a band that leaves out the
dominant mode has no peak to judge.

A level outside its range is reported with the unit mix-ups that would bring it inside
(``kN labelled N`` and so on, the likeliest first); the campaign and ``robovib frf compute``
make it an error that names them.
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
#: typical peak compliance of a robot's dominant mode [m/N] (geometric middle of the thesis
#: KR500-3 and virtual robot range, 0.79-4.6 µm/N): ranks the likely mix-ups of a compliance.
_TYPICAL_COMPLIANCE_M_PER_N = 1.9e-6
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
        Largest FRF magnitude as compliance in the analysed band [m/N] (the resonance peak;
        the lower bound applies only where that peak lies inside the band).
    """

    peak_force_n: tuple[float, float] = (5.0, 5e4)
    peak_acceleration_m_per_s2: tuple[float, float] = (1e-3, 1e4)
    peak_velocity_m_per_s: tuple[float, float] = (1e-6, 10.0)
    peak_displacement_m: tuple[float, float] = (1e-9, 1e-2)
    peak_compliance_m_per_n: tuple[float, float] = (6e-7, 1e-3)

    def __post_init__(self) -> None:
        for name in self.__dataclass_fields__:
            lo, hi = getattr(self, name)
            if not (np.isfinite(lo) and np.isfinite(hi) and 0 <= lo < hi):
                raise ValueError(f"{name} must be a range 0 <= low < high, got ({lo}, {hi})")

    def range_of(self, quantity: str) -> tuple[float, float]:
        """The range of ``force``, ``acceleration``, ``velocity``, ``displacement`` or
        ``compliance``.

        Parameters
        ----------
        quantity : str
            One of the five quantities.

        Returns
        -------
        tuple of float
            (low, high) in SI.
        """
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
    fits = [
        (words, factor)
        for words, factor in _MIXUPS[quantity]
        if factor is not None and lo <= value * factor <= hi
    ]
    if quantity == "compliance":  # the likeliest first: nearest a robot's typical peak
        fits.sort(key=lambda w: abs(np.log(value * w[1] / _TYPICAL_COMPLIANCE_M_PER_N)))
    likely = [words for words, _ in fits]
    if quantity == "force" and value < lo and not likely:
        likely = [_MIXUPS["force"][2][0]]
    hint = f"; likely {' or '.join(likely)}" if likely else ""
    if quantity == "compliance":
        what = f"{what} {value:.3g} {unit} (dynamic stiffness {1 / value:.3g} N/m at the peak)"
    else:
        what = f"{what} {value:.3g} {unit}"
    return (
        f"{what} is {side} the plausible {lo:g}-{hi:g} {unit} of a hammer "
        f"test on a robot{hint} (check the file's units, or override the range"
        + (": --compliance-range LOW HIGH)" if quantity == "compliance" else ")")
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
        The message when the largest |H| lies above ``peak_compliance_m_per_n``, or below it
        while being a resonance peak inside the band (not at its first or last line): a
        normal-level response in g labelled m/s² makes the robot look 9.81x stiffer.

    Examples
    --------
    >>> import numpy as np
    >>> from robovib.frf import FRF
    >>> f = np.arange(5.0, 60.0, 0.5)
    >>> w, wn = 2 * np.pi * f, 2 * np.pi * 16.0  # 16 Hz, 2 MN/m, 5 %: peak 5 µm/N
    >>> h = 1 / (2e6 * (1 - (w / wn) ** 2 + 2j * 0.05 * w / wn))
    >>> check_frf_level(FRF(f, h)) is None
    True
    >>> "g labelled m/s^2" in check_frf_level(FRF(f, h / 9.80665))
    True
    """
    ranges = ranges or PlausibleRanges()
    if frf.quantity != "compliance":
        raise ValueError(f"check_frf_level needs a compliance FRF, got {frf.quantity!r}")
    mag = np.abs(np.asarray(frf.values))
    i = int(np.argmax(mag))
    peak = float(mag[i])
    lo, _ = ranges.peak_compliance_m_per_n
    if peak < lo and i in (0, mag.size - 1):
        return None  # no resonance peak inside the band: nothing to judge the level by
    return _message("peak compliance", "compliance", peak, ranges)
