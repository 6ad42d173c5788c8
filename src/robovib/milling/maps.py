"""Workspace stability maps: critical depth over a dense grid of poses × spindle speeds, on Dask.

The pose model is evaluated once on the driver (one batched prediction of the mean modes for
every pose); only the modal parameters travel to the workers. Poses are cut into chunks, one Dask
task per chunk computes the stability envelope of every pose in it (semi-discretization or
zero-order method, all speeds vectorised), and the results come back as an
:class:`xarray.Dataset` with labelled coordinates ``x_mm, y_mm, rz_deg, spindle_rpm``, units
attributes, the settings and the robovib version, written to NetCDF atomically.

Schedulers: ``"sync"`` (one core, in process), ``"threads"``, ``"processes"`` (Dask's local
schedulers with ``n_workers``) or the address of a ``distributed`` scheduler (``tcp://host:port``).
"""

from __future__ import annotations

import json
import os
from collections.abc import Callable
from pathlib import Path

import numpy as np

from .forces import CuttingCoefficients, CuttingConditions, MillingTool
from .lobes import zoa_envelope
from .sdm import sdm_lobes
from .stability import stability_lobes

__all__ = [
    "KIND_CODES",
    "WORKSPACE_X_MM",
    "WORKSPACE_Y_MM",
    "best_pose",
    "feed_normal_modes",
    "map_speeds",
    "mean_modes_at_poses",
    "plot_lobe_map",
    "save_lobe_map",
    "workspace_lobe_map",
]

KIND_CODES = {"none": 0, "hopf": 1, "flip": 2, "fold": 3}
#: X and Y extent of the chapter-3 workspace (Table A1 poses) [mm].
WORKSPACE_X_MM = (2100.0, 2700.0)
WORKSPACE_Y_MM = (-300.0, 600.0)


def map_speeds(spindle_rpm: float, rpm_grid=None) -> np.ndarray:
    """Spindle speeds of a map: ``rpm_grid`` (sorted, unique) with ``spindle_rpm`` included [rpm].

    Parameters
    ----------
    spindle_rpm : float
        The speed the map is read at [rpm], > 0.
    rpm_grid : array_like, optional
        (n,) further speeds [rpm], > 0; only ``spindle_rpm`` when omitted.

    Returns
    -------
    numpy.ndarray
        (m,) ascending speeds [rpm].

    Raises
    ------
    ValueError
        A speed that is not finite and positive.
    """
    speeds = np.atleast_1d(np.asarray([spindle_rpm] if rpm_grid is None else rpm_grid, float))
    speeds = np.union1d(speeds, [float(spindle_rpm)])
    if not np.all(np.isfinite(speeds) & (speeds > 0)):
        raise ValueError(f"spindle speeds must be finite and > 0 rpm, got {speeds}")
    return speeds


def best_pose(ds, spindle_rpm: float, rz_deg: float) -> dict:
    """Deepest and shallowest stable cut of a lobe map at one speed and tool rotation.

    Parameters
    ----------
    ds : xarray.Dataset
        Map from :func:`workspace_lobe_map` (``a_lim_m`` over x_mm, y_mm, rz_deg, spindle_rpm).
    spindle_rpm : float
        Speed on the map's ``spindle_rpm`` axis [rpm].
    rz_deg : float
        Tool rotation on the map's ``rz_deg`` axis [deg].

    Returns
    -------
    dict
        ``critical_depth_m`` (n_y, n_x) [m] (NaN where no lobe was found), ``best_pose_mm``
        [x, y] [mm] (among the poses inside the model's measured region, where the map says),
        ``best_depth_m`` and ``shallowest_depth_m`` [m]; for a sampled map also the 5/95 %
        depths and the best spot stable with 95 % (``best_sure_*``), and ``p_stable``.

    Raises
    ------
    ValueError
        No finite critical depth at that speed and rotation.
    """
    at = ds["a_lim_m"].sel(spindle_rpm=spindle_rpm, rz_deg=rz_deg).transpose("x_mm", "y_mm")
    vals = np.where(np.isfinite(at.values), at.values, np.nan)
    if not np.any(np.isfinite(vals)):
        raise ValueError(f"no finite critical depth at {spindle_rpm:g} rpm, rz = {rz_deg:g} deg")
    inside = np.ones(vals.shape, bool)
    if "extrapolating" in ds:  # the best spot is one the model was measured around
        inside = ~ds["extrapolating"].sel(rz_deg=rz_deg).transpose("x_mm", "y_mm").values
        if not np.any(inside & np.isfinite(vals)):
            inside[:] = True

    def argmax(v):
        return np.unravel_index(np.nanargmax(np.where(inside, v, np.nan)), v.shape)

    i, j = argmax(vals)
    xs, ys = at["x_mm"].values, at["y_mm"].values
    out = {
        "critical_depth_m": vals.T,
        "best_pose_mm": [float(xs[i]), float(ys[j])],
        "best_depth_m": float(vals[i, j]),
        "shallowest_depth_m": float(np.nanmin(vals)),
    }
    if "a_lim_p05_m" in ds:  # sampled: the best spot is the deepest cut stable with 95 %
        q = {k: ds[f"a_lim_{k}_m"].sel(spindle_rpm=spindle_rpm, rz_deg=rz_deg)
             .transpose("x_mm", "y_mm").values for k in ("p05", "p50", "p95")}  # fmt: skip
        safe = np.where(np.isfinite(q["p05"]), q["p05"], np.nan)
        i, j = argmax(safe)
        out |= {
            "critical_depth_p05_m": q["p05"].T,
            "critical_depth_p95_m": q["p95"].T,
            "best_sure_pose_mm": [float(xs[i]), float(ys[j])],
            "best_sure_depth_p05_m": float(q["p05"][i, j]),
            "best_sure_depth_band_m": [float(q["p05"][i, j]), float(q["p95"][i, j])],
            "best_sure_depth_median_m": float(q["p50"][i, j]),
        }
        if "p_stable" in ds:
            p = ds["p_stable"].sel(spindle_rpm=spindle_rpm, rz_deg=rz_deg)
            out["p_stable"] = p.transpose("x_mm", "y_mm").values.T
            out["p_stable_depth_m"] = float(p.attrs["depth_m"])
    return out


def mean_modes_at_poses(model, poses: np.ndarray) -> np.ndarray:
    """Mean dominant modes (n, 3 directions, 3) as [fn_hz, stiffness_n_per_m, damping_ratio].

    Accepts a pose model (:class:`robovib.gp.contract.PoseModel`; in a multi-mode model the
    mode with the largest compliance peak of each direction) or a model whose ``predict(X)``
    returns the 9 chapter-3 outputs in thesis units (fn [Hz], k [MN/m], c [kN·s/m]).

    Parameters
    ----------
    model : object
        The pose model.
    poses : numpy.ndarray
        (n, 3) poses in the model's input units.

    Returns
    -------
    numpy.ndarray
        (n, 3, 3) modes (NaN for a direction the model does not have).
    """
    from ..gp.contract import PoseModel
    from ..modal.parameters import ModalParameters

    x = np.atleast_2d(np.asarray(poses, float))
    out = np.full((len(x), 3, 3), np.nan)
    if isinstance(model, PoseModel):
        for i, row in enumerate(model.mode_set(x)):
            for j, d in enumerate(("x", "y", "z")):
                if d in row:
                    p = max(row[d], key=lambda m: m.compliance_peak_m_per_n).parameters
                    out[i, j] = (p.natural_frequency_hz, p.stiffness_n_per_m, p.damping_ratio)
        return out
    mean = np.asarray(model.predict(x))
    if mean.ndim != 2 or mean.shape[1] != 9:
        raise ValueError(f"expected (n, 9) chapter-3 outputs, got {mean.shape}")
    for i, r in enumerate(mean):
        for j in range(3):
            p = ModalParameters.from_fn_k_c(r[3 * j], r[3 * j + 1] * 1e6, r[3 * j + 2] * 1e3)
            out[i, j] = (p.natural_frequency_hz, p.stiffness_n_per_m, p.damping_ratio)
    return out


def feed_normal_modes(model, poses: np.ndarray, feed_direction: str = "x"):
    """Every modelled mode of the feed and normal directions at each pose (the map's input).

    Parameters
    ----------
    model : object
        A pose model (:class:`robovib.gp.contract.PoseModel`) or a thesis-unit regressor (see
        :func:`mean_modes_at_poses`).
    poses : numpy.ndarray
        (n, 3) poses in the model's input units.
    feed_direction : {"x", "y"}
        Base-frame feed direction (the other horizontal direction is the normal).

    Returns
    -------
    modes : numpy.ndarray
        (n, 2, m, 3) [fn_hz, stiffness_n_per_m, damping_ratio] of up to ``m`` modes per
        direction (feed, normal), NaN-padded; all NaN at a pose where the model predicts no
        physical mode (far off the measured poses).
    ids : tuple of tuple of str
        Mode ids of the feed and the normal direction (as the model names them).

    Raises
    ------
    ValueError
        The model has no mode in the feed or the normal direction.
    """
    from ..gp.contract import PoseModel

    normal = "y" if feed_direction == "x" else "x"
    x = np.atleast_2d(np.asarray(poses, float))
    if not isinstance(model, PoseModel):
        m = mean_modes_at_poses(model, x)[:, [0, 1] if feed_direction == "x" else [1, 0], :]
        return m[:, :, None, :], ((feed_direction,), (normal,))
    try:
        rows = model.mode_set(x)
    except ValueError:  # a pose far off the measured poses predicts no physical mode: no row
        rows = []
        for r in x:
            try:
                rows.append(model.mode_set(r[None, :])[0])
            except ValueError:
                rows.append(None)
        if all(r is None for r in rows):
            raise
    first = next(r for r in rows if r is not None)
    for d in (feed_direction, normal):
        if d not in first:
            raise ValueError(
                f"the pose model has no mode in direction {d!r} (it has modes in "
                f"{', '.join(sorted(first))}): a map needs the feed and the normal direction"
            )
    width = max(len(first[d]) for d in (feed_direction, normal))
    out = np.full((len(x), 2, width, 3), np.nan)
    for i, row in enumerate(rows):
        if row is None:
            continue
        for j, d in enumerate((feed_direction, normal)):
            for k, m in enumerate(row[d]):
                p = m.parameters
                out[i, j, k] = (p.natural_frequency_hz, p.stiffness_n_per_m, p.damping_ratio)
    ids = tuple(tuple(m.mode_id for m in first[d]) for d in (feed_direction, normal))
    return out, ids


def _chunk_lobes(modes, tool, cond, coef, rpm, method, options):
    """One task: envelopes of a chunk of poses -> (a_lim, chatter, kind code), each (n, n_rpm)."""
    from ..modal.parameters import ModalParameters

    n = modes.shape[0]
    a = np.full((n, rpm.size), np.nan)
    f = np.full((n, rpm.size), np.nan)
    k = np.zeros((n, rpm.size), np.int8)
    for i in range(n):
        feed = [ModalParameters(*m) for m in modes[i, 0] if np.all(np.isfinite(m))]
        normal = [ModalParameters(*m) for m in modes[i, 1] if np.all(np.isfinite(m))]
        if not (feed and normal):  # no physical mode predicted at this pose: left NaN
            continue
        if method == "sdm":
            env = sdm_lobes(feed, normal, tool, cond, coef, rpm, **options)
        else:
            env = zoa_envelope(stability_lobes(feed, normal, tool, cond, coef, **options), rpm)
        a[i], f[i] = env.a_lim_m, env.chatter_hz
        k[i] = [KIND_CODES.get(str(s), 0) for s in env.kind]
    return a, f, k


def _chunk_probability(dists, tool, cond, coef, rpm, method, n_samples, seeds, depth_m, options):
    """One task: sampled limits of a chunk of poses -> (p05, p50, p95, p_stable), (n, n_rpm)."""
    from .uncertainty import stability_probability

    n = len(dists)
    q = np.full((3, n, rpm.size), np.nan)
    p = np.full((n, rpm.size), np.nan)
    for i, (dist, seed) in enumerate(zip(dists, seeds, strict=True)):
        if dist is None:  # no physical mode predicted at this pose
            continue
        prob = stability_probability(
            dist, tool, cond, coef, rpm, n_samples=n_samples, method=method, rng=seed, **options
        )
        a = np.where(np.isfinite(prob.a_lim_samples_m), prob.a_lim_samples_m, np.inf)
        q[:, i] = np.quantile(a, [0.05, 0.5, 0.95], axis=0)
        if depth_m is not None:
            p[i] = np.mean(a > depth_m, axis=0)
    return q[0], q[1], q[2], p


def workspace_lobe_map(
    model,
    x_mm,
    y_mm,
    rz_deg,
    spindle_rpm,
    tool: MillingTool,
    conditions: CuttingConditions,
    coefficients: CuttingCoefficients,
    *,
    method: str = "sdm",
    feed_direction: str = "x",
    scheduler: str | None = None,
    n_workers: int | None = None,
    poses_per_chunk: int = 4,
    progress: Callable[[int, int], None] | None = None,
    n_samples: int = 0,
    depth_m: float | None = None,
    rng=0,
    **lobe_options,
):
    """Critical depth over poses × speeds as a labelled :class:`xarray.Dataset` (module docs).

    Parameters
    ----------
    model
        Pose model (see :func:`mean_modes_at_poses`), inputs ``(x_mm, y_mm, rz_deg)``.
    x_mm, y_mm, rz_deg : array_like
        Grid axes [mm, mm, deg] (every combination is a pose).
    spindle_rpm : array_like (n_rpm,)
        Speeds [rpm].
    tool, conditions, coefficients
        Tool, radial immersion / milling direction, cutting coefficients.
    method : {"sdm", "zoa"}
    feed_direction : {"x", "y"}
        Base-frame feed direction (the other horizontal direction is the normal).
    scheduler : str, optional
        ``"sync"``, ``"threads"``, ``"processes"`` or ``"tcp://host:port"``; default
        ``"processes"`` for the SDM when ``n_workers > 1``, else ``"sync"`` (the zero-order
        method is cheaper than starting worker processes).
    n_workers : int, optional
        Local workers (default: the CPU count).
    poses_per_chunk : int
        Poses per Dask task.
    progress : callable(done, total), optional
        Called as chunks finish (the CLI draws a progress bar with it).
    n_samples : int
        Monte-Carlo samples of the pose model's predictive distribution per pose (every
        modelled mode, :func:`robovib.milling.uncertainty.stability_probability`); 0: the
        mean modes only. Adds the 5/50/95 % quantiles of the critical depth
        (``a_lim_p05_m``, ``a_lim_p50_m``, ``a_lim_p95_m``).
    depth_m : float, optional
        With ``n_samples``: the axial depth [m] whose probability of a stable cut is mapped
        (``p_stable``).
    rng : int
        Seed of the samples (pose ``i`` uses ``rng + i``).
    **lobe_options
        Passed to :func:`~robovib.milling.sdm.sdm_lobes` or
        :func:`~robovib.milling.stability.stability_lobes`.

    Returns
    -------
    xarray.Dataset
        ``a_lim_m``, ``chatter_hz``, ``kind`` (x_mm, y_mm, rz_deg, spindle_rpm);
        ``minimum_depth_m``, ``best_rpm``, ``best_depth_m`` (x_mm, y_mm, rz_deg); the modal
        parameters used; attributes ``robovib_version``, ``method``, ``settings`` (JSON).

    See ``docs/methods.md`` section 5.

    Examples
    --------
    >>> from robovib.gp import load_chapter3_model
    >>> from robovib.milling import ALUMINIUM_7075, CuttingConditions, MillingTool
    >>> from robovib.milling.maps import workspace_lobe_map
    >>> ds = workspace_lobe_map(load_chapter3_model(), [2100, 2700], [0, 300], [0.0], [1750.0],
    ...                         MillingTool(0.0254, 2), CuttingConditions(1750.0, 1e-4, 1e-3, 6e-3),
    ...                         ALUMINIUM_7075, method="zoa", scheduler="sync")
    >>> ds["a_lim_m"].dims
    ('x_mm', 'y_mm', 'rz_deg', 'spindle_rpm')
    """
    import dask
    import xarray as xr

    from .. import __version__
    from ..files.h5format import LOBE_MAP_FORMAT, LOBE_MAP_FORMAT_VERSION

    if method not in ("sdm", "zoa"):
        raise ValueError(f"method must be 'sdm' or 'zoa', got {method!r}")
    if feed_direction not in ("x", "y"):
        raise ValueError(f"feed_direction must be 'x' or 'y', got {feed_direction!r}")
    axes = [np.atleast_1d(np.asarray(v, float)) for v in (x_mm, y_mm, rz_deg, spindle_rpm)]
    for name, ax in zip(("x_mm", "y_mm", "rz_deg", "spindle_rpm"), axes, strict=True):
        if ax.ndim != 1 or ax.size == 0 or not np.all(np.isfinite(ax)):
            raise ValueError(f"{name} must be a non-empty 1-D array of finite values")
        if np.any(np.diff(ax) <= 0):
            raise ValueError(f"the {name} grid must be sorted and unique (ascending), got {ax}")
    xs, ys, rzs, rpm = axes
    if np.any(rpm <= 0):
        raise ValueError("spindle_rpm must be positive [rpm]")
    grid = np.stack(np.meshgrid(xs, ys, rzs, indexing="ij"), axis=-1).reshape(-1, 3)
    every, ids = feed_normal_modes(model, grid, feed_direction)
    predicted = np.all(np.any(np.all(np.isfinite(every), axis=-1), axis=-1), axis=-1)  # (n,)
    if not np.any(predicted):
        raise ValueError("the pose model returned no x/y mode at any pose of the map")
    from ..gp.contract import PoseModel

    extrap = (np.asarray(model.extrapolating(grid), bool) if isinstance(model, PoseModel)
              else np.zeros(len(grid), bool))  # fmt: skip
    # the per-pose variables hold the mode with the largest compliance peak of each direction
    z = np.clip(np.nan_to_num(every[..., 2], nan=0.5), 1e-12, 0.999)
    peak = 1.0 / (np.nan_to_num(every[..., 1], nan=np.inf) * z * np.sqrt(1.0 - z * z))
    fm = np.take_along_axis(every, np.argmax(peak, axis=-1)[..., None, None], axis=2)[:, :, 0, :]
    n = len(grid)
    size = max(1, int(poses_per_chunk))
    chunks = [slice(i, min(i + size, n)) for i in range(0, n, size)]
    tasks = [
        dask.delayed(_chunk_lobes)(
            every[c], tool, conditions, coefficients, rpm, method, lobe_options
        )
        for c in chunks
    ]
    n_samples = int(n_samples)
    if n_samples == 1 or n_samples < 0:
        raise ValueError(f"n_samples must be 0 (mean modes only) or >= 2, got {n_samples}")
    if depth_m is not None and not (np.isfinite(depth_m) and depth_m > 0):
        raise ValueError(f"depth_m must be a finite depth > 0 m, got {depth_m!r}")
    if depth_m is not None and not n_samples:
        raise ValueError("a P(stable) map at depth_m needs n_samples >= 2")
    if n_samples:
        from .uncertainty import mode_distributions_at_pose

        draws = max(400, 20 * n_samples)
        dists = [mode_distributions_at_pose(model, g, n_draws=draws, rng=int(rng) + i)
                 if ok else None for i, (g, ok) in enumerate(zip(grid, predicted, strict=True))]  # fmt: skip
        opts = {**lobe_options, "feed_direction": feed_direction}
        tasks += [
            dask.delayed(_chunk_probability)(
                dists[c], tool, conditions, coefficients, rpm, method, n_samples,
                [int(rng) + 1000 + i for i in range(c.start, c.stop)], depth_m, opts,
            )
            for c in chunks
        ]  # fmt: skip
    workers = int(n_workers or os.cpu_count() or 1)
    sched = scheduler or ("processes" if workers > 1 and method == "sdm" else "sync")
    results = _compute(tasks, sched, workers, progress)
    sampled = results[len(chunks) :]
    results = results[: len(chunks)]
    a = np.concatenate([r[0] for r in results]).reshape(xs.size, ys.size, rzs.size, rpm.size)
    f = np.concatenate([r[1] for r in results]).reshape(a.shape)
    k = np.concatenate([r[2] for r in results]).reshape(a.shape)
    a_fin = np.where(np.isfinite(a), a, np.nan)
    interior = np.full(a.shape[:3], np.nan)
    best_d = np.full(a.shape[:3], np.nan)
    if rpm.size >= 3:
        mid = a_fin[..., 1:-1]
        peak = (mid >= a_fin[..., :-2]) & (mid >= a_fin[..., 2:])
        masked = np.where(peak, mid, -np.inf)
        j = np.argmax(masked, axis=-1)
        has = np.isfinite(np.take_along_axis(masked, j[..., None], -1)[..., 0])
        interior = np.where(has, rpm[1:-1][j], np.nan)
        best_d = np.where(has, np.take_along_axis(mid, j[..., None], -1)[..., 0], np.nan)
    dims = ("x_mm", "y_mm", "rz_deg")
    mshape = (xs.size, ys.size, rzs.size)
    settings = {
        "method": method,
        "feed_direction": feed_direction,
        "n_flutes": int(tool.n_flutes),
        "diameter_m": tool.diameter_m,
        "helix_deg": tool.helix_deg,
        "radial_depth_m": conditions.radial_depth_m,
        "down_milling": bool(conditions.down_milling),
        "ktc_n_per_m2": coefficients.ktc,
        "krc_n_per_m2": coefficients.krc,
        "scheduler": sched if not sched.startswith("tcp://") else "distributed",
        "n_workers": workers,
        "poses_per_chunk": size,
        **{k2: v for k2, v in lobe_options.items() if isinstance(v, int | float | str)},
    }
    ds = xr.Dataset(
        {
            "a_lim_m": ((*dims, "spindle_rpm"), a, {"units": "m", "long_name": "critical axial depth"}),
            "chatter_hz": ((*dims, "spindle_rpm"), f, {"units": "Hz"}),
            "kind": ((*dims, "spindle_rpm"), k, {"units": "1", "flag_values": list(KIND_CODES.values()),
                                                  "flag_meanings": " ".join(KIND_CODES)}),
            "minimum_depth_m": (dims, np.nanmin(np.where(np.isfinite(a), a, np.inf), axis=-1),
                                {"units": "m", "long_name": "depth stable at every speed"}),
            "best_rpm": (dims, interior, {"units": "rpm", "long_name": "interior maximum of the envelope"}),
            "best_depth_m": (dims, best_d, {"units": "m"}),
            "extrapolating": (dims, extrap.reshape(mshape), {"units": "1", "long_name":
                              "pose outside the box or hull of the model's training poses"}),
            "feed_fn_hz": (dims, fm[:, 0, 0].reshape(mshape), {"units": "Hz"}),
            "feed_stiffness_n_per_m": (dims, fm[:, 0, 1].reshape(mshape), {"units": "N/m"}),
            "feed_damping_ratio": (dims, fm[:, 0, 2].reshape(mshape), {"units": "1"}),
            "normal_fn_hz": (dims, fm[:, 1, 0].reshape(mshape), {"units": "Hz"}),
            "normal_stiffness_n_per_m": (dims, fm[:, 1, 1].reshape(mshape), {"units": "N/m"}),
            "normal_damping_ratio": (dims, fm[:, 1, 2].reshape(mshape), {"units": "1"}),
        },
        coords={
            "x_mm": ("x_mm", xs, {"units": "mm"}),
            "y_mm": ("y_mm", ys, {"units": "mm"}),
            "rz_deg": ("rz_deg", rzs, {"units": "deg"}),
            "spindle_rpm": ("spindle_rpm", rpm, {"units": "rpm"}),
        },
        attrs={
            "title": "robovib workspace stability map",
            "format": LOBE_MAP_FORMAT,
            "format_version": LOBE_MAP_FORMAT_VERSION,
            "robovib_version": __version__,
            "method": method,
            "settings": json.dumps(settings),
            "feed_modes": ",".join(ids[0]),
            "normal_modes": ",".join(ids[1]),
        },
    )  # fmt: skip
    if n_samples:
        shape4 = (*mshape, rpm.size)
        qs = [np.concatenate([r[j] for r in sampled]).reshape(shape4) for j in range(4)]
        for name, v, q in zip(("a_lim_p05_m", "a_lim_p50_m", "a_lim_p95_m"), qs, (5, 50, 95),
                              strict=False):  # fmt: skip
            ds[name] = ((*dims, "spindle_rpm"), v, {
                "units": "m", "long_name": f"{q} % quantile of the critical depth over "
                f"{n_samples} samples of the pose model"})  # fmt: skip
        if depth_m is not None:
            ds["p_stable"] = ((*dims, "spindle_rpm"), qs[3], {
                "units": "1", "long_name": f"probability of a stable cut at {depth_m * 1e3:g} mm",
                "depth_m": float(depth_m)})  # fmt: skip
        settings.update(n_samples=n_samples, seed=int(rng),
                        **({} if depth_m is None else {"depth_m": float(depth_m)}))  # fmt: skip
        ds.attrs["settings"] = json.dumps(settings)
    return ds


#: Seconds a Dask scheduler address gets to accept the connection and greet (handshake).
SCHEDULER_TIMEOUT_S = 5.0


def check_scheduler_address(address: str, timeout_s: float = SCHEDULER_TIMEOUT_S) -> None:
    """Check, within ``timeout_s``, that a Dask scheduler answers at ``tcp://host:port``.

    ``distributed.Client`` waits for the scheduler's greeting without a limit: a listener
    that never speaks (another service, a hung scheduler) blocks it forever, and a refused
    port costs its 30 s connect timeout. A Dask scheduler writes its handshake as soon as it
    accepts a connection, so the probe connects and waits for the first byte.

    Parameters
    ----------
    address : str
        ``tcp://host:port``.
    timeout_s : float
        Seconds for the connection and the first byte of the handshake together.

    Raises
    ------
    ValueError
        A malformed address, a refused connection, an unknown host, or no handshake in time;
        the message names the address.
    """
    import socket
    import time
    from urllib.parse import urlsplit

    parts = urlsplit(address)
    try:
        host, port = parts.hostname, parts.port
    except ValueError:  # a port that is not a number
        host, port = None, None
    if parts.scheme != "tcp" or not host or port is None:
        raise ValueError(f"Dask scheduler {address!r}: expected tcp://host:port")
    start = time.monotonic()
    try:
        sock = socket.create_connection((host, port), timeout=timeout_s)
    except ConnectionRefusedError:
        raise ValueError(
            f"Dask scheduler {address}: connection refused (no scheduler listens there)"
        ) from None
    except socket.gaierror as exc:
        raise ValueError(f"Dask scheduler {address}: unknown host {host!r} ({exc})") from None
    except TimeoutError:
        raise ValueError(
            f"Dask scheduler {address}: no connection within {timeout_s:g} s"
        ) from None
    except OSError as exc:
        raise ValueError(
            f"Dask scheduler {address}: cannot connect ({exc.strerror or exc})"
        ) from None
    with sock:
        sock.settimeout(max(0.1, timeout_s - (time.monotonic() - start)))
        try:
            greeting = sock.recv(1)
        except TimeoutError:
            greeting = None
        except OSError as exc:
            raise ValueError(
                f"Dask scheduler {address}: connection dropped ({exc.strerror or exc})"
            ) from None
    if not greeting:
        raise ValueError(
            f"Dask scheduler {address}: something listens there but sent no Dask handshake "
            f"within {timeout_s:g} s (not a Dask scheduler, or a hung one)"
        )


def _compute(tasks, scheduler: str, workers: int, progress):
    import dask

    total = len(tasks)
    if scheduler.startswith("tcp://"):
        from distributed import Client, as_completed

        check_scheduler_address(scheduler)  # a silent listener would block Client forever
        try:
            client = Client(scheduler, timeout=SCHEDULER_TIMEOUT_S)
        except OSError as exc:  # TimeoutError and distributed's CommClosedError included
            raise ValueError(f"Dask scheduler {scheduler}: no connection ({exc})") from None
        with client:
            futures = client.compute(tasks)
            index = {fut.key: i for i, fut in enumerate(futures)}
            results = [None] * total
            for done, fut in enumerate(as_completed(futures), 1):
                results[index[fut.key]] = fut.result()
                if progress is not None:
                    progress(done, total)
            return results
    if scheduler not in ("sync", "threads", "processes", "synchronous", "single-threaded"):
        raise ValueError(
            f"scheduler must be 'sync', 'threads', 'processes' or 'tcp://host:port', got {scheduler!r}"
        )
    from dask.callbacks import Callback

    keys = {t.key for t in tasks}
    count = [0]

    class _Progress(Callback):
        def _posttask(self, key, result, dsk, state, worker_id):
            if key in keys and progress is not None:
                count[0] += 1
                progress(count[0], total)

    name = "sync" if scheduler in ("synchronous", "single-threaded") else scheduler
    with _Progress():
        return list(dask.compute(*tasks, scheduler=name, num_workers=workers))


def save_lobe_map(ds, path: str | Path) -> Path:
    """Write the map to NetCDF atomically (temporary file in the target folder, then rename).

    Parameters
    ----------
    ds : xarray.Dataset
        The lobe map.
    path : str or pathlib.Path
        The ``.nc`` file.

    Returns
    -------
    pathlib.Path
        The file written.
    """
    target = Path(path)
    if target.suffix.lower() not in (".nc", ".netcdf", ".nc4"):
        raise ValueError(f"lobe maps are written as NetCDF (.nc), got {target.name!r}")
    from ..files.safe_write import atomic_output

    target.parent.mkdir(parents=True, exist_ok=True)
    with atomic_output(target) as tmp:
        ds.to_netcdf(tmp)
    return target


def plot_lobe_map(ds, ax=None, *, spindle_rpm: float | None = None, rz_deg: float | None = None):
    """Map image: critical depth [mm] over X-Y at one speed (nearest) and one Rz (nearest).

    Without ``spindle_rpm`` the depth stable at every speed (``minimum_depth_m``) is shown.

    Parameters
    ----------
    ds : xarray.Dataset
        The lobe map (:func:`workspace_lobe_map`).
    ax : matplotlib.axes.Axes, optional
        Axes to draw on (default: a new figure).
    spindle_rpm : float, optional
        Speed shown [rpm].
    rz_deg : float, optional
        Rz shown [deg] (default: the first).

    Returns
    -------
    matplotlib.figure.Figure
    """
    import matplotlib.pyplot as plt

    sampled = "a_lim_p05_m" in ds and spindle_rpm is not None
    if ax is None:
        _, axes = plt.subplots(1, 2 if sampled else 1, figsize=(12 if sampled else 7, 5))
        ax = axes[0] if sampled else axes
        second = axes[1] if sampled else None
    else:
        second = None
    rz = float(ds.rz_deg.values[0]) if rz_deg is None else float(rz_deg)
    sel = ds.sel(rz_deg=rz, method="nearest")
    if spindle_rpm is None:
        field = sel["minimum_depth_m"]
        what = "depth stable at every speed"
    else:
        field = sel["a_lim_m"].sel(spindle_rpm=float(spindle_rpm), method="nearest")
        what = f"critical depth at {float(field.spindle_rpm):.0f} rpm"
    vals = np.where(np.isfinite(field.values), field.values, np.nan) * 1e3
    out = sel["extrapolating"].values if "extrapolating" in ds else None
    _map_panel(ax, ds, vals, f"{what} [mm]", "viridis", "deepest", out)
    ax.set_title(f"{ds.attrs.get('method', '').upper()} stability map, Rz = {float(sel.rz_deg):g} deg",
                 fontsize=10)  # fmt: skip
    if second is not None:
        at = sel.sel(spindle_rpm=float(spindle_rpm), method="nearest")
        if "p_stable" in ds:
            v = at["p_stable"].values
            _map_panel(second, ds, v, "P(stable) [-]", "RdYlGn", "most sure", out, vmin=0, vmax=1)
            second.set_title(
                f"probability of a stable cut at {ds['p_stable'].attrs['depth_m'] * 1e3:g} mm",
                fontsize=10,
            )
        else:
            v = np.where(np.isfinite(at["a_lim_p05_m"].values), at["a_lim_p05_m"].values, np.nan)
            _map_panel(second, ds, v * 1e3, "5 % quantile of the critical depth [mm]", "viridis",
                       "deepest sure", out)  # fmt: skip
            wid = (at["a_lim_p95_m"].values - at["a_lim_p05_m"].values) * 1e3
            cs = second.contour(ds.x_mm.values, ds.y_mm.values, wid.T, colors="w", linewidths=0.8)
            second.clabel(cs, fmt="%.2g mm", fontsize=7)
            second.set_title("stable with 95 % (white: width of the 90 % band)", fontsize=10)
    ax.figure.tight_layout()
    return ax.figure


def _map_panel(ax, ds, vals, label, cmap, best, outside=None, **kw):
    """One X-Y image of ``vals`` (n_x, n_y) with its colour bar, the poses outside the measured
    region crossed and the best spot (inside it) starred."""
    mesh = ax.pcolormesh(ds.x_mm.values, ds.y_mm.values, vals.T, shading="nearest", cmap=cmap,
                         **kw)  # fmt: skip
    ax.figure.colorbar(mesh, ax=ax, label=label)
    pick = vals
    if outside is not None and np.any(outside):
        gx, gy = np.meshgrid(ds.x_mm.values, ds.y_mm.values, indexing="ij")
        ax.plot(gx[outside], gy[outside], "x", color="0.3", ms=5, lw=0,
                label="outside the measured poses (extrapolation)")  # fmt: skip
        if np.any(~outside & np.isfinite(vals)):
            pick = np.where(outside, np.nan, vals)
    if np.any(np.isfinite(pick)):
        i, j = np.unravel_index(np.nanargmax(pick), pick.shape)
        ax.plot(ds.x_mm.values[i], ds.y_mm.values[j], "*", ms=16, color="w", mec="k",
                label=f"{best}: X {ds.x_mm.values[i]:.0f}, Y {ds.y_mm.values[j]:.0f} mm")  # fmt: skip
        ax.legend(fontsize=8, loc="lower right")
    ax.set_xlabel("X [mm]")
    ax.set_ylabel("Y [mm]")
