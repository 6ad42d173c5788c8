"""One pose unit convention for every pose model: units live in the input names.

A pose model records its inputs with their unit as suffix (``"x_mm"``, ``"x_m"``,
``"rz_deg"``, ``"s_m"``; saved in its file's ``input_names``): :class:`robovib.gp.PoseModalModel`
of the thesis' Table A1 takes millimetres, :class:`robovib.hybrid.FRFPoseModel` metres, and
neither file changes. Callers never convert by hand: :func:`pose_in_units` takes values named
with their own units and returns the pose in the model's.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np

__all__ = ["pose_in_units", "split_unit"]

#: Unit suffix -> (dimension, factor to the dimension's reference unit: m or deg).
_UNITS = {
    "m": ("length", 1.0),
    "mm": ("length", 1e-3),
    "um": ("length", 1e-6),
    "deg": ("angle", 1.0),
    "rad": ("angle", 180.0 / math.pi),
}


def split_unit(name: str) -> tuple[str, str]:
    """An input name split into quantity and unit: ``"x_mm"`` -> ``("x", "mm")``.

    Parameters
    ----------
    name
        ``<quantity>_<unit>`` with a unit of m, mm, um, deg or rad.

    Returns
    -------
    tuple of str
        The quantity and the unit.

    Raises
    ------
    ValueError
        No unit suffix, or a unit other than those above.

    Examples
    --------
    >>> split_unit("rz_deg")
    ('rz', 'deg')
    """
    stem, _, unit = name.rpartition("_")
    if not stem or unit not in _UNITS:
        raise ValueError(
            f"pose input {name!r} must be <quantity>_<unit> with a unit of {', '.join(_UNITS)}"
        )
    return stem, unit


def pose_in_units(
    input_names: Sequence[str],
    values: Mapping[str, float | None],
    labels: Mapping[str, str] | None = None,
) -> np.ndarray:
    """The pose in a model's input units from values named with their own units.

    Parameters
    ----------
    input_names
        The model's inputs (``model.input_names``), e.g. ``("x_m", "y_m", "rz_deg")``.
    values
        Quantity with its unit -> value, e.g. ``{"x_mm": 1200.0, "y_mm": 0.0, "rz_deg": 45.0}``;
        None means not given. Values the model does not use are ignored.
    labels
        How a person gives each value (e.g. ``{"x_mm": "--x [mm]"}`` for a command-line
        option), used in the error messages; default ``"x [mm]"`` from the name.

    Returns
    -------
    ndarray (n_inputs,)
        The pose, each value converted to the unit of its input name.

    Raises
    ------
    ValueError
        An input with no (finite) value given, or units of different dimensions.

    Examples
    --------
    >>> pose_in_units(("x_m", "y_m", "rz_deg"), {"x_mm": 1200.0, "y_mm": -50.0, "rz_deg": 45.0})
    array([ 1.2 , -0.05, 45.  ])
    """

    def label(key: str) -> str:
        stem, unit = split_unit(key)
        return (labels or {}).get(key, f"{stem} [{unit}]")

    given_names = [k for k, v in values.items() if v is not None]
    given = {split_unit(k): float(values[k]) for k in given_names}
    by_stem = {split_unit(k)[0]: k for k in values}  # how each quantity can be given
    out = []
    for name in input_names:
        stem, unit = split_unit(name)
        match = [(u, v) for (s, u), v in given.items() if s == stem]
        if not match:
            wanted = ", ".join(label(by_stem.get(split_unit(n)[0], n)) for n in input_names)
            raise ValueError(
                f"the model's inputs are {tuple(input_names)}: give {wanted} "
                f"(no value for {stem}; given: {', '.join(map(label, given_names)) or 'none'})"
            )
        (have, v), dim = match[0], _UNITS[unit][0]
        if _UNITS[have][0] != dim:
            raise ValueError(f"{stem} given in {have}, the model's input is in {unit}")
        if not math.isfinite(v):
            raise ValueError(f"{stem} must be a finite number, got {v!r}")
        ratio = _UNITS[have][1] / _UNITS[unit][1]
        out.append(v / (1.0 / ratio) if ratio < 1 else v * ratio)  # mm -> m as x / 1000 exactly
    return np.array(out)
