"""Closed-loop studies on the virtual robot (thesis §4.2-4.4, Tables 7 and 10), one module each.

The studies compose library code: the path model from the virtual EMA
(:func:`robovib.sim.path_modal_model`), the controllers designed from it alone
(:func:`robovib.control.design.build_controllers`), the command-channel models
(:mod:`robovib.control.channel`, :class:`robovib.sim.CommandChannel`) and the closed-loop
simulator (:func:`robovib.sim.run_closed_loop`); import those from the library.

* :mod:`.offset_mass` — :func:`fixed_pose_offset_mass` (§4.3.2): the thesis' own gains
  0.079 / 0.0059 on the mode it measured (8.5 Hz, 0.775 MN/m, 0.179) at 480 / 960 / 1440 rpm,
  open vs closed loop, through a given command channel; :func:`calibrate_channel` searches the
  channel options against §4.3.2 (:func:`~robovib.control.channel.sensitivity_bound` is the
  best any non-amplifying channel allows); :func:`offset_mass_study` (Table 7 analogue): 1 kg
  at 50.8 mm while the robot moves 900 mm toward the base at 84 mm/s;
* :mod:`.milling` — :func:`milling_study` (Table 10 analogue): the eight cuts at Positions 1
  and 2, X and Z;
* :mod:`.simulate` — :func:`simulate_control`: one entry point (the CLI's ``control
  simulate``), and :func:`file_milling_positions` for a controller file.

Measurement realism comes from :func:`robovib.sim.run_closed_loop`: tracker at 1 kHz with
noise and 0.01 mm resolution, force sensor with 0.5 N noise, commands at 250 Hz through a
:class:`~robovib.sim.CommandChannel` (default: 32 ms pure delay).
"""

from .milling import TABLE_10_CONDITIONS, milling_study, plot_milling
from .offset_mass import (
    calibrate_channel,
    fixed_pose_offset_mass,
    offset_mass_study,
    plot_offset_mass,
)
from .simulate import ControlSimulation, file_milling_positions, simulate_control

__all__ = [
    "TABLE_10_CONDITIONS",
    "ControlSimulation",
    "calibrate_channel",
    "file_milling_positions",
    "fixed_pose_offset_mass",
    "milling_study",
    "offset_mass_study",
    "plot_milling",
    "plot_offset_mass",
    "simulate_control",
]
