"""Robustness of the milling controllers to a real cut (issue 25): the robustness table.

Every controller x every disturbance of :class:`~robovib.sim.disturbances.CutDisturbances`
at its realistic level (:data:`~robovib.sim.disturbances.REALISTIC_LEVELS`) and at 2x, plus all
of them combined at the realistic levels, on the Table 10 cuts at both positions
(:func:`~robovib.studies.control.milling_study`). :func:`summarize_robustness`
reduces the per-cut rows to mean and worst RMS reduction, unstable runs and amplified cuts.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ..sim import REALISTIC_LEVELS, CutDisturbances, VirtualRobot, path_modal_model
from ..sim.disturbances import DISTURBANCE_UNITS
from .control import TABLE_10_CONDITIONS, milling_study

__all__ = [
    "ROBUSTNESS_CONTROLLERS",
    "robustness_scenarios",
    "robustness_study",
    "summarize_robustness",
]

#: Controllers of the robustness table: the ideal-cut best two and the adaptive ones.
ROBUSTNESS_CONTROLLERS = (
    "feedforward+robust",
    "repetitive",
    "adaptive",
    "adaptive-feedforward",
    "adaptive+force",
)


def robustness_scenarios(
    names=tuple(DISTURBANCE_UNITS), levels=(1.0, 2.0), combined: bool = True
) -> list[tuple[str, CutDisturbances]]:
    """(label, disturbances): none, each of ``names`` at each level x realistic, all combined.

    Parameters
    ----------
    names
        Disturbances (field names of :class:`~robovib.sim.disturbances.CutDisturbances`, keys
        of :data:`~robovib.sim.disturbances.DISTURBANCE_UNITS`) run one at a time.
    levels
        Multiples of each disturbance's realistic level
        (:data:`~robovib.sim.disturbances.REALISTIC_LEVELS`).
    combined
        Also add every disturbance at once at its realistic level.

    Returns
    -------
    list of (str, CutDisturbances)
        ``("none", CutDisturbances())`` first, then one pair per name and level (label
        ``"NAME=VALUE (Fx)"``), then ``("all realistic (1x)", REALISTIC_LEVELS)`` if
        ``combined``.

    Raises
    ------
    ValueError
        An unknown disturbance name.
    """
    out = [("none", CutDisturbances())]
    for name in names:
        if name not in DISTURBANCE_UNITS:
            raise ValueError(
                f"unknown disturbance {name!r}; expected some of {sorted(DISTURBANCE_UNITS)}"
            )
        for f in levels:
            v = getattr(REALISTIC_LEVELS, name) * f
            out.append((f"{name}={v:g} ({f:g}x)", CutDisturbances(**{name: v})))
    if combined:
        out.append(("all realistic (1x)", REALISTIC_LEVELS))
    return out


def robustness_study(
    controllers=ROBUSTNESS_CONTROLLERS,
    scenarios=None,
    conditions=TABLE_10_CONDITIONS,
    *,
    robot: VirtualRobot | None = None,
    model=None,
    progress: Callable[[str], None] | None = None,
    rng=0,
) -> list[dict]:
    """Per-cut rows of :func:`milling_study` under every scenario (column ``scenario``).

    ``scenarios``: (label, :class:`CutDisturbances`) pairs (default
    :func:`robustness_scenarios`). The pose model is the virtual EMA along the path
    (:func:`path_modal_model`), the same for every scenario; the controllers never see the
    disturbances. ``progress`` is called with each scenario's label before it runs.

    Parameters
    ----------
    controllers
        Names of the controllers (as in :func:`milling_study`); the open loop always runs.
    scenarios
        (label, :class:`CutDisturbances`) pairs; ``None``: :func:`robustness_scenarios`.
    conditions
        Cuts as (spindle speed [rpm], feed per tooth [m], axial depth [m]) triples.
    robot
        The simulated robot; ``None``: a default :class:`~robovib.sim.VirtualRobot`.
    model
        Pose model along the path; ``None``: :func:`path_modal_model` of ``robot`` in X and Z.
    progress
        Called with each scenario's label before it runs; ``None``: silent.
    rng
        Seed (or generator) of the pose model's virtual tests and of every scenario's cuts.

    Returns
    -------
    list of dict
        The rows of :func:`milling_study` (RMS vibration [mm] and reductions [%] per cut,
        position and controller), each with a ``scenario`` label first.
    """
    robot = robot or VirtualRobot()
    model = model or path_modal_model(robot, directions=("x", "z"), rng=rng)
    rows = []
    for label, dist in scenarios or robustness_scenarios():
        if progress is not None:
            progress(label)
        for r in milling_study(robot, model, conditions, controllers=tuple(controllers),
                               disturbances=dist, rng=rng):  # fmt: skip
            rows.append({"scenario": label, **r})
    return rows


def summarize_robustness(rows: list[dict], amplified_pct: float = 5.0) -> list[dict]:
    """Per scenario and controller: mean / worst RMS reduction [%] in X and Z, unstable runs,
    cuts amplified by more than ``amplified_pct`` % (in X or Z) and guard events.

    Parameters
    ----------
    rows
        Per-cut rows of :func:`robustness_study`.
    amplified_pct
        A cut counts as amplified when its RMS reduction in X or Z is below
        ``-amplified_pct`` [%].

    Returns
    -------
    list of dict
        One row per (scenario, controller) in order of first appearance: ``scenario``,
        ``controller``, ``cuts``, ``x_mean_pct``, ``x_worst_pct``, ``z_mean_pct``,
        ``z_worst_pct`` (RMS reductions [%], NaN when none is finite), ``unstable``,
        ``amplified`` and ``guard_events`` (counts of cuts).
    """
    keys = list(dict.fromkeys((r["scenario"], r["controller"]) for r in rows))
    out = []
    for sc, c in keys:
        sel = [r for r in rows if r["scenario"] == sc and r["controller"] == c]
        row = {"scenario": sc, "controller": c, "cuts": len(sel)}
        for d in ("x", "z"):
            v = np.array([r[f"{d}_reduction_pct"] for r in sel], float)
            row[f"{d}_mean_pct"] = float(np.nanmean(v)) if np.any(np.isfinite(v)) else np.nan
            row[f"{d}_worst_pct"] = float(np.nanmin(v)) if np.any(np.isfinite(v)) else np.nan
        row["unstable"] = sum(r["unstable"] is not None for r in sel)
        row["amplified"] = sum(
            (r["x_reduction_pct"] < -amplified_pct) or (r["z_reduction_pct"] < -amplified_pct)
            for r in sel
        )
        row["guard_events"] = sum(bool(r.get("guard_events")) for r in sel)
        out.append(row)
    return out
