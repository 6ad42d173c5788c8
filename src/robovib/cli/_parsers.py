"""Option strings of the mill and report commands -> values (modes, speeds, an operating point).

The library takes values; these parsers are the command line's concern and name its texts.
"""

from __future__ import annotations

import math

import numpy as np

from ..modal.parameters import ModalParameters

__all__ = ["parse_mode_spec", "parse_mode_specs", "parse_operating_point", "parse_rpm_range"]


def parse_mode_spec(spec: str) -> tuple[str, ModalParameters]:
    """``"x:FN_HZ,K_N_PER_M,ZETA"`` -> (direction, mode); e.g. ``"y:650,2.1e7,0.03"``.

    Parameters
    ----------
    spec : str
        The text given on the command line.

    Returns
    -------
    direction : str
        ``"x"`` or ``"y"``.
    mode : ModalParameters
        The mode.
    """
    try:
        direction, rest = spec.split(":", 1)
        fn, k, zeta = (float(v) for v in rest.split(","))
    except ValueError as exc:
        raise ValueError(
            f"mode {spec!r} must read DIRECTION:FN_HZ,K_N_PER_M,ZETA (e.g. x:650,2.1e7,0.03)"
        ) from exc
    direction = direction.strip().lower()
    if direction not in ("x", "y"):
        raise ValueError(
            f"mode {spec!r}: direction must be x (feed) or y (normal), got {direction!r}"
        )
    if not 0 < zeta < 1:  # an undamped mode has no finite stability limit
        raise ValueError(
            f"mode {spec!r}: damping ratio ZETA must be in (0, 1), got {zeta} (a ratio, not %)"
        )
    try:
        return direction, ModalParameters(fn, k, zeta)
    except ValueError as exc:  # which of several --mode texts, and which number
        raise ValueError(f"mode {spec!r}: {exc}") from None


def parse_mode_specs(specs) -> tuple[tuple[ModalParameters, ...], tuple[ModalParameters, ...]]:
    """Several ``"x:FN_HZ,K_N_PER_M,ZETA"`` texts -> the feed (x) and normal (y) modes.

    Parameters
    ----------
    specs : sequence of str
        The texts given on the command line (:func:`parse_mode_spec`), in any order.

    Returns
    -------
    modes_x, modes_y : tuple of ModalParameters
        The modes of each direction, in the order given.

    Examples
    --------
    >>> mx, my = parse_mode_specs(["x:650,2.1e7,0.03", "y:700,3e7,0.02", "x:900,5e7,0.04"])
    >>> [m.natural_frequency_hz for m in mx], [m.natural_frequency_hz for m in my]
    ([650.0, 900.0], [700.0])
    """
    parsed = [parse_mode_spec(s) for s in specs]
    return (
        tuple(m for d, m in parsed if d == "x"),
        tuple(m for d, m in parsed if d == "y"),
    )


def parse_operating_point(spec: str) -> tuple[float, float]:
    """``"RPM,DEPTH_MM"`` -> (rpm, depth [m]).

    Parameters
    ----------
    spec : str
        The text given on the command line.

    Returns
    -------
    rpm, depth_m : float
        Speed [rpm] and depth [m].
    """
    try:
        a, b = (float(v) for v in spec.split(","))
    except ValueError as exc:
        raise ValueError(
            f"operating point {spec!r} must read RPM,DEPTH_MM (e.g. 9000,1.5)"
        ) from exc
    if not (a > 0 and b > 0 and math.isfinite(a) and math.isfinite(b)):
        raise ValueError(
            f"operating point needs a positive speed [rpm] and depth [mm], got {spec!r}"
        )
    return a, b * 1e-3


def parse_rpm_range(spec: str) -> np.ndarray:
    """``"A:B:N"`` -> N speeds [rpm] from A to B.

    Parameters
    ----------
    spec : str
        The text given on the command line.

    Returns
    -------
    numpy.ndarray
        (N,) speeds [rpm].
    """
    try:
        a, b, n = spec.split(":")
        lo, hi, count = float(a), float(b), int(n)
    except ValueError as exc:
        raise ValueError(
            f"rpm range {spec!r} must read MIN_RPM:MAX_RPM:N (e.g. 2000:12000:200)"
        ) from exc
    if not (0 < lo < hi and math.isfinite(hi)) or count < 2:
        raise ValueError(f"rpm range needs 0 < MIN_RPM < MAX_RPM and N >= 2, got {spec!r}")
    return np.linspace(lo, hi, count)
