"""The milling study (thesis Table 10 analogue) and its figure."""

from __future__ import annotations

import math

import numpy as np

from ...control.design import build_controllers
from ...control.guard import FadeGuard
from ...gp import PoseModalModel
from ...milling.forces import ACETAL, CuttingCoefficients, CuttingConditions, MillingTool
from ...sim import (
    POSITION_1_S_M,
    POSITION_2_S_M,
    PURE_DELAY,
    CommandChannel,
    CutDisturbances,
    LinearMove,
    VirtualRobot,
)
from ._loop import true_displacement

__all__ = ["TABLE_10_CONDITIONS", "milling_study", "plot_milling"]


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
        The path model with directions x and z (:func:`~robovib.sim.path_modal_model`).
    conditions
        (spindle rpm, feed per tooth [m], axial depth [m]) per cut.
    positions
        (name, path distance [m] of the cut's middle) pairs, or (name,
        :class:`~robovib.sim.LinearMove`) pairs: the cut itself (e.g. in the workspace).
    controllers
        Controller names from :data:`~robovib.control.design.CONTROLLERS` (open loop is always run).
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
                disp, err = true_displacement(robot, move, force, ctrl, rng, true_channel, **sensor)
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
