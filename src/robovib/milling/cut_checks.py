"""Checks that keep a vibration prediction from being silently meaningless (issue 38).

* :func:`cut_stability` — whether the cut itself is stable: the chatter limit at the cut's
  speed from the same pose model, tool and coefficients (the envelope of ``mill lobes``,
  :func:`robovib.milling.chart.lobes_chart`). A forced-vibration peak-to-valley describes a
  stable cut only; beyond the limit the cut chatters and that figure means nothing.
* :func:`implausible_cut_warnings` — inputs no milling cut has (an axial depth of 1 km, a feed
  per tooth larger than the tool) and a predicted deflection larger than the tool, where linear
  theory has long stopped applying.
* :func:`quantile_sample_warning` — a quantile asked of too few samples: the 2.5 % quantile of
  fewer than 40 draws is just their minimum.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .forces import CuttingCoefficients, CuttingConditions, MillingTool

__all__ = [
    "MAX_AXIAL_DEPTH_DIAMETERS",
    "MAX_FEED_PER_TOOTH_DIAMETERS",
    "MAX_SPINDLE_RPM",
    "CutStability",
    "cut_stability",
    "implausible_cut_warnings",
    "quantile_sample_warning",
]

#: Axial depth beyond this many tool diameters: no end mill has such flutes.
MAX_AXIAL_DEPTH_DIAMETERS = 5.0
#: Feed per tooth beyond this fraction of the tool diameter (0.05 D = 1.3 mm at 25.4 mm).
MAX_FEED_PER_TOOTH_DIAMETERS = 0.05
#: Spindle speed beyond which no machining spindle turns [rpm].
MAX_SPINDLE_RPM = 100_000.0


@dataclass(frozen=True)
class CutStability:
    """Whether one cut is below the chatter limit at its speed.

    Attributes
    ----------
    spindle_rpm : float
        Speed of the cut [rpm].
    axial_depth_m : float
        Depth of the cut [m].
    critical_depth_m : float
        Lowest unstable depth at that speed [m] (inf: no limit found).
    method : str
        ``"sdm"`` or ``"zoa"``.
    notes : tuple of str
        How the modes were chosen (the lobes chart's notes).
    """

    spindle_rpm: float
    axial_depth_m: float
    critical_depth_m: float
    method: str
    notes: tuple[str, ...] = ()

    @property
    def stable(self) -> bool:
        """The cut's depth lies below the limit."""
        return bool(self.axial_depth_m < self.critical_depth_m)

    def to_dict(self) -> dict:
        """JSON-ready (SI, units in the keys).

        Returns
        -------
        dict
            Method, depths, the verdict and the depth / limit ratio.
        """
        crit = self.critical_depth_m
        return {
            "method": self.method,
            "spindle_rpm": self.spindle_rpm,
            "axial_depth_m": self.axial_depth_m,
            "critical_depth_m": crit if math.isfinite(crit) else None,
            "stable": self.stable,
            "chatter_predicted": not self.stable,
            "depth_to_limit_ratio": self.axial_depth_m / crit if math.isfinite(crit) else 0.0,
            "notes": list(self.notes),
        }


def cut_stability(
    model,
    pose,
    conditions: CuttingConditions,
    coefficients: CuttingCoefficients,
    *,
    tool: MillingTool | None = None,
    feed_direction: str = "x",
    method: str = "sdm",
    steps_per_period: int = 40,
) -> CutStability:
    """The chatter limit at the cut's speed and whether its axial depth is below it.

    The limit is that of ``mill lobes`` at one speed (:func:`robovib.milling.chart.lobes_chart`
    with the pose model's modes at ``pose``, the cut's radial depth and milling mode).

    Parameters
    ----------
    model : PoseModalModel or PosePredictor
        Pose model with inputs ``(x_mm, y_mm, rz_deg)``.
    pose : (float, float, float)
        ``(x_mm, y_mm, rz_deg)``.
    conditions : CuttingConditions
        The cut: speed [rpm], feed per tooth [m], axial and radial depth [m], milling mode.
    coefficients : CuttingCoefficients
        Cutting coefficients [N/m²].
    tool : MillingTool, optional
        The cutter (default: ``MillingTool()``, as :func:`~robovib.milling.at_pose.predict_at_pose`).
    feed_direction : {"x", "y"}
        Feed direction in the base frame.
    method : {"sdm", "zoa"}
        Stability method.
    steps_per_period : int
        Semi-discretization steps per tooth period.

    Returns
    -------
    CutStability
        The limit and the verdict.

    Raises
    ------
    ValueError
        As :func:`~robovib.milling.chart.lobes_chart` (a pose model without x/y modes, ...).

    Examples
    --------
    >>> from robovib.gp.chapter3_model import load_chapter3_predictor
    >>> from robovib.milling import ALUMINIUM_7075, CuttingConditions
    >>> from robovib.milling.cut_checks import cut_stability
    >>> deep = CuttingConditions(1750.0, 58e-6, 50e-3, 6e-3)
    >>> cut_stability(load_chapter3_predictor(), (2400.0, 0.0, 45.0), deep, ALUMINIUM_7075).stable
    False
    """
    from .chart import lobes_chart

    rpm = float(conditions.spindle_rpm)
    chart = lobes_chart(
        tool=tool or MillingTool(), conditions=conditions, coefficients=coefficients,
        spindle_rpm=np.array([rpm]), method=method, pose_model=model,
        pose=tuple(float(v) for v in pose), feed_direction=feed_direction,
        steps_per_period=steps_per_period,
    )  # fmt: skip
    crit = float(chart.envelope.critical_depth(rpm)[0])
    return CutStability(rpm, float(conditions.axial_depth_m), crit, method, tuple(chart.notes))


def implausible_cut_warnings(
    tool: MillingTool, conditions: CuttingConditions, *, deflection_m: float | None = None
) -> list[str]:
    """Warnings for cutting inputs (or a predicted deflection) no real cut has.

    Parameters
    ----------
    tool : MillingTool
        The cutter.
    conditions : CuttingConditions
        The cut.
    deflection_m : float, optional
        The largest predicted deflection or peak-to-valley [m].

    Returns
    -------
    list of str
        One line per implausible value (empty: all plausible).

    Examples
    --------
    >>> from robovib.milling import CuttingConditions, MillingTool
    >>> from robovib.milling.cut_checks import implausible_cut_warnings
    >>> implausible_cut_warnings(MillingTool(), CuttingConditions(1750.0, 58e-6, 1e3, 25.4e-3))
    ['axial depth 1e+06 mm is 39370 tool diameters (25.4 mm): no end mill cuts that deep; check --ap (mm)']
    """
    out = []
    d = tool.diameter_m
    ap, fz = conditions.axial_depth_m, conditions.feed_per_tooth_m
    if ap > MAX_AXIAL_DEPTH_DIAMETERS * d:
        out.append(
            f"axial depth {ap * 1e3:.4g} mm is {ap / d:.0f} tool diameters ({d * 1e3:g} mm): "
            "no end mill cuts that deep; check --ap (mm)"
        )
    if fz > MAX_FEED_PER_TOOTH_DIAMETERS * d:
        out.append(
            f"feed per tooth {fz * 1e3:.4g} mm is {fz / d:.2g} tool diameters: far beyond any "
            "chip load; check --fz (mm)"
        )
    if conditions.spindle_rpm > MAX_SPINDLE_RPM:
        out.append(
            f"spindle speed {conditions.spindle_rpm:.4g} rpm is beyond any machining spindle "
            f"({MAX_SPINDLE_RPM:.0f} rpm)"
        )
    if deflection_m is not None and math.isfinite(deflection_m) and abs(deflection_m) > d:
        out.append(
            f"predicted deflection {abs(deflection_m) * 1e3:.4g} mm exceeds the tool diameter: "
            "far outside the small-vibration (linear) theory the prediction rests on"
        )
    return out


def quantile_sample_warning(n_samples: int, lower_tail: float, what: str = "samples") -> str | None:
    """A warning when ``n_samples`` draws cannot resolve a ``lower_tail`` quantile.

    Fewer than ``1 / lower_tail`` draws (40 for a 2.5-97.5 % band, 20 for 5-95 %) leave no draw
    beyond the quantile: the "band" is the range of the draws.

    Parameters
    ----------
    n_samples : int
        Draws (0: none asked, no warning).
    lower_tail : float
        Lower tail probability of the band (0.025 for 95 %).
    what : str
        Name of the option, for the message.

    Returns
    -------
    str or None
        The warning, or None.

    Examples
    --------
    >>> from robovib.milling.cut_checks import quantile_sample_warning
    >>> quantile_sample_warning(2, 0.025, "--samples")
    '--samples 2: too few draws for a 2.5-97.5 % band (it is their range); use at least 40'
    >>> quantile_sample_warning(50, 0.025) is None
    True
    """
    need = math.ceil(1.0 / lower_tail - 1e-9)
    if 0 < int(n_samples) < need:
        lo, hi = 100 * lower_tail, 100 * (1 - lower_tail)
        return (
            f"{what} {int(n_samples)}: too few draws for a {lo:g}-{hi:g} % band (it is their "
            f"range); use at least {need}"
        )
    return None
