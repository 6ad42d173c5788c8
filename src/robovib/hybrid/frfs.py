"""FRFs with their poses onto a model's frequency grid: the data side of
:class:`robovib.hybrid.FRFPoseModel` (its ``fit_frfs`` / ``update_frfs``) and of the file
workflow (:mod:`robovib.hybrid.frf_prediction`, which re-exports these names)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..frf.core import FRF
from .oma import h1_random_error

__all__ = ["INPUT_SETS", "frequency_grid", "frf_pose", "frfs_on_grid", "frfs_on_path_grid"]

#: Pose inputs the file workflow understands: the path coordinate or the workspace pose.
INPUT_SETS = {"path": ("s_m",), "workspace": ("x_m", "y_m", "rz_deg")}


def frequency_grid(f_min_hz: float, f_max_hz: float, df_hz: float) -> np.ndarray:
    """The model's frequency grid ``f_min_hz, f_min_hz + df_hz, ... <= f_max_hz`` [Hz], checked.

    Parameters
    ----------
    f_min_hz
        First bin [Hz], >= 0.
    f_max_hz
        Upper end [Hz]; the last bin is the largest ``f_min_hz + i df_hz`` not above it.
    df_hz
        Bin spacing [Hz], > 0.

    Returns
    -------
    ndarray (n_f,)
        The bin frequencies [Hz], 2 <= n_f <= 100000.

    Raises
    ------
    ValueError
        Non-finite values, ``f_min_hz`` < 0 Hz, ``f_min_hz >= f_max_hz``, ``df_hz <= 0`` Hz, or a
        grid of fewer than 2 or more than 100000 bins.
    """
    from .._checks import check_number

    lo = check_number("f_min_hz", f_min_hz, "Hz", lo=0.0)
    hi = check_number("f_max_hz", f_max_hz, "Hz", lo=0.0, lo_open=True)
    df = check_number("df_hz", df_hz, "Hz", lo=0.0, lo_open=True)
    if lo >= hi:
        raise ValueError(f"f_min_hz={lo:g} Hz must be below f_max_hz={hi:g} Hz")
    n = int(np.floor((hi - lo) / df + 1e-9)) + 1
    if not 2 <= n <= 100_000:
        raise ValueError(
            f"grid {lo:g}-{hi:g} Hz in steps of {df:g} Hz has {n} bins; need 2 to 100000"
        )
    return lo + df * np.arange(n)


def frf_pose(frf: FRF, input_names=("s_m",)) -> tuple[float, ...]:
    """The pose of an FRF in the units of ``input_names``.

    ``("s_m",)``: ``meta["path_s_m"]``; ``("x_m", "y_m", "rz_deg")``: ``frf.pose`` =
    (x [m], y [m], z [m], rx, ry, rz [deg]) as written by ``frf compute`` / ``hybrid oma``.

    Parameters
    ----------
    frf
        An FRF carrying its pose (``meta["path_s_m"]`` or ``pose``).
    input_names
        The model's pose inputs: ``("s_m",)`` or ``("x_m", "y_m", "rz_deg")``.

    Returns
    -------
    tuple of float
        The pose, one value per input name, in the units of the names ([m], [deg]).

    Raises
    ------
    ValueError
        The FRF carries no such pose, or unknown input names.
    """
    names = tuple(input_names)
    if names == INPUT_SETS["path"]:
        if "path_s_m" not in frf.meta:
            raise ValueError(
                "FRF has no path coordinate (write it with --path-s / from `hybrid oma`)"
            )
        return (float(frf.meta["path_s_m"]),)
    if names == INPUT_SETS["workspace"]:
        if (
            frf.pose is None
            or len(frf.pose) != 6
            or not np.all(np.isfinite(np.take(frf.pose, [0, 1, 5])))
        ):
            raise ValueError("FRF has no workspace pose (x, y, rz): record it at a workspace pose")
        return (float(frf.pose[0]), float(frf.pose[1]), float(frf.pose[5]))
    raise ValueError(f"unknown pose inputs {names}; expected one of {list(INPUT_SETS.values())}")


def frfs_on_grid(
    frfs: Sequence[FRF], grid_hz, input_names=("s_m",), partial: bool = False
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Complex compliances on ``grid_hz`` with their poses, bin masks and random errors.

    Parameters
    ----------
    frfs
        Compliance FRFs carrying their pose (see :func:`frf_pose`) and optionally
        ``meta["flagged"]`` (bool per bin, as written by ``hybrid oma``).
    grid_hz
        (n_f,) model grid [Hz].
    input_names
        The model's pose inputs.
    partial
        True: grid bins outside an FRF's range are masked (missing), not an error.

    Returns
    -------
    values
        (n, n_f) complex compliance [m/N].
    poses
        (n, n_inputs) in the units of ``input_names``.
    mask
        (n, n_f) bool, True where a bin is observed and not flagged.
    random_error
        (n, n_f) H1 random error std [m/N] from the coherence (0 where none is stored).

    Raises
    ------
    ValueError
        An FRF without that pose, not a compliance, or (``partial=False``) not covering the grid.
    """
    grid = np.asarray(grid_hz, float)
    vals, poses, masks, errs = [], [], [], []
    for i, f in enumerate(frfs):
        try:
            poses.append(frf_pose(f, input_names))
        except ValueError as exc:
            raise ValueError(f"FRF {i}: {exc}") from None
        if f.quantity != "compliance":
            raise ValueError(f"FRF {i} is {f.quantity}, expected compliance")
        try:
            on_grid = f.interpolate(grid, outside="hold" if partial else "raise")
        except ValueError as exc:
            raise ValueError(f"FRF {i}: {exc} (the model grid)") from None
        outside = (grid < f.frequency_hz[0] - 1e-3) | (grid > f.frequency_hz[-1] + 1e-3)
        flagged = np.asarray(f.meta.get("flagged", np.zeros(f.frequency_hz.size, bool)), bool)
        nearest = np.clip(np.searchsorted(f.frequency_hz, grid), 0, f.frequency_hz.size - 1)
        vals.append(on_grid.values)
        masks.append(~flagged[nearest] & ~outside)
        if f.coherence is not None:
            err = h1_random_error(f.values, f.coherence, f.n_averages)
            errs.append(np.interp(grid, f.frequency_hz, err))
        else:
            errs.append(np.zeros(grid.size))
    return np.array(vals), np.array(poses, float), np.array(masks), np.array(errs)


def frfs_on_path_grid(
    frfs: Sequence[FRF], grid_hz, partial: bool = False
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Complex compliances on ``grid_hz``, their path coordinates and bin masks.

    The path-coordinate case of :func:`frfs_on_grid` (without the random errors).

    Parameters
    ----------
    frfs
        Compliance FRFs carrying ``meta["path_s_m"]`` and optionally ``meta["flagged"]``.
    grid_hz
        (n_f,) model grid [Hz].
    partial
        True: grid bins outside an FRF's range are masked (missing), not an error.

    Returns
    -------
    values
        (n, n_f) complex compliance [m/N].
    s_m
        (n,) path coordinates [m].
    mask
        (n, n_f) bool, True where a bin is observed and not flagged.

    Raises
    ------
    ValueError
        As :func:`frfs_on_grid`.
    """
    h, p, m, _ = frfs_on_grid(frfs, grid_hz, ("s_m",), partial)
    return h, p[:, 0], m
