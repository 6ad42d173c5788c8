"""Replay of a logged cut through a run-time controller (issue 40).

:func:`replay` runs a :class:`~robovib.control.runtime.RuntimeController` over a logged cut,
as the bridge would have run it, and predicts the vibration without and with its corrections
(:class:`ReplayResult`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..modal.parameters import ModalParameters
from .runtime import RuntimeController

__all__ = ["ReplayResult", "replay"]


@dataclass(frozen=True)
class ReplayResult:
    """What a controller would have done over a logged cut (:func:`replay`).

    Attributes
    ----------
    time_s
        (n_cmd,) time of each command [s].
    path_s_m
        (n_cmd,) path coordinate at each command [m].
    commands_mm
        (n_cmd, 3) corrections it would have sent [mm].
    guard_scale
        (n_cmd,) the guard's fade factor after each step.
    events
        The guard's and learners' events (time [s], target, reason).
    rms_mm
        Direction -> ``{"measured", "predicted_open", "predicted_corrected"}`` RMS [mm] of
        the tracker and of the model's response to the measured force without and with the
        corrections (after the first fifth of the cut).
    tracker_fed_m
        (n, 3) the tracker signal the controller was given [m]: the record's, plus the model's
        response to the corrections where the record was made without the controller.
    """

    time_s: np.ndarray
    path_s_m: np.ndarray
    commands_mm: np.ndarray
    guard_scale: np.ndarray
    events: tuple
    rms_mm: dict
    tracker_fed_m: np.ndarray | None = None


def replay(runtime: RuntimeController, record: dict, *, spindle_rpm: float | None = None,
           teeth: int | None = None, record_made: str = "with") -> ReplayResult:  # fmt: skip
    """Run the controller over a logged cut, as the bridge would have run it.

    Commands fall at samples ``0, every, 2 every, ...`` (``every`` = samples per cycle); each
    step gets the samples since the previous one (the first: sample 0 alone), as in
    :func:`robovib.sim.run_closed_loop`. The predicted vibration runs the file's mode of each
    direction (at the record's middle path coordinate) on the measured force (high-passed at
    the force model's 1 Hz) and on the corrections, ``delay_s`` late.

    A cut logged *without* this controller (``record_made="without"``, the usual case before
    deployment) holds none of its corrections: fed as it is, the guard would see a tracker
    signal its corrections never reduced and fade the controller out, and the learners would
    chase a residual that never moves. There the tracker signal the controller is given is the
    logged one plus the model's response to the corrections already sent (``delay_s`` late,
    held for a cycle), computed sample by sample: a model-in-the-loop replay. A cut logged
    *with* the controller running (``"with"``, e.g. a closed-loop simulation's record) already
    holds their effect and is fed unchanged, so the replay reproduces its commands.

    Parameters
    ----------
    runtime : RuntimeController
        The controller (reset here).
    record : dict
        :func:`robovib.io.read_milling_record_csv`: ``time_s``, ``force_n``,
        ``displacement_m`` and ``path_s_m`` or ``pose``.
    spindle_rpm, teeth
        The cut's spindle speed [rev/min] and teeth (default the file's).
    record_made : {"with", "without"}
        Whether the record was logged with this controller running (see above).

    Returns
    -------
    ReplayResult

    Raises
    ------
    ValueError
        A record whose sample rate is not the file's, too short, or poses off the model.
    """
    if record_made not in ("with", "without"):
        raise ValueError(f"record_made must be 'with' or 'without', got {record_made!r}")
    t = np.asarray(record["time_s"], float)
    force = np.asarray(record["force_n"], float)
    tracker = np.asarray(record["displacement_m"], float)
    if t.size < 2:
        raise ValueError("the record needs at least 2 samples")
    fs = 1.0 / float(np.median(np.diff(t)))
    if abs(fs / runtime.sample_rate_hz - 1) > 1e-6:
        raise ValueError(f"the record is sampled at {fs:.6g} Hz, the controller file assumes "
                         f"{runtime.sample_rate_hz:g} Hz")  # fmt: skip
    coords = record["path_s_m"] if "path_s_m" in record else record["pose"]
    every = runtime.every
    idx = np.arange(0, t.size, every)
    s = runtime.path_coordinate(np.asarray(coords)[idx])
    runtime.reset(spindle_rpm=spindle_rpm, teeth=teeth,
                  max_duration_s=(idx.size + 2) * runtime.period_s,
                  nominal_s_m=float(s[idx.size // 2]))  # fmt: skip
    cmds = np.zeros((idx.size, 3))
    scale = np.zeros(idx.size)
    fed = tracker if record_made == "with" else tracker.copy()
    loop = None if record_made == "with" else _CorrectionResponse(runtime, float(np.median(s)), fs)
    for k, i in enumerate(idx):
        lo = max(0, i - every + 1)
        if loop is not None:  # the corrections sent so far reach these samples through the model
            loop.add(fed, cmds, lo, i + 1)
        cmds[k] = runtime.step_arrays(force[lo : i + 1], fed[lo : i + 1] * 1e3, float(s[k]))
        scale[k] = runtime.guard_scale
    rms = _predicted_rms(runtime, force, tracker, cmds, float(np.median(s)), fs)
    return ReplayResult(t[idx], s, cmds, scale, tuple(runtime.events()), rms, fed)


class _CorrectionResponse:
    """Causal response of the file's mode per axis (at path coordinate ``s_mid``) to the
    corrections already sent, ``delay_s`` late and held for a cycle, added to the tracker."""

    def __init__(self, runtime, s_mid: float, fs: float) -> None:
        from .lqr import continuous_model, discretize

        self.every, self.delay = runtime.every, round(runtime.delay_s * fs)
        self.axes = {}
        for a in runtime.tables.axes:
            fz = runtime.tables.fz(a).at(np.array([s_mid]))[0]
            k = runtime.tables.stiffness(a).at(np.array([s_mid]))[0, 0]
            phi, gam = discretize(*continuous_model(ModalParameters(fz[0], k, fz[1])), 1.0 / fs)
            self.axes[a] = (phi, gam[:, 0], np.zeros(2))

    def add(self, tracker_m: np.ndarray, cmds_mm: np.ndarray, lo: int, hi: int) -> None:
        for j in range(lo, hi):
            m = (j - self.delay) // self.every  # the command applied at sample j (< this step)
            for a, (phi, g, x) in self.axes.items():
                tracker_m[j, a] += x[0]
                u = cmds_mm[m, a] * 1e-3 if m >= 0 else 0.0
                x[:] = phi @ x + g * u


def _predicted_rms(runtime, force, tracker, cmds_mm, s_mid, fs) -> dict:
    from .lqr import continuous_model, discretize

    n = force.shape[0]
    every, delay = runtime.every, round(runtime.delay_s * fs)
    applied = np.zeros((n, 3))
    held = np.repeat(cmds_mm * 1e-3, every, axis=0)[:n]
    applied[delay:] = held[: max(0, n - delay)]
    alpha = math.exp(-2 * math.pi * 1.0 / fs)
    f_hp = np.zeros_like(force)
    for i in range(1, n):
        f_hp[i] = alpha * (f_hp[i - 1] + force[i] - force[i - 1])
    out = {}
    start = n // 5
    for a, d in runtime.tables.axes.items():
        fz = runtime.tables.fz(a).at(np.array([s_mid]))[0]
        k = runtime.tables.stiffness(a).at(np.array([s_mid]))[0, 0]
        phi, gam = discretize(*continuous_model(ModalParameters(fz[0], k, fz[1])), 1.0 / fs)
        x = np.zeros(2)
        xo = np.zeros(2)
        y_c = np.zeros(n)
        y_o = np.zeros(n)
        g = gam[:, 0]
        for i in range(n):
            y_c[i], y_o[i] = x[0], xo[0]
            x = phi @ x + g * (f_hp[i, a] / k + applied[i, a])
            xo = phi @ xo + g * (f_hp[i, a] / k)
        out[d] = {"measured": 1e3 * float(np.std(tracker[start:, a])),
                  "predicted_open": 1e3 * float(np.std(y_o[start:])),
                  "predicted_corrected": 1e3 * float(np.std(y_c[start:]))}  # fmt: skip
    return out
