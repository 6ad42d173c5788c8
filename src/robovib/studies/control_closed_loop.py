"""Closed-loop studies on the virtual robot (thesis §4.2-4.4, Tables 7 and 10).

The studies compose library code: the path model from the virtual EMA
(:func:`robovib.sim.path_modal_model`), the controllers designed from it alone
(:func:`robovib.control.design.build_controllers`), the command-channel models
(:mod:`robovib.control.channel`, :class:`robovib.sim.CommandChannel`) and the closed-loop
simulator (:func:`robovib.sim.run_closed_loop`). Those names are re-exported here.

1. :func:`fixed_pose_offset_mass` (§4.3.2): the thesis' own gains 0.079 / 0.0059 on the mode it
   measured (8.5 Hz, 0.775 MN/m, 0.179) at 480 / 960 / 1440 rpm, open vs closed loop, through a
   given command channel; :func:`calibrate_channel` searches the channel options against
   §4.3.2 and Table 7; :func:`~robovib.control.channel.sensitivity_bound` is the best any
   non-amplifying channel allows.
2. :func:`offset_mass_study` (Table 7 analogue): 1 kg at 50.8 mm while the robot moves 900 mm
   toward the base at 84 mm/s; the controllers of
   :func:`~robovib.control.design.build_controllers`.
3. :func:`milling_study` (Table 10 analogue): the eight cuts at Positions 1 and 2, X and Z.
4. :func:`simulate_control`: one entry point (the CLI's ``control simulate``).

Measurement realism comes from :func:`robovib.sim.run_closed_loop`: tracker at 1 kHz with
noise and 0.01 mm resolution, force sensor with 0.5 N noise, commands at 250 Hz through a
:class:`~robovib.sim.CommandChannel` (default: 32 ms pure delay).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..control.adaptive import FadeGuard
from ..control.band_stability import stability_over_band
from ..control.channel import (
    THESIS_OFFSET_MASS_GAINS,
    THESIS_OFFSET_MASS_MODE,
    operating_mode,
    required_channel_gain,
    sensitivity_bound,
)
from ..control.controllers import ScheduledTable, StateFeedback
from ..control.design import (
    CONTROLLERS,
    DEFAULT_CONTROLLER,
    THESIS_PRINTED_END_GAINS,
    THESIS_PRINTED_START_GAINS,
    build_controllers,
    thesis_printed_gains,
)
from ..control.pose_plants import SECOND_MODE_HYPOTHESES, path_band, path_mode
from ..gp import PoseModalModel
from ..milling.forces import (
    ACETAL,
    CuttingCoefficients,
    CuttingConditions,
    MillingTool,
)
from ..modal.parameters import ModalParameters
from ..sim import (
    ACTUATORS,
    PATH_LENGTH_M,
    POSITION_1_S_M,
    POSITION_2_S_M,
    PURE_DELAY,
    CommandChannel,
    ConstantModesRobot,
    CutDisturbances,
    LinearMove,
    ModeSet,
    VirtualRobot,
    offset_mass_force,
    path_modal_model,
    run_closed_loop,
    virtual_path_modes,
)

__all__ = [
    "ACTUATORS",
    "CONTROLLERS",
    "DEFAULT_CONTROLLER",
    "SECOND_MODE_HYPOTHESES",
    "TABLE_10_CONDITIONS",
    "THESIS_OFFSET_MASS_MODE",
    "ControlSimulation",
    "build_controllers",
    "calibrate_channel",
    "file_milling_positions",
    "fixed_pose_offset_mass",
    "milling_study",
    "offset_mass_study",
    "operating_mode",
    "path_band",
    "path_modal_model",
    "path_mode",
    "plot_milling",
    "plot_offset_mass",
    "required_channel_gain",
    "sensitivity_bound",
    "simulate_control",
    "stability_over_band",
    "virtual_path_modes",
]

# The §4.3.2 calibration target is withdrawn (issue 25). The thesis reports the offset mass
# at 8.5 Hz going from 0.93 to 0.39 mm with the gains 0.079 / 0.0059 (closed/open 0.42 at 480
# and 960 rpm). No command channel of gain <= 1 can do that: :func:`sensitivity_bound` limits
# the closed/open ratio of those gains on the thesis' measured mode to >= 0.53 at 8 Hz and
# >= 0.81 at 16 Hz (:func:`required_channel_gain`: the channel would have to amplify >= 1.6x at
# 8 Hz and >= 6x at 16 Hz). :func:`calibrate_channel` searched lag, breakaway, rate limit, RSI
# hold and lightly damped servos: the pure 32 ms delay fits best among the non-amplifying
# channels (RMS log error of the ratios 0.78) and the amplifying servos that come within 20 %
# make the Eq. 28-29 schedule unstable on the Table 7 path, which the thesis measured stable.
# The studies therefore use the pure delay (:data:`~robovib.sim.PURE_DELAY`) and no
# "calibrated" channel exists.


# --------------------------------------------------------------------------- runs
def _run(robot, move, force, controller, rng, channel, **sensor):
    try:
        rec = run_closed_loop(robot, move, force, 1000.0, controller, channel=channel, rng=rng,
                              **sensor)  # fmt: skip
        return rec.true_displacement_m, None
    except ValueError as exc:
        return None, str(exc)


def fixed_pose_offset_mass(
    channel: CommandChannel = PURE_DELAY,
    speeds_rpm=(480.0, 960.0, 1440.0),
    *,
    mode: ModalParameters = THESIS_OFFSET_MASS_MODE,
    gains=THESIS_OFFSET_MASS_GAINS,
    duration_s: float = 2.0,
    settle_s: float = 1.0,
    rng=0,
) -> list[dict]:
    """§4.3.2: the offset mass at a fixed pose, open loop vs the thesis gains, in Y.

    Amplitudes are peak-to-peak [mm] of the true Y vibration after ``settle_s``
    (§4.3.2's 0.93 mm open loop at 480 rpm matches the peak-to-peak of the measured mode's
    response, 2 x 0.46 mm; Table 7's numbers match half of it).

    Parameters
    ----------
    channel
        Command channel between controller and robot (default: 32 ms pure delay).
    speeds_rpm
        Spindle speeds [rev/min] of the offset mass.
    mode
        The Y mode of the fixed pose (default §4.3.2's measured mode).
    gains
        State-feedback gains (w1, w2) of the closed loop (default the thesis' 0.079 / 0.0059).
    duration_s
        Simulated time per run [s].
    settle_s
        Time skipped before the amplitude is read [s].
    rng
        Seed of the sensor noise.

    Returns
    -------
    list of dict
        One row per speed: ``speed_rpm``, ``open_ptp_mm`` and ``closed_ptp_mm`` [mm] (NaN when
        unstable), ``open_unstable`` / ``closed_unstable`` (the error message or None) and
        ``ratio`` (closed / open).
    """
    robot = ConstantModesRobot(
        {
            "y": ModeSet(
                np.array([[mode.natural_frequency_hz]]),
                np.array([[mode.stiffness_n_per_m]]),
                np.array([[mode.damping_ratio]]),
            )
        }
    )
    n = round(duration_s * 1000)
    t = np.arange(n) / 1000.0
    move = LinearMove("path", (0.0,), (0.04,))  # 20 mm/s for 2 s; the modes do not change
    w = round(settle_s * 1000)
    rows = []
    for rpm in speeds_rpm:
        force = offset_mass_force(t, rpm)
        row = {"speed_rpm": rpm}
        for name, ctrl in (("open", None), ("closed", StateFeedback({1: gains}))):
            disp, err = _run(robot, move, force, ctrl, rng, channel)
            row[f"{name}_ptp_mm"] = np.nan if disp is None else 1e3 * np.ptp(disp[w:, 1])
            row[f"{name}_unstable"] = err
        row["ratio"] = row["closed_ptp_mm"] / row["open_ptp_mm"]
        rows.append(row)
    return rows


def _settle_time_s(channel: CommandChannel, mode: ModalParameters) -> float:
    """Five of the slowest open time constants (mode, lag, servo), at least 1 s: the window
    after which a closed-loop amplitude is read as steady."""
    taus = [1.0 / (mode.damping_ratio * mode.omega_n), channel.lag_s]
    if math.isfinite(channel.servo_hz):
        taus.append(1.0 / (channel.servo_damping * 2 * math.pi * channel.servo_hz))
    return max(1.0, 5.0 * max(taus))


def calibrate_channel(
    delays_s=(0.0, 0.008, 0.016, 0.024, 0.032),
    lags_s=(0.0, 0.01, 0.02, 0.04),
    breakaways_m=(0.0, 2e-5),
    rate_limits_m_per_s=(math.inf, 0.05),
    holds=(0, 1),
    servo_hz=(math.inf,),
    servo_dampings=(0.7,),
    *,
    mode: ModalParameters = THESIS_OFFSET_MASS_MODE,
    targets=((480.0, 0.93, 0.39), (960.0, 0.36, 0.15)),
    rng=0,
) -> list[dict]:
    """Grid search of the channel options against the §4.3.2 open / closed amplitudes.

    Each channel runs the thesis gains on ``mode`` (:func:`fixed_pose_offset_mass`) at the
    target speeds and 1440 rpm, read after five of the slowest time constants of the mode and
    the channel (at least 1 s), so lightly damped servos are compared in steady state.

    Parameters
    ----------
    delays_s, lags_s, breakaways_m, rate_limits_m_per_s, holds, servo_hz, servo_dampings
        The grid of :class:`~robovib.sim.CommandChannel` options (``servo_dampings`` only
        with a finite ``servo_hz``).
    mode
        The plant mode (the hammer test's, or :func:`operating_mode`).
    targets
        (rpm, thesis open [mm], thesis closed [mm]) triples, peak to peak.
    rng
        Seed of the sensor noise.

    Returns
    -------
    list of dict
        One row per channel: its settings, ``ratio_<rpm>`` and ``closed_<rpm>_mm``,
        ``score`` (RMS log error of the closed / open ratios), ``closed_error`` (largest
        relative error of the closed amplitudes: what the channel changes), ``open_error``
        (of the open amplitudes: the mode's alone, the same for every channel) and
        ``max_error`` (the larger; "within 20 %" is ``max_error <= 0.2``). Sorted by
        ``closed_error``, then ``score``.

    Raises
    ------
    ValueError
        Malformed ``targets``.
    """
    tgt = np.asarray(targets, float)
    if tgt.ndim != 2 or tgt.shape[1] != 3 or not np.all(np.isfinite(tgt)) or np.any(tgt <= 0):
        raise ValueError(
            "targets must be (rpm, open_mm, closed_mm) triples of positive numbers, "
            f"got {targets!r}"
        )
    speeds = tuple(dict.fromkeys([*tgt[:, 0].tolist(), 1440.0]))
    rows = []
    grid = [(d, lag, b, rl, h, fs, zs) for d in delays_s for lag in lags_s for b in breakaways_m
            for rl in rate_limits_m_per_s for h in holds for fs in servo_hz
            for zs in (servo_dampings if math.isfinite(fs) else servo_dampings[:1])]  # fmt: skip
    for d, lag, b, rl, h, fs, zs in grid:
        ch = CommandChannel(d, lag_s=lag, rate_limit_m_per_s=rl, breakaway_m=b, hold_periods=h,
                            servo_hz=fs, servo_damping=zs)  # fmt: skip
        settle = _settle_time_s(ch, mode)
        res = fixed_pose_offset_mass(ch, speeds, mode=mode, duration_s=settle + 1.0,
                                     settle_s=settle, rng=rng)  # fmt: skip
        by = {r["speed_rpm"]: r for r in res}
        log_err, open_err, closed_err = [], [], []
        for rpm, open_mm, closed_mm in tgt:
            row = by[rpm]
            log_err.append(math.log(row["ratio"] / (closed_mm / open_mm)))
            open_err.append(abs(row["open_ptp_mm"] / open_mm - 1))
            closed_err.append(abs(row["closed_ptp_mm"] / closed_mm - 1))
        closed_e, open_e = float(np.max(closed_err)), float(np.max(open_err))
        rows.append({**ch.to_dict(),
                     **{f"ratio_{int(r['speed_rpm'])}": r["ratio"] for r in res},
                     **{f"closed_{int(r['speed_rpm'])}_mm": r["closed_ptp_mm"] for r in res},
                     "score": float(np.sqrt(np.mean(np.square(log_err)))),
                     "closed_error": closed_e, "open_error": open_e,
                     "max_error": max(closed_e, open_e)})  # fmt: skip
    rows.sort(key=lambda r: (np.nan_to_num(r["closed_error"], nan=np.inf),
                             np.nan_to_num(r["score"], nan=np.inf)))  # fmt: skip
    return rows


def offset_mass_study(
    robot: VirtualRobot,
    model: PoseModalModel,
    speeds_rpm=(480.0, 960.0),
    *,
    controllers=(
        "thesis",
        "constant-start",
        "constant-end",
        "lqg",
        "robust",
        "feedforward",
        "feedforward+robust",
    ),
    channel: CommandChannel = PURE_DELAY,
    thesis_gains: bool = False,
    s_start: float = PATH_LENGTH_M,
    s_end: float = PATH_LENGTH_M - 0.9,
    speed_m_per_s: float = 0.084,
    window_s: float = 1.0,
    keep_traces: bool = False,
    rng=0,
) -> list[dict]:
    """Table 7 analogue: X vibration amplitude (half peak-to-peak) at the start and end.

    ``thesis_gains=True`` adds the thesis' printed gains (Eq. 28-29 schedule and the constants
    0.11 / 0.0065 and 0.06 / 0.005) as ``thesis-printed``, ``thesis-printed-start`` and
    ``thesis-printed-end``. ``keep_traces=True`` adds the X displacement record
    (``trace_x_m``, 1 kHz) to each row.

    Parameters
    ----------
    robot
        The virtual robot (the truth; the controllers see only ``model``).
    model
        The path model the controllers are designed from (:func:`path_modal_model`).
    speeds_rpm
        Spindle speeds of the offset mass [rev/min].
    controllers
        Controller names from :data:`CONTROLLERS` (``"no-feedback"`` is always run).
    channel
        Command channel between controller and robot.
    thesis_gains
        Also run the thesis' printed gains.
    s_start, s_end
        Path distances [m] where the move starts and ends.
    speed_m_per_s
        Path speed [m/s].
    window_s
        Length of the start and end windows in which the amplitude is read [s].
    keep_traces
        Keep the X displacement records.
    rng
        Seed of the sensor noise.

    Returns
    -------
    list of dict
        One row per speed and controller: ``speed_rpm``, ``controller``, ``start_mm`` and
        ``end_mm`` (half peak-to-peak [mm], NaN when unstable), ``unstable`` (the error
        message or None) and, with ``keep_traces``, ``trace_x_m``.
    """
    move = LinearMove("path", (s_start,), (s_end,))
    n = round(move.length_m / speed_m_per_s * 1000.0)
    t = np.arange(n) / 1000.0
    grid = np.linspace(min(s_start, s_end), max(s_start, s_end), 20)
    w = round(window_s * 1000)
    rows = []
    for rpm in speeds_rpm:
        force = offset_mass_force(t, rpm)
        ctrls = {"no-feedback": None}
        ctrls.update(build_controllers(model, {0: "x"}, grid, names=controllers,
                                       excitation_period_s=60.0 / rpm, s_start=s_start, s_end=s_end))  # fmt: skip
        if thesis_gains:
            tab = thesis_printed_gains(grid, s_start)
            ctrls["thesis-printed"] = StateFeedback({0: ScheduledTable(grid, tab)})
            ctrls["thesis-printed-start"] = StateFeedback({0: THESIS_PRINTED_START_GAINS})
            ctrls["thesis-printed-end"] = StateFeedback({0: THESIS_PRINTED_END_GAINS})
        for name, ctrl in ctrls.items():
            disp, err = _run(robot, move, force, ctrl, rng, channel)
            row = {"speed_rpm": rpm, "controller": name, "start_mm": np.nan, "end_mm": np.nan,
                   "unstable": err}  # fmt: skip
            if disp is not None:
                x = disp[:, 0]
                row["start_mm"] = 1e3 * np.ptp(x[w : 2 * w]) / 2
                row["end_mm"] = 1e3 * np.ptp(x[-w:]) / 2
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
    model: PoseModalModel,
    conditions=TABLE_10_CONDITIONS,
    positions=(("Position 1", POSITION_1_S_M), ("Position 2", POSITION_2_S_M)),
    *,
    controllers=("thesis", "lqg", "robust", "feedforward", "feedforward+robust"),
    channel: CommandChannel = PURE_DELAY,
    tool: MillingTool | None = None,
    coefficients: CuttingCoefficients = ACETAL,
    radial_depth_m: float = 6e-3,
    cut_length_m: float = 0.05,
    background_noise_rel: float = 0.15,
    disturbances: CutDisturbances | None = None,
    keep_traces: bool = False,
    runtime=None,
    rng=0,
) -> list[dict]:
    """Table 10 analogue: RMS X and Z vibration [mm] (about the mean) open vs each controller.

    ``disturbances`` (:class:`~robovib.sim.disturbances.CutDisturbances`) make the cut real:
    spindle-speed error, runout, non-periodic force, engagement, force-sensor noise and bias
    (on the force the controllers see), actuator gain and delay errors (of the true channel;
    the controllers keep the nominal ones). A guarded controller's fade-out events go to the
    row's ``guard_events``.

    One row per cut, position and controller with ``x_rms_mm``, ``z_rms_mm``, the open-loop
    values and the reductions [%] (NaN and ``unstable`` set when the loop went unstable).
    The RMS is taken after the first fifth of the cut (start-up transient).

    Parameters
    ----------
    robot
        The virtual robot (the truth; the controllers see only ``model``).
    model
        The path model with directions x and z (:func:`path_modal_model`).
    conditions
        (spindle rpm, feed per tooth [m], axial depth [m]) per cut.
    positions
        (name, path distance [m] of the cut's middle) pairs, or (name,
        :class:`~robovib.sim.LinearMove`) pairs: the cut itself (e.g. in the workspace).
    controllers
        Controller names from :data:`CONTROLLERS` (open loop is always run).
    channel
        Nominal command channel (the disturbances may change the true one).
    tool
        The milling tool (default :class:`robovib.milling.MillingTool`).
    coefficients
        Cutting-force coefficients (default acetal).
    radial_depth_m
        Radial depth of cut [m].
    cut_length_m
        Length of each cut along the path [m].
    background_noise_rel
        Std of white noise added to each force component, relative to its std.
    disturbances
        Disturbances of a real cut (default none).
    keep_traces
        Keep the X and Z displacement records (``trace_m``, (n, 2) [m]).
    runtime
        A :class:`~robovib.control.runtime.RuntimeController` (a controller file) to run
        instead of ``controllers``: the one controller of the file, every step through its
        ``step`` (row name ``"<name> (file)"``; ``commands_mm`` with ``keep_traces``).
    rng
        Seed of the force noise and the sensor noise.

    Returns
    -------
    list of dict
        One row per cut, position and controller (see above).
    """
    tool = tool or MillingTool()
    dist = disturbances or CutDisturbances()
    true_channel = dist.channel(channel)
    sensor = {"force_noise_n": math.hypot(0.5, dist.force_noise_n),
              "force_bias_n": dist.force_bias_n}  # fmt: skip
    gen = np.random.default_rng(rng)
    rows = []
    for pos_name, s_mid in positions:
        if isinstance(s_mid, LinearMove):
            move = s_mid
        else:
            move = LinearMove("path", (s_mid - cut_length_m / 2,), (s_mid + cut_length_m / 2,))
        grid = np.linspace(move.start[0], move.end[0], 6)
        for i, (rpm, fz, ap) in enumerate(conditions):
            cond = CuttingConditions(rpm, fz, ap, radial_depth_m)
            n = round(move.length_m / cond.feed_speed_m_per_s(tool) * 1000.0)
            t = np.arange(n) / 1000.0
            local = dist.cutting_force(t, tool, cond, coefficients, rng=gen)
            if move.domain == "path":
                # Feed along the path (-Y); normal = Z x feed = +X; axial = Z.
                force = np.column_stack([local[:, 1], -local[:, 0], local[:, 2]])
            else:  # feed along the move; normal = Z x feed; axial = Z
                feed = move.feed_direction()
                normal = np.cross([0.0, 0.0, 1.0], feed)
                force = np.outer(local[:, 0], feed) + np.outer(local[:, 1], normal)
                force[:, 2] += local[:, 2]
            force += gen.normal(size=force.shape) * background_noise_rel * force.std(axis=0)
            ctrls = {"open": None}
            if runtime is not None:
                ctrls[f"{runtime.name} (file)"] = runtime.planned(rpm, tool.n_flutes)
            else:
                ctrls.update(build_controllers(model, {0: "x", 2: "z"}, grid, names=controllers,
                                               excitation_period_s=1.0 / cond.tooth_passing_hz(tool),
                                               teeth=tool.n_flutes))  # fmt: skip
            base = {"test": i + 1, "position": pos_name, "speed_rpm": rpm, "feed_mm": fz * 1e3,
                    "axial_depth_mm": ap * 1e3}  # fmt: skip
            open_rms = None
            for name, ctrl in ctrls.items():
                disp, err = _run(robot, move, force, ctrl, rng, true_channel, **sensor)
                row = {**base, "controller": name, "unstable": err}
                if isinstance(ctrl, FadeGuard) or hasattr(ctrl, "all_events"):
                    row["guard_events"] = "; ".join(
                        f"{e.time_s:.2f} s -> {e.target:g}: {e.reason}" for e in ctrl.all_events()
                    )
                for axis, d in ((0, "x"), (2, "z")):
                    rms = np.nan if disp is None else 1e3 * np.std(disp[n // 5 :, axis])
                    row[f"{d}_rms_mm"] = rms
                    if open_rms is not None:
                        row[f"{d}_open_rms_mm"] = open_rms[d]
                        row[f"{d}_reduction_pct"] = 100 * (1 - rms / open_rms[d])
                if keep_traces and disp is not None:
                    row["trace_m"] = disp[:, [0, 2]]
                    if runtime is not None and name != "open":
                        row["trace_commands_mm"] = ctrl.commands_mm.copy()
                if name == "open":
                    open_rms = {"x": row["x_rms_mm"], "z": row["z_rms_mm"]}
                    continue
                rows.append(row)
    return rows


# --------------------------------------------------------------------------- figures
def plot_offset_mass(rows: list[dict], speed_rpm: float | None = None, ax=None):
    """Vibration envelope (moving max of |x| over 0.25 s) [mm] vs time per controller.

    Parameters
    ----------
    rows
        From :func:`offset_mass_study` with ``keep_traces=True``.
    speed_rpm
        The speed drawn [rev/min] (default the first traced row's).
    ax
        Axes to draw into; a new figure when None.

    Returns
    -------
    matplotlib.figure.Figure

    Raises
    ------
    ValueError
        No traces in the rows.
    """
    import matplotlib.pyplot as plt
    from scipy.ndimage import maximum_filter1d

    traced = [r for r in rows if "trace_x_m" in r]
    if not traced:
        raise ValueError("no traces in the rows: run offset_mass_study(..., keep_traces=True)")
    speed = traced[0]["speed_rpm"] if speed_rpm is None else speed_rpm
    if ax is None:
        fig, ax = plt.subplots(figsize=(9, 4))
    else:
        fig = ax.figure
    for r in traced:
        if r["speed_rpm"] != speed:
            continue
        x = np.abs(r["trace_x_m"]) * 1e3
        env = maximum_filter1d(x, size=250)
        ax.plot(np.arange(x.size) / 1000.0, env, lw=1.0, label=r["controller"])
    ax.set_xlabel("time [s] (robot moving from the extended end toward the base)")
    ax.set_ylabel("X vibration envelope [mm]")
    ax.set_title(f"offset mass at {speed:g} rpm on the virtual robot (Table 7 analogue)")
    ax.legend(fontsize=8, ncol=2)
    fig.tight_layout()
    return fig


def plot_milling(rows: list[dict], direction: str = "x", ax=None):
    """RMS vibration [mm] per cut for each controller, both positions (Table 10 analogue).

    Open loop drawn as black ticks; unstable runs as missing bars.

    Parameters
    ----------
    rows
        From :func:`milling_study`.
    direction
        ``"x"`` or ``"z"``.
    ax
        Axes to draw into; a new figure when None.

    Returns
    -------
    matplotlib.figure.Figure

    Raises
    ------
    ValueError
        Unknown direction or no rows.
    """
    import matplotlib.pyplot as plt

    if direction not in ("x", "z"):
        raise ValueError(f"direction must be 'x' or 'z', got {direction!r}")
    if not rows:
        raise ValueError("no milling rows to plot")
    if ax is None:
        fig, ax = plt.subplots(figsize=(10, 4))
    else:
        fig = ax.figure
    cuts = sorted({(r["position"], r["test"]) for r in rows})
    names = list(dict.fromkeys(r["controller"] for r in rows))
    width = 0.8 / max(len(names), 1)
    x0 = np.arange(len(cuts))
    for j, name in enumerate(names):
        vals = []
        for cut in cuts:
            match = [
                r for r in rows if (r["position"], r["test"]) == cut and r["controller"] == name
            ]
            vals.append(match[0][f"{direction}_rms_mm"] if match else np.nan)
        ax.bar(x0 + (j - (len(names) - 1) / 2) * width, vals, width, label=name)
    opens = []
    for cut in cuts:
        match = [r for r in rows if (r["position"], r["test"]) == cut]
        opens.append(match[0][f"{direction}_open_rms_mm"])
    ax.scatter(x0, opens, marker="_", s=400, color="k", label="open loop", zorder=3)
    ax.set_xticks(x0, [f"{p[-1]}-T{t}" for p, t in cuts], fontsize=7)
    ax.set_xlabel("position - test (Table 10 cuts)")
    ax.set_ylabel(f"RMS {direction.upper()} vibration [mm]")
    ax.set_title(f"milling on the virtual robot: {direction.upper()} vibration per controller")
    ax.legend(fontsize=7, ncol=3)
    fig.tight_layout()
    return fig


# --------------------------------------------------------------------------- one entry point
@dataclass(frozen=True)
class ControlSimulation:
    """Result of :func:`simulate_control`: rows (one per run) and the settings used.

    Attributes
    ----------
    experiment
        ``"offset-mass"`` (Table 7 analogue) or ``"milling"`` (Table 10 analogue).
    rows
        Tuple of dicts, one per run (see :func:`offset_mass_study`, :func:`milling_study`);
        traces (``trace_x_m`` / ``trace_m``) only with ``keep_traces``.
    settings
        Controllers, actuator and channel, command period [s], sample rate [Hz], seed,
        speeds [rpm] and active disturbances.
    """

    experiment: str
    rows: tuple
    settings: dict

    def to_frame(self):
        """The rows as a table, without the traces.

        Returns
        -------
        pandas.DataFrame
            One row per run, the columns of the result rows.
        """
        import pandas as pd

        return pd.DataFrame(
            [{k: v for k, v in r.items() if not k.startswith("trace")} for r in self.rows]
        )

    def to_dict(self) -> dict:
        """JSON-ready dict: settings, rows (no traces) and the units of every column.

        Returns
        -------
        dict
            ``experiment``, ``settings``, ``rows`` (NaN as None) and ``units``.
        """
        rows = self.to_frame().replace({np.nan: None}).to_dict(orient="records")
        units = {"speed_rpm": "rev/min", "start_mm": "mm (half peak-to-peak)",
                 "end_mm": "mm (half peak-to-peak)", "feed_mm": "mm per tooth",
                 "axial_depth_mm": "mm"}  # fmt: skip
        for d in ("x", "z"):
            units[f"{d}_rms_mm"] = units[f"{d}_open_rms_mm"] = "mm (RMS about the mean)"
            units[f"{d}_reduction_pct"] = "% of the open-loop RMS"
        return {
            "experiment": self.experiment,
            "settings": self.settings,
            "rows": rows,
            "units": units,
        }

    def plot(self, direction: str = "x", ax=None):
        """:func:`plot_offset_mass` (needs traces) or :func:`plot_milling` of the rows.

        Parameters
        ----------
        direction
            Milling only: ``"x"`` or ``"z"``.
        ax
            Axes to draw into; a new figure when None.

        Returns
        -------
        matplotlib.figure.Figure
        """
        if self.experiment == "offset-mass":
            return plot_offset_mass(list(self.rows), ax=ax)
        return plot_milling(list(self.rows), direction, ax=ax)


def simulate_control(
    experiment: str,
    controllers=None,
    *,
    actuator: str = "pure-delay",
    speeds_rpm=(480.0, 960.0),
    disturbances: CutDisturbances | None = None,
    keep_traces: bool = False,
    controller_file=None,
    rng=0,
) -> ControlSimulation:
    """Closed-loop runs on the virtual robot with controllers designed from the path model.

    Parameters
    ----------
    experiment
        ``"offset-mass"`` (Table 7 analogue, X, 900 mm path) or ``"milling"`` (Table 10
        analogue, X and Z, 8 cuts x 2 positions).
    controllers
        Names from :data:`CONTROLLERS` (default: all).
    actuator
        ``"pure-delay"`` (32 ms), the only channel (the §4.3.2 calibration is withdrawn: no
        channel of gain <= 1 reproduces it, :func:`sensitivity_bound`).
    speeds_rpm
        Offset-mass spindle speeds [rev/min].
    disturbances
        Milling only: the disturbances of a real cut
        (:class:`~robovib.sim.disturbances.CutDisturbances`, e.g. from ``CutDisturbances.parse``).
    keep_traces
        Keep the displacement records (for :meth:`ControlSimulation.plot`).
    controller_file
        Milling only: a controller file (path) or
        :class:`~robovib.control.runtime.RuntimeController` to run instead of ``controllers``
        (:func:`file_milling_positions` says where its cuts are).
    rng
        Seed of the virtual EMA and the sensor noise.

    Returns
    -------
    ControlSimulation
        The result rows and the settings used.

    Raises
    ------
    ValueError
        Unknown experiment, controller or actuator; disturbances with the offset mass.
    """
    if experiment not in ("offset-mass", "milling"):
        raise ValueError(f"unknown experiment {experiment!r}; expected 'offset-mass' or 'milling'")
    if actuator not in ACTUATORS:
        raise ValueError(f"unknown actuator {actuator!r}; expected one of {sorted(ACTUATORS)}")
    names = tuple(CONTROLLERS if controllers is None else controllers)
    unknown = set(names) - set(CONTROLLERS)
    if unknown:
        raise ValueError(f"unknown controllers {sorted(unknown)}; expected some of {CONTROLLERS}")
    channel = ACTUATORS[actuator]
    if disturbances is not None and disturbances.active() and experiment != "milling":
        raise ValueError("disturbances apply to the milling experiment only")
    if controller_file is not None:
        if controllers is not None:
            raise ValueError("give either controllers or a controller file, not both")
        if experiment != "milling":
            raise ValueError("a controller file runs the milling experiment only")
        return _simulate_file(controller_file, channel, actuator, disturbances, keep_traces, rng)
    robot = VirtualRobot()
    model = path_modal_model(
        robot, directions=("x",) if experiment == "offset-mass" else ("x", "z"), rng=rng
    )
    if experiment == "offset-mass":
        rows = offset_mass_study(robot, model, speeds_rpm, controllers=names, channel=channel,
                                 keep_traces=keep_traces, rng=rng)  # fmt: skip
    else:
        rows = milling_study(robot, model, controllers=names, channel=channel,
                             disturbances=disturbances, keep_traces=keep_traces, rng=rng)  # fmt: skip
    settings = {"controllers": list(names), "actuator": actuator, "channel": channel.to_dict(),
                "command_period_s": 0.004, "sample_rate_hz": 1000.0, "seed": rng,
                "speeds_rpm": list(speeds_rpm) if experiment == "offset-mass" else None,
                "disturbances": (disturbances or CutDisturbances()).active()}  # fmt: skip
    return ControlSimulation(experiment, tuple(rows), settings)


def file_milling_positions(runtime, cut_length_m: float = 0.05) -> tuple:
    """Where the Table 10 cuts of a controller file run on the virtual robot.

    A file designed on a path model (input ``s_m``) cuts at Positions 1 and 2 of the chapter-4
    path (s = 0.35 and 1.00 m). A file designed on a workspace model (``x_mm, y_mm, rz_deg``)
    cuts on its own path, at the same fractions of it (0.35 / 1.235 and 1.00 / 1.235), each
    cut ``cut_length_m`` long in the workspace.

    Parameters
    ----------
    runtime : RuntimeController
        The controller file.
    cut_length_m : float
        Length of each cut [m].

    Returns
    -------
    tuple
        (name, path distance [m] or :class:`~robovib.sim.LinearMove`) pairs.

    Raises
    ------
    ValueError
        A path too short for the cuts, or inputs the virtual robot does not have.
    """
    path = runtime.path
    if path.input_names == ("s_m",):
        return (("Position 1", POSITION_1_S_M), ("Position 2", POSITION_2_S_M))
    if set(path.input_names) != {"x_mm", "y_mm", "rz_deg"}:
        raise ValueError(f"the virtual robot's workspace has x_mm, y_mm, rz_deg; the controller's "
                         f"path is in {', '.join(path.input_names)}")  # fmt: skip
    if path.length_m < 2 * cut_length_m:
        raise ValueError(f"the controller's path ({path.length_m:.3f} m) is too short for "
                         f"{cut_length_m * 1e3:g} mm cuts")  # fmt: skip
    out = []
    for name, s_ref in (("Position 1", POSITION_1_S_M), ("Position 2", POSITION_2_S_M)):
        mid = path.s_m[0] + s_ref / PATH_LENGTH_M * path.length_m
        lo = min(max(mid - cut_length_m / 2, path.s_m[0]), path.s_m[-1] - cut_length_m)
        ends = path.poses_at([lo, lo + cut_length_m])
        cols = [path.input_names.index(n) for n in ("x_mm", "y_mm", "rz_deg")]
        a, b = ends[0, cols], ends[1, cols]
        out.append((name, LinearMove("workspace", (a[0] * 1e-3, a[1] * 1e-3, a[2]),
                                     (b[0] * 1e-3, b[1] * 1e-3, b[2]))))  # fmt: skip
    return tuple(out)


def _simulate_file(controller_file, channel, actuator, disturbances, keep_traces, rng):
    from ..control.runtime import RuntimeController, load_controller

    runtime = (controller_file if isinstance(controller_file, RuntimeController)
               else load_controller(controller_file))  # fmt: skip
    positions = file_milling_positions(runtime)
    rows = milling_study(VirtualRobot(), None, positions=positions, channel=channel,
                         disturbances=disturbances, keep_traces=keep_traces, runtime=runtime,
                         rng=rng)  # fmt: skip
    settings = {"controllers": [f"{runtime.name} (file)"], "actuator": actuator,
                "channel": channel.to_dict(), "command_period_s": runtime.period_s,
                "sample_rate_hz": runtime.sample_rate_hz, "seed": rng, "speeds_rpm": None,
                "disturbances": (disturbances or CutDisturbances()).active(),
                "controller_file": runtime.doc.get("provenance", {}),
                "positions": [{"name": p, "path_s_m": m} if not isinstance(m, LinearMove) else
                              {"name": p, "start_x_m": m.start[0], "start_y_m": m.start[1],
                               "start_rz_deg": m.start[2], "end_x_m": m.end[0],
                               "end_y_m": m.end[1], "end_rz_deg": m.end[2]}
                              for p, m in positions]}  # fmt: skip
    return ControlSimulation("milling", tuple(rows), settings)
