"""Closed-loop runs on the virtual robot: the actuator (path-correction) input channel.

The robot controller accepts position corrections ``u`` (per direction, metres) at the command
rate (KUKA RSI: 250 Hz) and applies them through a *command channel*
(:class:`CommandChannel`): a transport delay (the thesis measured 32 ms, §4.3.2), optionally an
extra RSI hold of whole command periods, a first-order lag, a rate limit, a stiction /
breakaway band (the causes the thesis names for its delay) and a second-order servo response. The applied correction enters like a
force ``k_s u`` with the direction's static stiffness ``k_s = 1 / sum(1 / k_r)``, so a held
correction ``u`` moves the tool tip by ``u`` once transients decay.

Two kinds of controller are accepted:

* a plain callable ``controller(t, displacement_m, velocity_m_per_s, coords) -> u`` called at the
  command rate with the *measured* tracker displacement (1 kHz samples with noise and 0.01 mm
  resolution) and the backward-difference velocity over one command period (a 1 ms difference
  of 0.01 mm-quantised samples would carry ±10 mm/s of noise), returning a (3,) correction;
* an object with ``reset(coords_at_commands, period_s, sample_rate_hz)`` and
  ``command(k, tracker_m, force_n) -> u``: called at command instant ``k`` with the tracker and
  force-sensor samples (``(every, 3)``, 1 kHz) of the command period that ends at the current
  sample (the last row is the current sample), e.g. a Kalman filter or a force feedforward
  (:mod:`robovib.control.controllers`).

The loop is advanced one command period at a time (``method="blocked"``, default): the force
response is computed for the whole record at once (:func:`~robovib.sim.dynamics.affine_scan`)
and the command response is carried by exact per-period transition matrices precomputed for
all periods, so the Python loop runs once per command (250 Hz), not once per sample.
``method="per-sample"`` is the plain reference loop (one Python step per sample); both give
the same numbers up to rounding (tested).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Literal

import numpy as np

from .dynamics import affine_scan, zoh_transition
from .experiments import _TRUTH_STEP_S, LinearMove, MotionRecord, _rng
from .truth import DIRECTIONS, ModeSet, VirtualRobot

__all__ = [
    "ACTUATORS",
    "PURE_DELAY",
    "CommandChannel",
    "ConstantModesRobot",
    "Controller",
    "run_closed_loop",
]

Controller = Callable[[float, np.ndarray, np.ndarray, np.ndarray], np.ndarray]


@dataclass(frozen=True)
class CommandChannel:
    """How the robot applies a commanded path correction (the actuator model).

    Applied in this order, per 1 kHz sample, independently per direction:

    1. transport delay ``delay_s`` (rounded to whole samples) plus ``hold_periods`` extra
       command periods of RSI hold (the correction is applied at the next-but-``hold`` cycle);
    2. stiction / breakaway (``breakaway_m``): a play operator — the joint does not move until
       the command leaves a band of half-width ``breakaway_m`` around the applied correction,
       then it is dragged along (backlash-like hysteresis of static friction);
    3. rate limit ``rate_limit_m_per_s`` on the applied correction;
    4. first-order lag with time constant ``lag_s`` (servo bandwidth ``1 / (2 pi lag_s)``);
    5. second-order servo response ``w_s^2 / (s^2 + 2 zeta_s w_s s + w_s^2)`` with
       ``w_s = 2 pi servo_hz`` and ``zeta_s = servo_damping`` (unit static gain; exact
       zero-order-hold step per sample). ``servo_hz = inf`` (default) leaves it out. A lightly
       damped servo *amplifies* near ``servo_hz``, the only kind of channel that can make the
       thesis' gains reduce more than ``1 / (1 + |P||C|)`` (see
       :func:`robovib.control.channel.sensitivity_bound`).

    The lag and the servo are exact discretisations with the stage's input held over each
    1 kHz sample; the value applied over sample ``i`` is the stage state at the end of that
    sample (about half a sample of phase lead against the continuous stage).

    6. a static gain ``gain`` (1: the robot applies what it is told; 1.1: a 10 % actuator gain
       error the controller does not know).

    ``CommandChannel()`` is the pure 32 ms transport delay (:data:`PURE_DELAY`).

    Attributes
    ----------
    delay_s
        Transport delay [s].
    lag_s
        First-order lag time constant [s].
    rate_limit_m_per_s
        Rate limit of the applied correction [m/s].
    breakaway_m
        Half-width of the stiction band [m].
    hold_periods
        Extra command periods of RSI hold.
    servo_hz, servo_damping
        Second-order servo natural frequency [Hz] and damping ratio.
    gain
        Static gain of the applied correction (finite, > 0; 1.1: the robot applies 10 % more
        than commanded).
    """

    delay_s: float = 0.032
    lag_s: float = 0.0
    rate_limit_m_per_s: float = math.inf
    breakaway_m: float = 0.0
    hold_periods: int = 0
    servo_hz: float = math.inf
    servo_damping: float = 0.7
    gain: float = 1.0

    def __post_init__(self) -> None:
        if not (math.isfinite(self.gain) and self.gain > 0):
            raise ValueError(f"gain must be a finite number > 0, got {self.gain!r}")
        for name in ("delay_s", "lag_s", "breakaway_m"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0):
                raise ValueError(f"{name} must be a finite number >= 0, got {v!r}")
        if not self.rate_limit_m_per_s > 0:
            raise ValueError(
                f"rate_limit_m_per_s must be > 0 (inf for none), got {self.rate_limit_m_per_s!r}"
            )
        if not self.servo_hz > 0 or math.isnan(self.servo_hz):
            raise ValueError(f"servo_hz must be > 0 [Hz] (inf for none), got {self.servo_hz!r}")
        if not (math.isfinite(self.servo_damping) and 0 < self.servo_damping < 1):
            raise ValueError(
                f"servo_damping must lie in (0, 1) (underdamped), got {self.servo_damping!r}"
            )
        if int(self.hold_periods) != self.hold_periods or self.hold_periods < 0:
            raise ValueError(f"hold_periods must be a whole number >= 0, got {self.hold_periods!r}")

    @property
    def dynamic(self) -> bool:
        """True when the channel has state beyond the delay line (lag, rate limit, breakaway,
        servo)."""
        return (
            self.lag_s > 0
            or math.isfinite(self.rate_limit_m_per_s)
            or self.breakaway_m > 0
            or math.isfinite(self.servo_hz)
        )

    def frequency_response(self, frequency_hz, command_period_s: float = 0.004) -> np.ndarray:
        """Linear part of the channel, applied / commanded correction at ``frequency_hz``.

        ``exp(-s (delay + hold periods)) / (1 + s lag) * servo(s)``, continuous time: the
        simulator's rounding of the delay to whole samples and the half sample of lead of its
        discrete stages are left out, and so are the breakaway band and the rate limit (they
        are amplitude dependent and only reduce the gain).

        Parameters
        ----------
        frequency_hz : array_like
            Frequencies [Hz].
        command_period_s : float
            Command period [s] (the hold periods are multiples of it).

        Returns
        -------
        numpy.ndarray
            Complex frequency response.

        Raises
        ------
        ValueError
            ``command_period_s`` not a finite number > 0.
        """
        if not (math.isfinite(command_period_s) and command_period_s > 0):
            raise ValueError(
                f"command_period_s must be a finite number > 0 [s], got {command_period_s!r}"
            )
        f = np.asarray(frequency_hz, float)
        s = 2j * np.pi * f
        total = self.delay_s + int(self.hold_periods) * command_period_s
        g = self.gain * np.exp(-s * total) / (1.0 + s * self.lag_s)
        if math.isfinite(self.servo_hz):
            ws = 2 * np.pi * self.servo_hz
            g = g * ws**2 / (s**2 + 2 * self.servo_damping * ws * s + ws**2)
        return g

    def to_dict(self) -> dict:
        return {
            "delay_s": self.delay_s,
            "lag_s": self.lag_s,
            "rate_limit_m_per_s": self.rate_limit_m_per_s,
            "breakaway_m": self.breakaway_m,
            "hold_periods": int(self.hold_periods),
            "servo_hz": self.servo_hz,
            "servo_damping": self.servo_damping,
            "gain": self.gain,
        }


#: The uncalibrated channel: a pure 32 ms transport delay (§4.3.2).
PURE_DELAY = CommandChannel()

#: The command channels by name (``robovib control simulate --actuator``).
ACTUATORS = {"pure-delay": PURE_DELAY}


class _ChannelState:
    """Per-sample stiction / rate-limit / lag / servo stages of a :class:`CommandChannel` (3 axes)."""

    def __init__(self, channel: CommandChannel, dt: float):
        self.ch = channel
        self.play = np.zeros(3)
        self.applied = np.zeros(3)
        self.step_max = channel.rate_limit_m_per_s * dt
        self.alpha = math.exp(-dt / channel.lag_s) if channel.lag_s > 0 else 0.0
        self.servo = None
        if math.isfinite(channel.servo_hz):
            self.servo = [float(c) for c in zoh_transition(channel.servo_hz, 1.0, channel.servo_damping, dt)]  # fmt: skip
            self.servo_state = np.zeros((2, 3))

    def advance(self, delayed: np.ndarray) -> np.ndarray:
        """Applied corrections (m, 3) for the delayed commands (m, 3), in order."""
        out = np.empty_like(delayed)
        b = self.ch.breakaway_m
        for i in range(delayed.shape[0]):
            c = delayed[i]
            if b > 0:
                self.play = np.clip(self.play, c - b, c + b)
                c = self.play
            if math.isfinite(self.step_max):
                c = self.applied + np.clip(c - self.applied, -self.step_max, self.step_max)
                if self.alpha == 0.0:
                    self.applied = c
            if self.alpha > 0:
                self.applied = self.alpha * self.applied + (1 - self.alpha) * c
            elif not math.isfinite(self.step_max):
                self.applied = c
            if self.servo is not None:
                p00, p01, p10, p11, g0, g1 = self.servo
                y, v = self.servo_state
                self.servo_state = np.array(
                    [p00 * y + p01 * v + g0 * self.applied, p10 * y + p11 * v + g1 * self.applied]
                )
                out[i] = self.servo_state[0]
            else:
                out[i] = self.applied
        return out


class ConstantModesRobot:
    """A robot whose modes do not change with the pose (a fixed-pose experiment, §4.3.2).

    ``modes`` maps a direction to a :class:`~robovib.sim.truth.ModeSet` row (arrays of shape
    (1, n_modes)); directions not given get a stiff, well-damped placeholder mode
    (100 Hz, 100 MN/m, zeta 0.2) so that they barely move. Used as ``robot`` with a
    ``LinearMove("path", ...)`` of any coordinates.

    Parameters
    ----------
    modes : dict of str to ModeSet
        Direction -> modes.
    """

    def __init__(self, modes: dict[str, ModeSet]):
        for d, ms in modes.items():
            if d not in DIRECTIONS:
                raise ValueError(f"unknown direction {d!r}; expected x, y or z")
            if np.asarray(ms.fn_hz).shape[0] != 1:
                raise ValueError("ConstantModesRobot needs one row of modes per direction")
        self._modes = dict(modes)

    def domain(self, name: str):
        return self

    def modes(self, coords, direction: str, *, allow_extrapolation: bool = False) -> ModeSet:
        n = np.atleast_1d(np.asarray(coords, float)).shape[0]
        ms = self._modes.get(direction) or ModeSet(
            np.array([[100.0]]), np.array([[1e8]]), np.array([[0.2]])
        )
        return ModeSet(*(np.repeat(np.asarray(a, float), n, axis=0) for a in (ms.fn_hz, ms.stiffness_n_per_m, ms.damping_ratio)))  # fmt: skip


#: One-entry cache of the plant maps of the last (robot, move, length, rate): the studies run
#: several controllers on the same cut, which share the truth, the maps and the force response.
_CACHE: dict = {}


def _cached(key, build, robot):
    """``build()`` once per key; the entry holds ``robot`` so that its ``id`` (part of the
    key) cannot be reused by another object while the entry lives."""
    if key not in _CACHE:
        if len(_CACHE) > 8:
            _CACHE.clear()
        _CACHE[key] = (robot, build())
    return _CACHE[key][1]


def _transitions(robot, move, n, dt, allow_extrapolation):
    """Per-sample transition components (n_modes, n), static stiffness per mode and owners."""
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
    p = [np.array([c[m] for c in comps]) for m in range(6)]
    kk = np.array(kk)
    owner = np.array(owner)
    k_static = np.vstack([1.0 / np.sum(1.0 / kk[owner == i], axis=0) for i in range(3)])[owner]
    return p, k_static, owner


def _check_command(held, t_i, max_command_m):
    if not np.all(np.isfinite(held)) or np.max(np.abs(held)) > max_command_m:
        raise ValueError(
            f"closed loop unstable at t = {t_i:.3f} s: commanded correction "
            f"{np.max(np.abs(held)):.3g} m exceeds {max_command_m:g} m"
        )


def run_closed_loop(
    robot: VirtualRobot,
    move: LinearMove,
    force_n: np.ndarray,
    sample_rate_hz: float,
    controller=None,
    *,
    delay_s: float | None = None,
    channel: CommandChannel | None = None,
    command_rate_hz: float = 250.0,
    tracker_noise_m: float = 2e-6,
    tracker_resolution_m: float = 1e-5,
    force_noise_n: float = 0.5,
    force_bias_n=0.0,
    max_command_m: float = 0.01,
    allow_extrapolation: bool = False,
    method: Literal["blocked", "per-sample"] = "blocked",
    rng=None,
) -> MotionRecord:
    """Simulate the robot along ``move`` under ``force_n`` with a feedback controller.

    Parameters
    ----------
    robot
        The truth (:class:`~robovib.sim.VirtualRobot` or :class:`ConstantModesRobot`).
    move
        The straight move (its duration is that of ``force_n``).
    force_n
        (n, 3) force on the tool [N] at ``sample_rate_hz`` (zero-order held per sample).
    sample_rate_hz
        Simulation and sensor rate [Hz]; an integer multiple of ``command_rate_hz``.
    controller
        ``None`` (open loop), a callable ``(t, displacement_m, velocity_m_per_s, coords) -> (3,)``
        or an object with ``reset`` / ``command`` (see the module docs).
    delay_s
        Transport delay [s]; shorthand for ``channel=CommandChannel(delay_s=...)``.
    channel
        The actuator model (default :data:`PURE_DELAY`, 32 ms). Not both with ``delay_s``.
    command_rate_hz
        Controller / RSI rate [Hz] (250).
    tracker_noise_m, tracker_resolution_m
        Laser tracker white noise (std) and quantisation [m].
    force_noise_n
        Force-sensor white noise (std) [N] of the force samples given to ``command`` objects.
    force_bias_n
        Force-sensor bias [N] (scalar or (3,)) added to those samples.
    max_command_m
        A commanded correction above this [m] is taken as an unstable loop.
    allow_extrapolation
        Allow poses outside the robot's calibrated range.
    method
        ``"blocked"`` (one Python step per command period) or ``"per-sample"`` (reference).
    rng
        Seed or ``numpy.random.Generator`` for the sensor noise.

    Returns
    -------
    MotionRecord
        Tracker and true displacements (n, 3) [m]; ``meta["commands_m"]`` holds the applied
        corrections (n, 3) [m], ``meta["channel"]`` the channel settings.

    Raises
    ------
    ValueError
        Bad shapes or rates, or a loop that goes unstable (commanded correction above
        ``max_command_m``; a physical robot would fault long before).
    """
    force = np.asarray(force_n, float)
    if force.ndim != 2 or force.shape[1] != 3 or not np.all(np.isfinite(force)):
        raise ValueError(f"force_n must be a finite (n, 3) array, got shape {force.shape}")
    if force.shape[0] < 2:
        raise ValueError("force_n needs at least 2 samples")
    if not sample_rate_hz > 0 or not command_rate_hz > 0:
        raise ValueError("sample_rate_hz and command_rate_hz must be positive [Hz]")
    if delay_s is not None and channel is not None:
        raise ValueError("give either delay_s or channel, not both")
    if channel is None:
        channel = PURE_DELAY if delay_s is None else CommandChannel(delay_s=delay_s)
    if method not in ("blocked", "per-sample"):
        raise ValueError(f"unknown method {method!r}; expected 'blocked' or 'per-sample'")
    ratio = sample_rate_hz / command_rate_hz
    if abs(ratio - round(ratio)) > 1e-9 or ratio < 1:
        raise ValueError(
            f"the sample rate {sample_rate_hz} Hz must be an integer multiple of the command rate {command_rate_hz} Hz"
        )
    every = round(ratio)
    delay_steps = round(channel.delay_s * sample_rate_hz) + int(channel.hold_periods) * every
    gen = _rng(rng)
    n = force.shape[0]
    dt = 1.0 / sample_rate_hz
    t = np.arange(n) * dt
    coords = move.coords_at(t / (n * dt))
    tracker_noise = gen.normal(size=(n, 3)) * tracker_noise_m
    force_meas = force + gen.normal(size=(n, 3)) * force_noise_n if force_noise_n > 0 else force
    bias = np.broadcast_to(np.asarray(force_bias_n, float), (3,))
    if not np.all(np.isfinite(bias)):
        raise ValueError(f"force_bias_n must be finite [N], got {force_bias_n!r}")
    if np.any(bias != 0):
        force_meas = force_meas + bias
    base_key = (id(robot), move, n, dt, allow_extrapolation)
    p, k_static, owner = _cached(
        ("transitions", *base_key),
        lambda: _transitions(robot, move, n, dt, allow_extrapolation),
        robot,
    )
    rich = hasattr(controller, "command")
    if rich:
        controller.reset(coords[::every], every * dt, sample_rate_hz)
    tip_force = _cached(
        ("force", *base_key, hash(force.tobytes())),
        lambda: _command_response(p, np.ones_like(k_static), owner, force),
        robot,
    )
    args = (force, force_meas, tracker_noise, p, k_static, owner, every, delay_steps, channel,
            controller, rich, t, coords, tracker_resolution_m, max_command_m, dt)  # fmt: skip
    if method == "blocked":
        disp_true, tracked, applied = _blocked(*args, tip_force=tip_force, key=base_key)
    else:
        disp_true, tracked, applied = _per_sample(*args)
    if not math.isfinite(float(np.max(np.abs(disp_true)))):
        raise ValueError("closed-loop simulation diverged")
    return MotionRecord(
        t, force_meas.copy(), tracked, coords, move.domain, disp_true, force.copy(),
        {"delay_s": channel.delay_s, "command_rate_hz": command_rate_hz, "commands_m": applied,
         "channel": channel.to_dict()},
    )  # fmt: skip


def _quantise(x, res):
    return np.round(x / res) * res if res > 0 else x


def _per_sample(force, force_meas, noise, p, k_static, owner, every, delay_steps, channel,
                controller, rich, t, coords, res, max_command_m, dt):  # fmt: skip
    p00, p01, p10, p11, g0, g1 = p
    n = force.shape[0]
    n_modes = owner.size
    x = np.zeros(n_modes)
    v = np.zeros(n_modes)
    disp_true = np.zeros((n, 3))
    tracked = np.zeros((n, 3))
    commands = np.zeros((n + delay_steps + 1, 3))
    applied = np.zeros((n, 3))
    held = np.zeros(3)
    prev = np.zeros(3)
    state = _ChannelState(channel, dt) if channel.dynamic else None
    for i in range(n):
        tip = np.bincount(owner, weights=x, minlength=3)
        disp_true[i] = tip
        meas = _quantise(tip + noise[i], res)
        tracked[i] = meas
        if controller is not None and i % every == 0:
            if rich:
                lo = max(0, i - every + 1)
                held = np.asarray(
                    controller.command(i // every, tracked[lo : i + 1], force_meas[lo : i + 1]),
                    float,
                ).reshape(3)
            else:
                vel = (meas - prev) / (every * dt) if i > 0 else np.zeros(3)
                prev = meas
                held = np.asarray(controller(t[i], meas, vel, coords[i]), float).reshape(3)
            _check_command(held, t[i], max_command_m)
        commands[i + delay_steps] = held
        u = commands[i] if state is None else state.advance(commands[i][None, :])[0]
        u = u * channel.gain
        applied[i] = u
        f_eff = force[i][owner] + k_static[:, i] * u[owner]
        x, v = (
            p00[:, i] * x + p01[:, i] * v + g0[:, i] * f_eff,
            p10[:, i] * x + p11[:, i] * v + g1[:, i] * f_eff,
        )
    return disp_true, tracked, applied


def _block_matrices(p, k_static, owner, length):
    """Exact maps of the command-driven state over blocks of ``length`` samples.

    State ``S`` (2 n_modes,) = [x_0, v_0, x_1, v_1, ...]; input ``U`` (length, 3) = the applied
    corrections of the block's samples. Returns, per block j: ``M[j]`` (S -> S at the next
    block start), ``G[j]`` (U flattened row-major -> S), ``O[j]`` (S -> tip at the block's
    samples, (length * 3, 2 n_modes), row-major (sample, axis)) and ``F[j, a]`` (length,
    length): axis ``a``'s inputs -> its tip displacement at the block's samples.
    """
    p00, p01, p10, p11, g0, g1 = p
    nm, n = p00.shape
    nb = -(-n // length)
    pad = nb * length - n

    def blocks(a, fill):
        a = np.concatenate([a, np.full((nm, pad), fill)], axis=1)
        return a.reshape(nm, nb, length).transpose(1, 0, 2)  # (nb, nm, length)

    q00, q01, q10, q11 = (blocks(a, f) for a, f in ((p00, 1.0), (p01, 0.0), (p10, 0.0), (p11, 1.0)))
    b0, b1 = blocks(g0 * k_static, 0.0), blocks(g1 * k_static, 0.0)
    # P[o]: state map from the block start to offset o (cumulative product of the per-sample
    # transitions); the response at offset o to a unit input at offset o' < o is
    # P[o] P[o'+1]^-1 b[o'] (the maps are 2x2 and well conditioned over a block).
    c00, c01, c10, c11 = (np.empty((nb, nm, length + 1)) for _ in range(4))
    c00[..., 0], c01[..., 0], c10[..., 0], c11[..., 0] = 1.0, 0.0, 0.0, 1.0
    for o in range(length):
        a00, a01, a10, a11 = q00[..., o], q01[..., o], q10[..., o], q11[..., o]
        p00_, p01_, p10_, p11_ = c00[..., o], c01[..., o], c10[..., o], c11[..., o]
        c00[..., o + 1] = a00 * p00_ + a01 * p10_
        c01[..., o + 1] = a00 * p01_ + a01 * p11_
        c10[..., o + 1] = a10 * p00_ + a11 * p10_
        c11[..., o + 1] = a10 * p01_ + a11 * p11_
    n00, n01, n10, n11 = c00[..., 1:], c01[..., 1:], c10[..., 1:], c11[..., 1:]
    det = n00 * n11 - n01 * n10
    w0 = (n11 * b0 - n01 * b1) / det  # (nb, nm, L): P[o'+1]^-1 b[o']
    w1 = (n00 * b1 - n10 * b0) / det
    causal = np.tril(np.ones((length, length)), -1)
    fx = (c00[..., :length, None] * w0[..., None, :] + c01[..., :length, None] * w1[..., None, :]) * causal  # fmt: skip
    ns = 2 * nm
    M = np.zeros((nb, ns, ns))
    G = np.zeros((nb, ns, length * 3))
    O = np.zeros((nb, length * 3, ns))  # noqa: E741
    F = np.zeros((nb, 3, length, length))
    cols = np.arange(length) * 3
    e00, e01, e10, e11 = c00[..., length], c01[..., length], c10[..., length], c11[..., length]
    for m in range(nm):
        a = owner[m]
        r = slice(2 * m, 2 * m + 2)
        M[:, 2 * m, 2 * m], M[:, 2 * m, 2 * m + 1] = e00[:, m], e01[:, m]
        M[:, 2 * m + 1, 2 * m], M[:, 2 * m + 1, 2 * m + 1] = e10[:, m], e11[:, m]
        G[:, 2 * m, cols + a] = e00[:, m, None] * w0[:, m] + e01[:, m, None] * w1[:, m]
        G[:, 2 * m + 1, cols + a] = e10[:, m, None] * w0[:, m] + e11[:, m, None] * w1[:, m]
        O[:, cols + a, r.start] = c00[:, m, :length]
        O[:, cols + a, r.start + 1] = c01[:, m, :length]
        F[:, a] += fx[:, m]
    return M, G, O, F


def _command_response(p, k_static, owner, applied):
    """Tip displacement (n, 3) driven by the applied corrections alone (exact, vectorised)."""
    p00, p01, p10, p11, g0, g1 = p
    u = applied[:, owner].T * k_static
    xs, _ = affine_scan(p00, p01, p10, p11, g0 * u, g1 * u)
    out = np.zeros((applied.shape[0], 3))
    for a in range(3):
        out[:, a] = xs[owner == a, :-1].sum(axis=0)
    return out


def _blocked(force, force_meas, noise, p, k_static, owner, every, delay_steps, channel,
             controller, rich, t, coords, res, max_command_m, dt, *, tip_force, key):  # fmt: skip
    """Advance the loop in blocks of whole command periods no longer than the delay.

    Every correction applied inside a block was decided before it (the delay is at least the
    block), so the block's tracker readings come from one matrix product; the controller is
    then called once per command instant of the block and the state advanced by one more.
    """
    n = force.shape[0]
    if controller is None:
        return tip_force, _quantise(tip_force + noise, res), np.zeros((n, 3))
    per_block = delay_steps // every
    if per_block < 1:  # the delay is shorter than a command period: one sample at a time
        return _per_sample(force, force_meas, noise, p, k_static, owner, every, delay_steps,
                           channel, controller, rich, t, coords, res, max_command_m, dt)  # fmt: skip
    # Blocks of up to 4 command periods (the matrices grow with the block length).
    per_block = min(per_block, 4)
    length = per_block * every
    M, G, Obs, F = _cached(
        ("blocks", *key, length), lambda: _block_matrices(p, k_static, owner, length), None
    )
    nb = M.shape[0]
    n_pad = nb * length
    n_cmd = -(-n // every)
    extra = np.zeros((n_pad - n, 3))
    # What the tracker would read without any correction; the loop adds the command response.
    seen = np.concatenate([tip_force + noise, extra])
    fmeas = np.concatenate([force_meas, extra])
    # Which command instant feeds each sample (after the delay); -1: nothing yet.
    src = np.arange(n_pad) - delay_steps
    src_idx = np.where(src >= 0, src // every, -1).reshape(nb, length)
    cmds = np.zeros((nb * per_block + 1, 3))  # cmds[-1] stays zero: "no command yet"
    state = _ChannelState(channel, dt) if channel.dynamic else None
    applied = np.zeros((n_pad, 3))
    tracked = np.zeros((n_pad, 3))
    inv = 1.0 / res if res > 0 else 0.0
    S = np.zeros(2 * owner.size)
    prev = np.zeros(3)
    zero3 = np.zeros(3)
    period = every * dt
    disp = np.zeros((n_pad, 3))
    noise_pad = np.concatenate([noise, extra])
    for j in range(nb):
        lo, hi = j * length, (j + 1) * length
        u = cmds[src_idx[j]]
        if state is not None:
            u = state.advance(u)
        if channel.gain != 1.0:
            u = u * channel.gain
        applied[lo:hi] = u
        raw = (
            (Obs[j] @ S).reshape(length, 3)
            + seen[lo:hi]
            + np.matmul(F[j], u.T[:, :, None])[:, :, 0].T
        )
        disp[lo:hi] = raw - noise_pad[lo:hi]
        tracked[lo:hi] = np.round(raw * inv) * res if res > 0 else raw
        k0 = j * per_block
        k1 = min(k0 + per_block, n_cmd)
        for k in range(k0, k1):
            i0 = k * every
            if rich:
                a = max(0, i0 - every + 1)
                held = controller.command(k, tracked[a : i0 + 1], fmeas[a : i0 + 1])
            else:
                meas = tracked[i0]
                vel = (meas - prev) / period if i0 > 0 else zero3
                prev = meas
                held = controller(t[i0], meas, vel, coords[i0])
            if np.shape(held) != (3,):
                raise ValueError(
                    f"the controller must return a (3,) correction [m], got shape {np.shape(held)}"
                )
            cmds[k] = held
        if k1 > k0 and not np.abs(cmds[k0:k1]).max() <= max_command_m:
            bad = k0 + int(np.argmax(~(np.abs(cmds[k0:k1]).max(axis=1) <= max_command_m)))
            _check_command(cmds[bad], t[bad * every], max_command_m)
        S = M[j] @ S + G[j] @ u.ravel()
    applied = applied[:n]
    return disp[:n], tracked[:n], applied
