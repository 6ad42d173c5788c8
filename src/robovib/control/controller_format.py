"""The controller document's format (issue 40): its tag and version, the settings it carries.

What both the writer (:mod:`~robovib.control.controller_file`) and the run-time controller
(:mod:`~robovib.control.runtime`) need: the format tag and version, the period-tracker, guard
and learner settings with their checks, the timing check, and the design tables read back
from a document.
"""

from __future__ import annotations

import math

import numpy as np

from ..modal.parameters import ModalParameters
from .design import PathTables
from .schedule import GainSchedule

__all__ = ["FORMAT", "FORMAT_VERSION", "LEARNER_DEFAULTS", "LEARNER_DESIGN"]

FORMAT = "robovib.controller"
#: 2: the learners identify their loop phase (``learner.identify_loop`` and friends) and pause
#: while the guard fades their correction out (``learner.pause_when_faded``); a
#: version-1 file loads with them off and runs as it did. 3: the learners pool the loop phases
#: of a direction's harmonics (``learner.pool_loop_phase``) and the period tracker estimates
#: over several periods (``tracker.lag_periods``); ``adaptive+force`` files carry a feedback
#: for the axes without a force model (``gains.feedback``); a version-1 or 2 file loads with
#: them off (1, none) and runs as it did.
FORMAT_VERSION = 3


def _settings(what: str, defaults: dict, given: dict | None) -> dict:
    unknown = set(given or {}) - set(defaults)
    if unknown:
        raise ValueError(f"unknown {what} settings {sorted(unknown)}; expected some of "
                         f"{sorted(defaults)}")  # fmt: skip
    return {**defaults, **{k: float(v) for k, v in (given or {}).items()}}


#: The repetitive learners' settings of a controller file (see ``TrackingRepetitive``).
LEARNER_DEFAULTS = {"divergence_ratio": 1.2, "divergence_test": "correction",
                    "n_harmonics": "auto", "model_at_tracked_period": True,
                    "delay_uncertainty_s": 0.008, "fn_uncertainty_rel": 0.0,
                    "gain_uncertainty_rel": 0.1, "identify_loop": False,
                    "identify_rel_error": 0.2, "learning_time_s": 0.4,
                    "pause_when_faded": False, "pool_loop_phase": False}  # fmt: skip
#: Learner settings a newly designed file carries over the defaults (a file written before
#: they existed loads with the defaults above, i.e. as it ran then).
LEARNER_DESIGN = {"identify_loop": True, "learning_time_s": 0.8, "pause_when_faded": True,
                  "pool_loop_phase": True}  # fmt: skip


def _learner(given: dict | None) -> dict:
    unknown = set(given or {}) - set(LEARNER_DEFAULTS)
    if unknown:
        raise ValueError(f"unknown learner settings {sorted(unknown)}; expected some of "
                         f"{sorted(LEARNER_DEFAULTS)}")  # fmt: skip
    out = {**LEARNER_DEFAULTS, **(given or {})}
    out["divergence_ratio"] = float(out["divergence_ratio"])
    for key in ("model_at_tracked_period", "identify_loop", "pause_when_faded",
                "pool_loop_phase"):  # fmt: skip
        # bool("false") is True: a setting written as a string would silently turn on
        if not isinstance(out[key], bool | np.bool_):
            raise ValueError(f"learner.{key} must be true or false, got {out[key]!r}")
        out[key] = bool(out[key])
    for key in (
        "delay_uncertainty_s",
        "fn_uncertainty_rel",
        "gain_uncertainty_rel",
        "identify_rel_error",
        "learning_time_s",
    ):
        out[key] = float(out[key])
    if out["n_harmonics"] != "auto":
        out["n_harmonics"] = int(out["n_harmonics"])
    return out


def _check_timing(period_s: float, delay_s: float, sample_rate_hz: float) -> None:
    if not (math.isfinite(period_s) and period_s > 0 and math.isfinite(sample_rate_hz)
            and sample_rate_hz > 0 and math.isfinite(delay_s) and delay_s >= 0):  # fmt: skip
        raise ValueError("period_s > 0 [s], delay_s >= 0 [s] and sample_rate_hz > 0 [Hz]")
    every = period_s * sample_rate_hz
    if abs(every - round(every)) > 1e-9 or round(every) < 1:
        raise ValueError(f"the command period {period_s * 1e3:g} ms must be a whole number of "
                         f"samples at {sample_rate_hz:g} Hz")  # fmt: skip
    d = delay_s / period_s
    if abs(d - round(d)) > 1e-9:
        raise ValueError(f"the delay {delay_s * 1e3:g} ms must be a whole number of command "
                         f"periods ({period_s * 1e3:g} ms)")  # fmt: skip


def _tables(doc: dict) -> PathTables:
    try:
        grid = np.asarray(doc["grid_s_m"], float)
        axes = {int(a): d for d, a in doc["axes"].items()}
        t = doc["timing"]
        modes = {a: [ModalParameters(fn, k, z) for fn, k, z in zip(
            doc["modes"][d]["fn_hz"], doc["modes"][d]["stiffness_n_per_m"],
            doc["modes"][d]["damping_ratio"], strict=True)] for a, d in axes.items()}  # fmt: skip
        tab = PathTables(grid, axes, modes, float(t["command_period_s"]), float(t["delay_s"]))
        g = doc.get("gains", {})
        by_dir = {d: a for a, d in axes.items()}
        if "schedule" in g:
            tab.schedule = {by_dir[d]: GainSchedule(
                grid, np.asarray(v["w1"], float), np.asarray(v["w2"], float),
                np.asarray(v["r"], float), np.asarray(v["stable_with_delay"], bool),
                np.asarray(v["w1_poly_high_to_low"], float),
                np.asarray(v["w2_poly_high_to_low"], float)) for d, v in g["schedule"].items()}  # fmt: skip
            tab.constant = {n: {by_dir[d]: tuple(float(x) for x in w) for d, w in c.items()}
                            for n, c in g["constant"].items()}  # fmt: skip
        for key in ("robust", "lqg"):
            if key in g:
                setattr(tab, key, {by_dir[d]: np.asarray(v, float) for d, v in g[key].items()})
        if "feedback" in g:
            tab.feedback = {by_dir[d]: np.asarray(v, float) for d, v in g["feedback"].items()}
        if "force_model_r" in g:
            tab.force_model_r = {by_dir[d]: float(r) for d, r in g["force_model_r"].items()}
    except (KeyError, TypeError, ValueError) as exc:
        raise ValueError(f"controller file: missing or malformed design table ({exc})") from exc
    if grid.ndim != 1 or grid.size < 2 or not np.all(np.isfinite(grid)):
        raise ValueError("controller file: grid_s_m must be >= 2 finite path distances [m]")
    width = 2 + round(tab.delay_s / tab.period_s)  # [K_x, K_v, K_u1..K_ud]
    for a, v in tab.feedback.items():
        if v.shape != (grid.size, width):
            raise ValueError(f"controller file: gains.feedback.{axes[a]} must be {grid.size} "
                             f"rows (grid_s_m) x {width} gains (2 + delay / command period), "
                             f"got shape {v.shape}")  # fmt: skip
        if not np.all(np.isfinite(v)):
            raise ValueError(f"controller file: gains.feedback.{axes[a]} has non-finite gains")
        if a in tab.force_model_r:
            raise ValueError(f"controller file: direction {axes[a]!r} has both a force model "
                             "(gains.force_model_r) and gains.feedback; a design gives an "
                             "axis one or the other")  # fmt: skip
    return tab
