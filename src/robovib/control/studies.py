"""Closed-loop studies on the virtual robot (thesis §4.2-4.4).

1. :func:`path_modal_model`: hammer tests at points along the chapter-4 path (thesis: 20 points
   56 mm apart), dominant-mode fits, and a GP over path distance — the pose model the
   controller is scheduled from.
2. :func:`offset_mass_study`: 1 kg at 50.8 mm rotating at the given speeds while the robot
   moves 900 mm from the extended end toward the base at 84 mm/s; no feedback vs pose-dependent
   gains vs constant gains designed at the path start and at the path end (Table 7 analogue),
   plus the delay-aware LQR (:func:`robovib.control.design_delay_aware_lqr`, beyond the thesis).
3. :func:`milling_study`: the cutting conditions of Table 10 at Positions 1 and 2 with
   uncoupled X and Z controllers; RMS vibration open vs closed loop (Table 10 analogue).

Measurement realism comes from :func:`robovib.sim.run_closed_loop`: tracker at 1 kHz with
noise and 0.01 mm resolution, velocity by backward difference, commands at 250 Hz, 32 ms late.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..frf.impact import impact_frf
from ..gp.regressor import BatchedGPRegressor
from ..milling.forces import (
    ACETAL,
    CuttingCoefficients,
    CuttingConditions,
    MillingTool,
    milling_forces,
)
from ..modal.parameters import ModalParameters
from ..modal.sdof import fit_dominant_mode
from ..sim import (
    PATH_LENGTH_M,
    POSITION_1_S_M,
    POSITION_2_S_M,
    LinearMove,
    VirtualRobot,
    run_closed_loop,
    simulate_hammer_test,
)
from .lqr import design_delay_aware_lqr
from .schedule import GainSchedule, schedule_gains

__all__ = [
    "TABLE_10_CONDITIONS",
    "PathModalModel",
    "milling_study",
    "offset_mass_study",
    "path_modal_model",
]


@dataclass(frozen=True)
class PathModalModel:
    """GP of (fn, k, zeta) of the dominant mode over path distance, per direction."""

    gps: dict  #: direction -> BatchedGPRegressor on s [m] -> (fn [Hz], k [MN/m], zeta)
    s_tested_m: np.ndarray

    def mode(self, s_m: float, direction: str) -> ModalParameters:
        fn, k, z = self.gps[direction].predict(np.array([[s_m]]))[0]
        return ModalParameters(float(fn), float(k) * 1e6, float(z))


def path_modal_model(
    robot: VirtualRobot,
    directions=("x", "z"),
    n_points: int = 20,
    *,
    sample_rate_hz: float = 2048.0,
    n_hits: int = 3,
    rng=0,
) -> PathModalModel:
    """EMA at ``n_points`` along the chapter-4 path (virtual hammer tests) and a GP over s."""
    s = np.linspace(0.0, PATH_LENGTH_M, n_points)
    gen = np.random.default_rng(rng)
    gps = {}
    for d in directions:
        rows = []
        for si in s:
            rec = simulate_hammer_test(robot, si, d, domain="path", n_hits=n_hits, sample_rate_hz=sample_rate_hz,
                                       duration_s=4.0, rng=gen)  # fmt: skip
            fit = fit_dominant_mode(
                impact_frf(rec.forces, rec.responses, rec.sample_rate_hz, f_max_hz=100).frf
            )
            p = fit.parameters
            rows.append([p.natural_frequency_hz, p.stiffness_n_per_m / 1e6, p.damping_ratio])
        gps[d] = BatchedGPRegressor(kernel="isotropic", rng=rng).fit(s[:, None], np.array(rows))
    return PathModalModel(gps, s)


def _schedule(model: PathModalModel, direction: str, s_grid) -> GainSchedule:
    return schedule_gains(s_grid, [model.mode(si, direction) for si in s_grid])


def _controller(schedules: dict[int, GainSchedule | tuple[float, float]]):
    def control(t, disp, vel, coords):
        u = np.zeros(3)
        s = float(np.atleast_1d(coords)[0])
        for axis, sched in schedules.items():
            w1, w2 = sched.gains_at(s) if isinstance(sched, GainSchedule) else sched
            u[axis] = -(w1 * disp[axis] + w2 * vel[axis])
        return u

    return control


class _DelayAwareController:
    """Scheduled delay-aware LQR per axis: u = -K(s) [x, v, u_{k-1}, ..., u_{k-d}] (own history)."""

    def __init__(self, model: PathModalModel, axes: dict[int, str], s_grid, r: float = 1.0):
        self.s_grid = np.asarray(s_grid, float)
        self.k = {
            axis: np.array(
                [design_delay_aware_lqr(model.mode(si, d), r=[[r]]).gains for si in self.s_grid]
            )
            for axis, d in axes.items()
        }
        self.history = {axis: np.zeros(self.k[axis].shape[1] - 2) for axis in axes}

    def __call__(self, t, disp, vel, coords):
        s = float(np.atleast_1d(coords)[0])
        u = np.zeros(3)
        for axis, table in self.k.items():
            gains = np.array(
                [np.interp(s, self.s_grid, table[:, j]) for j in range(table.shape[1])]
            )
            hist = self.history[axis]
            ui = -(gains[0] * disp[axis] + gains[1] * vel[axis] + gains[2:] @ hist)
            self.history[axis] = np.concatenate([[ui], hist[:-1]]) if hist.size else hist
            u[axis] = ui
        return u


def _run(robot, move, force, controller, rng):
    try:
        rec = run_closed_loop(robot, move, force, 1000.0, controller, rng=rng)
        return rec.true_displacement_m, None
    except ValueError as exc:
        return None, str(exc)


def offset_mass_study(
    robot: VirtualRobot,
    model: PathModalModel,
    speeds_rpm=(480.0, 960.0),
    *,
    s_start: float = PATH_LENGTH_M,
    s_end: float = PATH_LENGTH_M - 0.9,
    speed_m_per_s: float = 0.084,
    window_s: float = 1.0,
    delay_aware_r: float = 1.0,
    keep_traces: bool = False,
    rng=0,
) -> list[dict]:
    """Table 7 analogue: X vibration amplitude at the start and end of the path, per controller.

    ``keep_traces=True`` adds the X displacement record (``trace_x_m``, 1 kHz) to each row.
    """
    from ..sim.experiments import offset_mass_force

    move = LinearMove("path", (s_start,), (s_end,))
    n = round(move.length_m / speed_m_per_s * 1000.0)
    t = np.arange(n) / 1000.0
    grid = np.linspace(min(s_start, s_end), max(s_start, s_end), 20)
    sched = _schedule(model, "x", grid)
    start_gains = sched.gains_at(s_start)
    end_gains = sched.gains_at(s_end)
    controllers = {
        "no_feedback": None,
        "pose_dependent": _controller({0: sched}),
        "constant_start": _controller({0: start_gains}),
        "constant_end": _controller({0: end_gains}),
        "delay_aware": lambda: _DelayAwareController(model, {0: "x"}, grid, delay_aware_r),
    }
    w = round(window_s * 1000)
    rows = []
    for rpm in speeds_rpm:
        force = offset_mass_force(t, rpm)
        for name, ctrl in controllers.items():
            if name == "delay_aware":
                ctrl = ctrl()  # stateful: a fresh command history per run
            disp, err = _run(robot, move, force, ctrl, rng)
            if disp is None:
                rows.append(
                    {
                        "speed_rpm": rpm,
                        "controller": name,
                        "start_mm": np.nan,
                        "end_mm": np.nan,
                        "unstable": err,
                    }
                )
                continue
            x = disp[:, 0]
            row = {"speed_rpm": rpm, "controller": name,
                   "start_mm": 1e3 * np.ptp(x[w : 2 * w]) / 2, "end_mm": 1e3 * np.ptp(x[-w:]) / 2,
                   "unstable": None}  # fmt: skip
            if keep_traces:
                row["trace_x_m"] = x
            rows.append(row)
    return rows


#: Table 10 cutting conditions: (spindle rpm, feed per tooth [m], axial depth [m]).
TABLE_10_CONDITIONS = tuple(
    (rpm, fz, ap) for rpm in (125.0, 250.0) for fz in (0.5e-3, 0.3e-3) for ap in (6e-3, 3e-3)
)


def milling_study(
    robot: VirtualRobot,
    model: PathModalModel,
    conditions=TABLE_10_CONDITIONS,
    positions=(("Position 1", POSITION_1_S_M), ("Position 2", POSITION_2_S_M)),
    *,
    tool: MillingTool | None = None,
    coefficients: CuttingCoefficients = ACETAL,
    radial_depth_m: float = 6e-3,
    cut_length_m: float = 0.05,
    background_noise_rel: float = 0.15,
    rng=0,
) -> list[dict]:
    """Table 10 analogue: RMS X and Z vibration (about the mean) open vs closed loop."""
    tool = tool or MillingTool()
    gen = np.random.default_rng(rng)
    rows = []
    for pos_name, s_mid in positions:
        move = LinearMove("path", (s_mid - cut_length_m / 2,), (s_mid + cut_length_m / 2,))
        grid = np.linspace(move.start[0], move.end[0], 6)
        ctrl = _controller({0: _schedule(model, "x", grid), 2: _schedule(model, "z", grid)})
        for i, (rpm, fz, ap) in enumerate(conditions):
            cond = CuttingConditions(rpm, fz, ap, radial_depth_m)
            n = round(move.length_m / cond.feed_speed_m_per_s(tool) * 1000.0)
            t = np.arange(n) / 1000.0
            local = milling_forces(t, tool, cond, coefficients)
            # Feed along the path (-Y); normal = Z x feed = +X; axial = Z.
            force = np.column_stack([local[:, 1], -local[:, 0], local[:, 2]])
            force += gen.normal(size=force.shape) * background_noise_rel * force.std(axis=0)
            result = {
                "test": i + 1,
                "position": pos_name,
                "speed_rpm": rpm,
                "feed_mm": fz * 1e3,
                "axial_depth_mm": ap * 1e3,
            }
            aware = _DelayAwareController(model, {0: "x", 2: "z"}, grid)
            for loop, c in (("open", None), ("control", ctrl), ("delay_aware", aware)):
                disp, err = _run(robot, move, force, c, rng)
                for axis, d in ((0, "x"), (2, "z")):
                    result[f"{d}_{loop}_rms_mm"] = (
                        np.nan if disp is None else 1e3 * np.std(disp[n // 5 :, axis])
                    )
                result[f"{loop}_unstable"] = err
            for d in ("x", "z"):
                result[f"{d}_reduction_pct"] = 100 * (
                    1 - result[f"{d}_control_rms_mm"] / result[f"{d}_open_rms_mm"]
                )
                result[f"{d}_delay_aware_reduction_pct"] = 100 * (
                    1 - result[f"{d}_delay_aware_rms_mm"] / result[f"{d}_open_rms_mm"]
                )
            rows.append(result)
    return rows


def split_traces(rows: list[dict]) -> tuple[list[dict], list[np.ndarray]]:
    """Rows of :func:`offset_mass_study` without their ``trace_x_m`` records, and the records.

    Returns
    -------
    rows
        Copies of the rows without the trace (JSON/table friendly).
    traces
        (n,) X displacement [m] at 1 kHz, one per row that had one (stable runs).
    """
    out, traces = [], []
    for r in rows:
        r = dict(r)
        if "trace_x_m" in r:
            traces.append(np.asarray(r.pop("trace_x_m")))
        out.append(r)
    return out, traces


def plot_offset_mass(rows: list[dict], ax=None):
    """X vibration per controller at the first spindle speed (thesis Fig. 24 analogue).

    Parameters
    ----------
    rows
        Rows of :func:`offset_mass_study` run with ``keep_traces=True``.
    ax
        Matplotlib axes; a new figure if None.

    Returns
    -------
    matplotlib.figure.Figure
    """
    import matplotlib.pyplot as plt

    if ax is None:
        fig, ax = plt.subplots(figsize=(9, 4))
    else:
        fig = ax.figure
    first = rows[0]["speed_rpm"]
    for r in rows:
        if r["speed_rpm"] == first and "trace_x_m" in r:
            x = np.asarray(r["trace_x_m"])
            ax.plot(np.arange(x.size) / 1000.0, 1e3 * x, lw=0.7, label=r["controller"])
    ax.set_xlabel("time [s] (robot moving from the extended end toward the base)")
    ax.set_ylabel("X vibration [mm]")
    ax.set_title(f"offset mass at {first:g} rpm on the virtual robot")
    ax.legend(fontsize=8)
    fig.tight_layout()
    return fig


def virtual_path_modes(
    robot: VirtualRobot | None = None, direction: str = "x", n_points: int = 20, rng=0
) -> tuple[np.ndarray, list[ModalParameters]]:
    """Dominant modes along the chapter-4 path from a virtual EMA (:func:`path_modal_model`).

    Returns
    -------
    s_m
        (n_points,) path coordinates [m], 0.335-1.235 m.
    modes
        One :class:`ModalParameters` per coordinate in ``direction``.
    """
    model = path_modal_model(robot or VirtualRobot(), directions=(direction,), rng=rng)
    s = np.linspace(0.335, 1.235, n_points)
    return s, [model.mode(si, direction) for si in s]
