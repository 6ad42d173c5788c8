"""Pose-dependent optimal vibration control (thesis ch. 4).

* :mod:`~robovib.control.lqr`: LQR, delay analysis and delay-aware designs;
* :mod:`~robovib.control.schedule`: gain schedules over a path or a line through the workspace;
* :mod:`~robovib.control.controllers` and :mod:`~robovib.control.adaptive`: run-time
  controllers (state feedback, LQG, feedforward, repetitive, period tracking);
  :mod:`~robovib.control.guard`: the fade-out guard and its amplification test;
  :mod:`~robovib.control.loop_analysis`: their closed-loop matrices, learning-loop radii and
  the tuned design; :mod:`~robovib.control.scheduled`: gains scheduled along the path, looked
  up for a planned run or live;
* :mod:`~robovib.control.force_model`: feedforward of the measured force through the pose model;
* :mod:`~robovib.control.pose_plants`: the plants a design must hold on (GP band, second modes);
* :mod:`~robovib.control.band_stability`: stability of designed controllers over that band;
* :mod:`~robovib.control.channel`: what a command channel allows a state feedback (§4.3.2);
* :mod:`~robovib.control.design`: the registry of designs (:data:`~robovib.control.design.DESIGNS`)
  over one path design: the modes along the path computed once, names checked first
  (:func:`~robovib.control.design.build_controllers` for the closed-loop studies);
* :mod:`~robovib.control.path_design`: a path through any pose model (dominant or multi-mode);
* :mod:`~robovib.control.controller_file`: controller files
  (:func:`~robovib.control.controller_file.design_controller`,
  :func:`~robovib.control.controller_file.load_controller`) in the format of
  :mod:`~robovib.control.controller_format`; :mod:`~robovib.control.runtime`: the run-time
  controller an RSI bridge calls (``reset`` / ``step``);
  :func:`~robovib.control.cut_replay.replay` over a logged cut;
* :mod:`~robovib.control.protocol`: the ``Controller`` (planned run) and ``StepController``
  (run time) protocols.

Names are imported on first use (PEP 562): designing gains at one pose
(:mod:`~robovib.control.lqr`, NumPy only) does not pay for SciPy's signal module, which the
adaptive controllers need.
"""

from .._lazy import lazy_exports

_WHERE = {
    **dict.fromkeys(
        ["PeriodTracker", "TrackingFeedforward", "TrackingRepetitive", "estimate_period"],
        "adaptive"),
    **dict.fromkeys(["FadeGuard", "GuardEvent"], "guard"),
    "stability_over_band": "band_stability",
    **dict.fromkeys(
        ["THESIS_OFFSET_MASS_GAINS", "THESIS_OFFSET_MASS_MODE", "operating_mode",
         "required_channel_gain", "sensitivity_bound"], "channel"),
    **dict.fromkeys(
        ["Combined", "DelayAwareFeedback", "ForceFeedforward", "RepetitiveFeedback",
         "ScheduledTable", "StateFeedback", "design_kalman", "design_tuned_state_feedback",
         "implemented_loop_matrix", "lqg_loop_matrix"], "controllers"),
    **dict.fromkeys(
        ["CONTROLLERS", "DEFAULT_CONTROLLER", "DESIGNS", "THESIS_PRINTED_END_GAINS",
         "THESIS_PRINTED_START_GAINS", "assemble_controller", "build_controllers",
         "check_controller_names", "design_tables", "thesis_printed_gains"], "design"),
    **dict.fromkeys(["ControlPath", "PathDesign"], "path_design"),
    **dict.fromkeys(["Controller", "StepController"], "protocol"),
    **dict.fromkeys(["design_controller", "load_controller", "write_controller_file"],
                    "controller_file"),
    **dict.fromkeys(["ReplayResult", "replay"], "cut_replay"),
    **dict.fromkeys(["Measurement", "RuntimeController"], "runtime"),
    **dict.fromkeys(
        ["ForceModelFeedforward", "force_model_r", "force_model_variance_ratio",
         "unpredictable_fraction"], "force_model"),
    **dict.fromkeys(
        ["THESIS_Q", "THESIS_R", "DelayAnalysis", "DelayAwareDesign", "LoopMargins",
         "LQRDesign", "closed_loop_with_delay", "continuous_model", "delay_analysis",
         "design_delay_aware_lqr", "design_lqr", "discretize", "loop_margins",
         "spectral_radius", "tune_r_for_delay"], "lqr"),
    **dict.fromkeys(["SECOND_MODE_HYPOTHESES", "path_band", "path_mode", "plant_set"],
                    "pose_plants"),
    **dict.fromkeys(["GainSchedule", "ModelSchedule", "schedule_along_line", "schedule_gains"],
                    "schedule"),
}  # fmt: skip

__all__ = sorted(_WHERE)


__getattr__, __dir__ = lazy_exports(__name__, _WHERE)
