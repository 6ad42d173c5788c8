"""Unit labels of measurement files -> SI factors (conversions happen here, at the edge)."""

from __future__ import annotations

__all__ = ["QUANTITY_OF_UNIT", "from_si", "si_factor", "to_si"]

_G = 9.80665

# label -> (quantity, factor to SI)
_UNITS: dict[str, tuple[str, float]] = {
    "n": ("force", 1.0),
    "kn": ("force", 1e3),
    "lbf": ("force", 4.4482216152605),
    "m": ("displacement", 1.0),
    "mm": ("displacement", 1e-3),
    "um": ("displacement", 1e-6),
    "µm": ("displacement", 1e-6),
    "m/s": ("velocity", 1.0),
    "mm/s": ("velocity", 1e-3),
    "m/s^2": ("acceleration", 1.0),
    "m/s2": ("acceleration", 1.0),
    "m/s²": ("acceleration", 1.0),
    "mm/s^2": ("acceleration", 1e-3),
    "g": ("acceleration", _G),
    "s": ("time", 1.0),
    "ms": ("time", 1e-3),
}
QUANTITY_OF_UNIT = {k: v[0] for k, v in _UNITS.items()}


def si_factor(label: str, expected: str | None = None) -> tuple[str, float]:
    """(quantity, factor) for a unit label such as ``"g"`` or ``"mm/s^2"``.

    Raises ``ValueError`` for unknown labels, or when the quantity differs from ``expected``.
    Voltage labels (V, mV) need a sensor sensitivity: convert with :func:`apply_sensitivity`.

    Parameters
    ----------
    label : str
        The unit label.
    expected : str, optional
        The quantity the label must be of.

    Returns
    -------
    quantity : str
        ``"force"``, ``"acceleration"``, ``"velocity"``, ``"displacement"`` ...
    factor : float
        Multiplier to SI.
    """
    key = label.strip().lower().replace(" ", "")
    if key not in _UNITS:
        raise ValueError(
            f"unknown unit {label!r}; known: {', '.join(sorted(_UNITS))} "
            "(voltage channels need a sensitivity, e.g. --force-sensitivity 2.25 mV/N)"
        )
    quantity, factor = _UNITS[key]
    if expected is not None and quantity != expected:
        raise ValueError(f"unit {label!r} is a {quantity} unit, expected a {expected} unit")
    return quantity, factor


def apply_sensitivity(values, voltage_label: str, sensitivity: float, per_unit: str):
    """Convert a voltage channel to SI: ``values [V or mV] / sensitivity [mV per per_unit]``.

    Parameters
    ----------
    values : array_like
        The channel's values in ``voltage_label``.
    voltage_label : {"V", "mV"}
        Their unit.
    sensitivity : float
        Sensor sensitivity [mV per ``per_unit``].
    per_unit : str
        Physical unit of the sensitivity (``"N"``, ``"g"``, ``"m/s^2"`` ...).

    Returns
    -------
    quantity : str
        The physical quantity.
    values : numpy.ndarray
        The values in SI.
    """
    key = voltage_label.strip().lower()
    if key not in ("v", "mv"):
        raise ValueError(f"{voltage_label!r} is not a voltage unit (V or mV)")
    if not sensitivity or sensitivity <= 0:
        raise ValueError(f"sensitivity must be positive, got {sensitivity!r}")
    mv = values * (1e3 if key == "v" else 1.0)
    quantity, factor = si_factor(per_unit)
    return quantity, mv / sensitivity * factor


def _scale(value, factor: float, to_si: bool):
    """``value * factor`` (to SI) or ``value / factor``, exact for the decimal prefixes: a
    factor 1e-3 divides by 1000 (``x / 1000 == x / 1e3``, not ``x * 1e-3``)."""
    inverse = 1.0 / factor
    if factor < 1.0 and inverse == round(inverse):
        return value / round(inverse) if to_si else value * round(inverse)
    return value * factor if to_si else value / factor


def to_si(value, unit: str):
    """A value given in ``unit`` (a label of :func:`si_factor`: ``"mm"``, ``"ms"``, ``"mm/s"``
    ...) in SI: the one place option values in other units are converted.

    Parameters
    ----------
    value : float or numpy.ndarray
        The value(s) in ``unit``.
    unit : str
        Their unit.

    Returns
    -------
    float or numpy.ndarray
        The value(s) in SI (m, s, m/s ...).

    Examples
    --------
    >>> to_si(25.4, "mm"), to_si(10.0, "ms")
    (0.0254, 0.01)
    """
    return _scale(value, si_factor(unit)[1], to_si=True)


def from_si(value, unit: str):
    """An SI value in ``unit`` (the inverse of :func:`to_si`), e.g. a depth [m] shown in mm.

    Parameters
    ----------
    value : float or numpy.ndarray
        The value(s) in SI.
    unit : str
        The unit wanted (a label of :func:`si_factor`).

    Returns
    -------
    float or numpy.ndarray
        The value(s) in ``unit``.

    Examples
    --------
    >>> from_si(0.0254, "mm"), from_si(0.0015, "ms")
    (25.4, 1.5)
    """
    return _scale(value, si_factor(unit)[1], to_si=False)
