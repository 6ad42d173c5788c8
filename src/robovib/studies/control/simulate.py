"""One entry point to the closed-loop studies (the CLI's ``control simulate``), and where a
controller file's cuts run on the virtual robot."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...control.design import CONTROLLERS
from ...sim import (
    ACTUATORS,
    PATH_LENGTH_M,
    POSITION_1_S_M,
    POSITION_2_S_M,
    CutDisturbances,
    LinearMove,
    VirtualRobot,
    path_modal_model,
)
from .milling import milling_study, plot_milling
from .offset_mass import offset_mass_study, plot_offset_mass

__all__ = ["ControlSimulation", "file_milling_positions", "simulate_control"]


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
        Names from :data:`~robovib.control.design.CONTROLLERS` (default: all).
    actuator
        ``"pure-delay"`` (32 ms), the only channel (the §4.3.2 calibration is withdrawn: no
        channel of gain <= 1 reproduces it, :func:`~robovib.control.channel.sensitivity_bound`).
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
    from ...control.controller_file import load_controller
    from ...control.runtime import RuntimeController

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
