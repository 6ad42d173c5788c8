"""Parsers of the hybrid studies' settings as typed (``robovib hybrid study`` options)."""

from __future__ import annotations

import numpy as np

__all__ = [
    "parse_backgrounds",
    "parse_seeds",
]


def parse_seeds(text: str) -> list[int]:
    """Simulator seeds from ``"0-4"`` (inclusive range) or ``"0,1,2"``.

    Parameters
    ----------
    text : str
        The seeds as typed.

    Returns
    -------
    list of int
        The seeds.

    Raises
    ------
    ValueError
        Anything else, naming the accepted forms.
    """
    try:
        if "-" in text.strip("-"):
            a, b = text.split("-", 1)
            seeds = list(range(int(a), int(b) + 1))
        else:
            seeds = [int(v) for v in text.split(",")]
    except ValueError:
        raise ValueError(f"seeds must look like 0-4 or 0,1,2, got {text!r}") from None
    if not seeds:
        raise ValueError(f"no seeds in {text!r} (a range must run upwards, e.g. 0-4)")
    return seeds


def parse_backgrounds(texts) -> list[float]:
    """Background levels from strings such as ``["0.05,0.15", "1"]`` (commas or spaces).

    Parameters
    ----------
    texts
        Strings, each one or more numbers separated by commas or spaces.

    Returns
    -------
    list of float

    Raises
    ------
    ValueError
        Something that is not a number, or a level that is not finite and > 0.
    """
    out = []
    for t in texts:
        for v in str(t).replace(",", " ").split():
            try:
                b = float(v)
            except ValueError:
                raise ValueError(f"background must be a number, got {v!r}") from None
            if not (np.isfinite(b) and b > 0):
                raise ValueError(f"background must be finite and > 0, got {v!r}")
            out.append(b)
    if not out:
        raise ValueError("no background level given")
    return out
