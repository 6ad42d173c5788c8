"""Prediction of the chapter-3 pose model at one pose, with extrapolation and mode-ambiguity notes."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..datasets import X_HIGH_MODE_THRESHOLD_HZ
from .extrapolation import outside_inputs

__all__ = ["PosePrediction", "predict_pose"]


@dataclass(frozen=True)
class PosePrediction:
    """Predicted dominant-mode parameters (thesis units) at one pose with their context."""

    pose_mm_deg: tuple[float, float, float]  #: (X [mm], Y [mm], Rz [deg])
    records: tuple[dict, ...]  #: per output: output, mean, std, lower_2sigma, upper_2sigma
    extrapolation: tuple[str, ...]  #: inputs outside the training range ("x", "y", "rz")
    x_high_mode_probability: float | None  #: P(~63 Hz X mode dominant); None without classifier
    note: str | None  #: ambiguity of the dominant X mode, if any


def predict_pose(model, x_mm: float, y_mm: float, rz_deg: float, labels) -> PosePrediction:
    """Predict a fitted chapter-3 model (``fit_chapter3_model``) at one pose with ±2σ.

    Parameters
    ----------
    model
        BatchedGPRegressor or ModeSwitchingGPRegressor over (X [mm], Y [mm], Rz [deg]), first
        output the X natural frequency [Hz].
    x_mm, y_mm, rz_deg
        Pose (Z = 325 mm, Rx = Ry = 0).
    labels
        Output labels, one per model output.

    Returns
    -------
    PosePrediction
        ``extrapolation`` names the inputs outside the training range; ``note`` says when the
        dominant X mode (16-23 Hz vs ~63 Hz) is uncertain: classifier probability in (0.2, 0.8)
        or, without classifier, the ±2σ band of X fn straddling 40 Hz.

    Raises
    ------
    ValueError
        Non-finite pose.
    """
    pose = np.array([[x_mm, y_mm, rz_deg]], dtype=float)
    if not np.all(np.isfinite(pose)):
        raise ValueError("pose coordinates must be finite numbers")
    switching = hasattr(model, "low_model_")
    outside = outside_inputs(model, pose[0], ("x", "y", "rz"))  # one range rule for all models
    mean, std = model.predict(pose, return_std=True)
    mean, std = mean[0], std[0]
    records = tuple(
        {
            "output": label,
            "mean": float(m),
            "std": float(s),
            "lower_2sigma": float(m - 2 * s),
            "upper_2sigma": float(m + 2 * s),
        }
        for label, m, s in zip(labels, mean, std, strict=True)
    )
    note = None
    p_high = float(model.high_mode_probability(pose)[0]) if switching else None
    if p_high is not None and 0.2 < p_high < 0.8:
        note = (
            f"P(~63 Hz X mode dominant) = {p_high:.2f}: the data cannot tell which X mode dominates "
            "here; the X values are those of the more probable mode"
        )
    elif p_high is None and mean[0] - 2 * std[0] < X_HIGH_MODE_THRESHOLD_HZ < mean[0] + 2 * std[0]:
        note = "the X band straddles the 16-23 Hz / ~63 Hz mode switch: the dominant X mode is uncertain here"
    return PosePrediction((x_mm, y_mm, rz_deg), records, outside, p_high, note)
