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
        [x, y] [mm], ``best_depth_m`` and ``shallowest_depth_m`` [m].

    Raises
    ------
    ValueError
        No finite critical depth at that speed and rotation.
    """
    at = ds["a_lim_m"].sel(spindle_rpm=spindle_rpm, rz_deg=rz_deg).transpose("x_mm", "y_mm")
    vals = np.where(np.isfinite(at.values), at.values, np.nan)
    if not np.any(np.isfinite(vals)):
        raise ValueError(f"no finite critical depth at {spindle_rpm:g} rpm, rz = {rz_deg:g} deg")
    i, j = np.unravel_index(np.nanargmax(vals), vals.shape)
    xs, ys = at["x_mm"].values, at["y_mm"].values
    return {
        "critical_depth_m": vals.T,
        "best_pose_mm": [float(xs[i]), float(ys[j])],
        "best_depth_m": float(vals[i, j]),
        "shallowest_depth_m": float(np.nanmin(vals)),
    }


def mean_modes_at_poses(model, poses: np.ndarray) -> np.ndarray:
    """Mean dominant modes (n, 3 directions, 3) as [fn_hz, stiffness_n_per_m, damping_ratio].

    Accepts a :class:`robovib.gp.PoseModalModel` (``modes(X)``) or a model whose ``predict(X)``
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
        (n, 3, 3) modes.
    """
    from ..modal.parameters import ModalParameters

    x = np.atleast_2d(np.asarray(poses, float))
    out = np.full((len(x), 3, 3), np.nan)
    if hasattr(model, "modes") and hasattr(model, "output_names_"):
        for i, row in enumerate(model.modes(x)):
            for j, d in enumerate(("x", "y", "z")):
                if d in row:
                    p = row[d].parameters
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


def _chunk_lobes(modes, tool, cond, coef, rpm, method, options):
    """One task: envelopes of a chunk of poses -> (a_lim, chatter, kind code), each (n, n_rpm)."""
    from ..modal.parameters import ModalParameters

    n = modes.shape[0]
    a = np.full((n, rpm.size), np.nan)
    f = np.full((n, rpm.size), np.nan)
    k = np.zeros((n, rpm.size), np.int8)
    for i in range(n):
        feed = [ModalParameters(*modes[i, 0])]
        normal = [ModalParameters(*modes[i, 1])]
        if method == "sdm":
            env = sdm_lobes(feed, normal, tool, cond, coef, rpm, **options)
        else:
            env = zoa_envelope(stability_lobes(feed, normal, tool, cond, coef, **options), rpm)
        a[i], f[i] = env.a_lim_m, env.chatter_hz
        k[i] = [KIND_CODES.get(str(s), 0) for s in env.kind]
    return a, f, k


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
    from ..io.h5format import LOBE_MAP_FORMAT, LOBE_MAP_FORMAT_VERSION

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
    modes = mean_modes_at_poses(model, grid)
    order = [0, 1] if feed_direction == "x" else [1, 0]
    fm = modes[:, order, :]
    if not np.all(np.isfinite(fm)):
        raise ValueError("the pose model returned no x/y mode for some poses")
    n = len(grid)
    size = max(1, int(poses_per_chunk))
    chunks = [slice(i, min(i + size, n)) for i in range(0, n, size)]
    tasks = [
        dask.delayed(_chunk_lobes)(fm[c], tool, conditions, coefficients, rpm, method, lobe_options)
        for c in chunks
    ]
    workers = int(n_workers or os.cpu_count() or 1)
    sched = scheduler or ("processes" if workers > 1 and method == "sdm" else "sync")
    results = _compute(tasks, sched, workers, progress)
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
        },
    )  # fmt: skip
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
    from ..io.safe_write import atomic_output

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

    if ax is None:
        _, ax = plt.subplots(figsize=(7, 5))
    rz = float(ds.rz_deg.values[0]) if rz_deg is None else float(rz_deg)
    sel = ds.sel(rz_deg=rz, method="nearest")
    if spindle_rpm is None:
        field = sel["minimum_depth_m"]
        what = "depth stable at every speed"
    else:
        field = sel["a_lim_m"].sel(spindle_rpm=float(spindle_rpm), method="nearest")
        what = f"critical depth at {float(field.spindle_rpm):.0f} rpm"
    vals = np.where(np.isfinite(field.values), field.values, np.nan) * 1e3
    mesh = ax.pcolormesh(ds.x_mm.values, ds.y_mm.values, vals.T, shading="nearest", cmap="viridis")
    ax.figure.colorbar(mesh, ax=ax, label=f"{what} [mm]")
    ax.set_xlabel("X [mm]")
    ax.set_ylabel("Y [mm]")
    ax.set_title(f"{ds.attrs.get('method', '').upper()} stability map, Rz = {float(sel.rz_deg):g} deg",
                 fontsize=10)  # fmt: skip
    return ax.figure
