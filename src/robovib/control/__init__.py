"""Pose-dependent optimal vibration control (thesis ch. 4): LQR, gain scheduling, delay analysis."""

from .lqr import (
    THESIS_Q,
    THESIS_R,
    DelayAnalysis,
    DelayAwareDesign,
    LoopMargins,
    LQRDesign,
    closed_loop_with_delay,
    continuous_model,
    delay_analysis,
    design_delay_aware_lqr,
    design_lqr,
    discretize,
    loop_margins,
    tune_r_for_delay,
)

__all__ = [
    "THESIS_Q",
    "THESIS_R",
    "DelayAnalysis",
    "DelayAwareDesign",
    "LQRDesign",
    "LoopMargins",
    "closed_loop_with_delay",
    "continuous_model",
    "delay_analysis",
    "design_delay_aware_lqr",
    "design_lqr",
    "discretize",
    "loop_margins",
    "tune_r_for_delay",
]
