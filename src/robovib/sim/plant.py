"""Closed-loop runs on the virtual robot: the actuator (path-correction) input channel.

The robot controller accepts position corrections ``u`` (per direction, metres) at the command
rate (KUKA RSI: 250 Hz) and applies them after a transport delay (the thesis measured 32 ms,
§4.3.2). A correction enters like a force ``k_s u`` with the direction's static stiffness
``k_s = 1 / sum(1 / k_r)``, so a held correction ``u`` moves the tool tip by ``u`` once
transients decay.

A controller is any callable ``controller(t, displacement_m, velocity_m_per_s, coords) -> u``
called at the command rate with the *measured* tracker displacement (1 kHz samples with noise
and 0.01 mm resolution) and the backward-difference velocity over one command period (a 1 ms
difference of 0.01 mm-quantised samples would carry ±10 mm/s of noise), returning a (3,)
correction.
The loop is stepped sample by sample (a Python loop over the sensor samples, vectorised over
all modes), with per-sample exact transitions as in :mod:`robovib.sim.dynamics`.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from .dynamics import zoh_transition
from .experiments import _TRUTH_STEP_S, LinearMove, MotionRecord, _rng
from .truth import DIRECTIONS, VirtualRobot

__all__ = ["Controller", "run_closed_loop"]

Controller = Callable[[float, np.ndarray, np.ndarray, np.ndarray], np.ndarray]


def run_closed_loop(
    robot: VirtualRobot,
    move: LinearMove,
    force_n: np.ndarray,
    sample_rate_hz: float,
    controller: Controller | None,
    *,
    delay_s: float = 0.032,
    command_rate_hz: float = 250.0,
    tracker_noise_m: float = 2e-6,
    tracker_resolution_m: float = 1e-5,
    max_command_m: float = 0.01,
    allow_extrapolation: bool = False,
    rng=None,
) -> MotionRecord:
    """Simulate the robot along ``move`` under ``force_n`` (n, 3) with a feedback controller.

    Raises ``ValueError`` if the loop goes unstable: the commanded correction exceeds
    ``max_command_m`` (a physical robot would fault long before).
    """
    force = np.asarray(force_n, float)
    if force.ndim != 2 or force.shape[1] != 3 or not np.all(np.isfinite(force)):
        raise ValueError(f"force_n must be a finite (n, 3) array, got shape {force.shape}")
    if not sample_rate_hz > 0 or not command_rate_hz > 0 or delay_s < 0:
        raise ValueError("sample_rate_hz and command_rate_hz must be positive and delay_s >= 0")
    ratio = sample_rate_hz / command_rate_hz
    if abs(ratio - round(ratio)) > 1e-9 or ratio < 1:
        raise ValueError(
            f"the sample rate {sample_rate_hz} Hz must be an integer multiple of the command rate {command_rate_hz} Hz"
        )
    every = round(ratio)
    delay_steps = round(delay_s * sample_rate_hz)
    gen = _rng(rng)
    n = force.shape[0]
    dt = 1.0 / sample_rate_hz
    duration = n * dt
    t = np.arange(n) * dt
    coarse_t = np.arange(0.0, duration + _TRUTH_STEP_S, _TRUTH_STEP_S)
    coarse = move.coords_at(np.clip(coarse_t / duration, 0.0, 1.0))
    truth = robot.domain(move.domain)
    comps, kk, owner = [], [], []
    for i, d in enumerate(DIRECTIONS):
        ms = truth.modes(coarse, d, allow_extrapolation=allow_extrapolation)
        for j in range(ms.n_modes):
            fn = np.interp(t, coarse_t, ms.fn_hz[:, j])
            k = np.interp(t, coarse_t, ms.stiffness_n_per_m[:, j])
            z = np.interp(t, coarse_t, ms.damping_ratio[:, j])
            comps.append(zoh_transition(fn, k, z, dt))
            kk.append(k)
            owner.append(i)
    p00, p01, p10, p11, g0, g1 = (np.array([c[m] for c in comps]) for m in range(6))
    kk = np.array(kk)
    owner = np.array(owner)
    # Static stiffness of each direction, per sample, mapped back onto its modes.
    k_static = np.vstack([1.0 / np.sum(1.0 / kk[owner == i], axis=0) for i in range(3)])[owner]
    n_modes = owner.size
    x = np.zeros(n_modes)
    v = np.zeros(n_modes)
    disp_true = np.zeros((n, 3))
    tracked = np.zeros((n, 3))
    commands = np.zeros((n + delay_steps + 1, 3))
    held = np.zeros(3)
    prev = np.zeros(3)  # tracker sample one command period ago
    coords = move.coords_at(t / duration)
    for i in range(n):
        tip = np.bincount(owner, weights=x, minlength=3)
        disp_true[i] = tip
        meas = tip + gen.normal(size=3) * tracker_noise_m
        if tracker_resolution_m > 0:
            meas = np.round(meas / tracker_resolution_m) * tracker_resolution_m
        tracked[i] = meas
        if controller is not None and i % every == 0:
            # Backward difference over the command period (the controller runs at that rate).
            vel = (meas - prev) / (every * dt) if i > 0 else np.zeros(3)
            prev = meas
            held = np.asarray(controller(t[i], meas, vel, coords[i]), float).reshape(3)
            if not np.all(np.isfinite(held)) or np.max(np.abs(held)) > max_command_m:
                raise ValueError(
                    f"closed loop unstable at t = {t[i]:.3f} s: commanded correction {np.max(np.abs(held)):.3g} m "
                    f"exceeds {max_command_m:g} m"
                )
        commands[i + delay_steps] = held
        u = commands[i][owner]
        f_eff = force[i][owner] + k_static[:, i] * u
        x, v = (
            p00[:, i] * x + p01[:, i] * v + g0[:, i] * f_eff,
            p10[:, i] * x + p11[:, i] * v + g1[:, i] * f_eff,
        )
    if not math.isfinite(float(np.max(np.abs(disp_true)))):
        raise ValueError("closed-loop simulation diverged")
    return MotionRecord(
        t, force.copy(), tracked, coords, move.domain, disp_true, force.copy(),
        {"delay_s": delay_s, "command_rate_hz": command_rate_hz, "commands_m": commands[:n]},
    )  # fmt: skip
