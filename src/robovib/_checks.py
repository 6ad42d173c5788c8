"""Input checks at the door: enumerations and ranges with the unit in the message.

Small helpers shared by the library's public functions, so that every bad option gives one clear
``ValueError`` naming the parameter, the value, the allowed set or range and the unit — and
nothing is silently clipped or mapped to a default.
"""

from __future__ import annotations

import math
from collections.abc import Iterable

import numpy as np

__all__ = ["check_choice", "check_increasing", "check_int", "check_number"]


def check_choice(name: str, value, choices: Iterable[str], *, case_insensitive: bool = False):
    """Return ``value`` (canonical spelling from ``choices``) or raise naming the choices.

    Raises
    ------
    ValueError
        ``value`` is not one of ``choices``.
    """
    choices = tuple(choices)
    if isinstance(value, str):
        if value in choices:
            return value
        if case_insensitive:
            for c in choices:
                if c.lower() == value.lower():
                    return c
    allowed = ", ".join(repr(c) for c in choices)
    raise ValueError(f"unknown {name} {value!r}; expected one of {allowed}")


def check_number(
    name: str,
    value,
    unit: str = "",
    *,
    lo: float | None = None,
    hi: float | None = None,
    lo_open: bool = False,
    hi_open: bool = False,
) -> float:
    """Return ``float(value)``, finite and inside ``[lo, hi]`` (open ends as asked), or raise.

    ``unit`` (e.g. ``"Hz"``, ``"s"``) is quoted in the message.

    Raises
    ------
    ValueError
        Not a number, NaN/inf, or outside the range.
    """
    u = f" {unit}" if unit else ""
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ValueError(
            f"{name} must be a number{' in ' + unit if unit else ''}, got {value!r}"
        ) from None
    if not math.isfinite(x):
        raise ValueError(f"{name} must be a finite number{' in ' + unit if unit else ''}, got {x}")
    if lo is not None and (x < lo or (lo_open and x == lo)):
        op = ">" if lo_open else ">="
        raise ValueError(f"{name} must be {op} {lo:g}{u}, got {x:g}{u}")
    if hi is not None and (x > hi or (hi_open and x == hi)):
        op = "<" if hi_open else "<="
        raise ValueError(f"{name} must be {op} {hi:g}{u}, got {x:g}{u}")
    return x


def check_int(name: str, value, *, lo: int | None = None, hi: int | None = None) -> int:
    """Return ``value`` as int inside ``[lo, hi]`` or raise (no silent rounding of 2.5)."""
    if isinstance(value, bool) or not isinstance(value, int | np.integer):
        if isinstance(value, float | np.floating) and float(value).is_integer():
            value = int(value)
        else:
            raise ValueError(f"{name} must be an integer, got {value!r}")
    value = int(value)
    if lo is not None and value < lo:
        raise ValueError(f"{name} must be >= {lo}, got {value}")
    if hi is not None and value > hi:
        raise ValueError(f"{name} must be <= {hi}, got {value}")
    return value


def check_increasing(name: str, values, unit: str = "", *, min_size: int = 1) -> np.ndarray:
    """Return ``values`` as a 1-D float array, finite and strictly increasing, or raise.

    Used for path coordinates and grid axes: unsorted or repeated points would make an
    interpolation silently wrong.
    """
    u = f" [{unit}]" if unit else ""
    a = np.asarray(values, float)
    if a.ndim != 1:
        raise ValueError(f"{name}{u} must be 1-D, got shape {a.shape}")
    if a.size < min_size:
        raise ValueError(f"{name}{u} needs at least {min_size} values, got {a.size}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name}{u} contains NaN or inf")
    d = np.diff(a)
    if np.any(d <= 0):
        i = int(np.flatnonzero(d <= 0)[0])
        what = "repeated" if d[i] == 0 else "not increasing"
        raise ValueError(
            f"{name}{u} must be sorted and unique; value {a[i + 1]:g} at index {i + 1} is {what} "
            f"(after {a[i]:g})"
        )
    return a
