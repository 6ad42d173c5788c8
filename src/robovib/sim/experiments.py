"""Experiments on the virtual robot: hammer tests, milling passes, rotating offset-mass runs.

All experiments are seeded (``rng``) and deterministic. Moving experiments evaluate the truth
along the path (every 10 ms, linearly interpolated to the simulation rate) and integrate the
*time-varying* modal dynamics exactly per sample (:mod:`robovib.sim.dynamics`); directions X,
Y, Z are uncoupled, as the thesis assumes (§3.2.1: cross terms below 6 %).

Sensors (defaults from the thesis): accelerometer for hammer tests; force sensor and laser
tracker at 1 kHz, the tracker with 2 µm noise and 0.01 mm resolution (§3.5.3, §4.3.2).
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field

import numpy as np

from ..io.recording import HammerRecording
from ..milling.forces import CuttingCoefficients, CuttingConditions, MillingTool, milling_forces
from .dynamics import modal_response
from .truth import DIRECTIONS, PATH_LENGTH_M, VirtualRobot

__all__ = [
    "LinearMove",
    "MotionRecord",
    "simulate_hammer_test",
    "simulate_milling",
    "simulate_offset_mass",
]

_TRUTH_STEP_S = 0.01


@dataclass(frozen=True)
class LinearMove:
    """A straight move in one pose domain.

    ``domain="workspace"``: ``start``/``end`` are ``(x_m, y_m, rz_deg)``; the feed direction
    is the XY direction of the move. ``domain="path"``: ``start``/``end`` are distances along
    the chapter-4 path [m]; the path runs in -Y of the base frame.

    Attributes
    ----------
    domain
        ``"workspace"`` or ``"path"``.
    start, end
        Start and end coordinates.
    """

    domain: str
    start: tuple[float, ...]
    end: tuple[float, ...]

    def __post_init__(self) -> None:
        if self.domain not in ("workspace", "path"):
            raise ValueError(f"unknown pose domain {self.domain!r}; expected 'workspace' or 'path'")
        n = 3 if self.domain == "workspace" else 1
        s, e = np.atleast_1d(self.start), np.atleast_1d(self.end)
        if s.shape != (n,) or e.shape != (n,):
            raise ValueError(f"{self.domain} moves need start/end of length {n}")
        object.__setattr__(self, "start", tuple(float(v) for v in s))
        object.__setattr__(self, "end", tuple(float(v) for v in e))

    @property
    def length_m(self) -> float:
        if self.domain == "path":
            return abs(self.end[0] - self.start[0])
        return math.hypot(self.end[0] - self.start[0], self.end[1] - self.start[1])

    def feed_direction(self) -> np.ndarray:
        """Unit feed vector in the base frame (x, y, 0).

        Returns
        -------
        numpy.ndarray
            (3,) unit vector.
        """
        if self.domain == "path":
            return np.array([0.0, -1.0 if self.end[0] >= self.start[0] else 1.0, 0.0])
        d = np.array([self.end[0] - self.start[0], self.end[1] - self.start[1], 0.0])
        norm = np.linalg.norm(d)
        if norm == 0:
            raise ValueError("a workspace move needs distinct start and end XY positions")
        return d / norm

    def coords_at(self, fraction) -> np.ndarray:
        """Pose coordinates at fractions in [0, 1] of the move: (n, 3) or (n,).

        Parameters
        ----------
        fraction : array_like
            Fractions of the move in [0, 1].

        Returns
        -------
        numpy.ndarray
            (n, 3) workspace or (n,) path coordinates.
        """
        f = np.asarray(fraction, float)
        s, e = np.asarray(self.start), np.asarray(self.end)
        c = s[None, :] + f[:, None] * (e - s)[None, :]
        return c[:, 0] if self.domain == "path" else c


@dataclass(frozen=True)
class MotionRecord:
    """Synchronised sensor records of a moving experiment (sensor grid: ``time_s``).

    Attributes
    ----------
    time_s
        (n,) sample times [s].
    force_n
        (n, 3) measured force X, Y, Z [N] (sensor rate).
    displacement_m
        (n, 3) tracker displacement [m] (noise, 0.01 mm resolution).
    coords
        (n, 3) workspace or (n,) path coordinates.
    domain
        ``"workspace"`` or ``"path"``.
    true_displacement_m
        (n, 3) noise-free tool-tip vibration [m].
    true_force_n
        (n, 3) force acting on the tool (cutting + background) [N].
    meta
        Settings and extra records of the run.
    """

    time_s: np.ndarray  #: (n,)
    force_n: np.ndarray  #: (n, 3) measured force X, Y, Z (sensor rate)
    displacement_m: np.ndarray  #: (n, 3) tracker displacement (noise, 0.01 mm resolution)
    coords: np.ndarray  #: (n, 3) workspace or (n,) path coordinates
    domain: str
    true_displacement_m: np.ndarray  #: (n, 3) noise-free tool-tip vibration
    true_force_n: np.ndarray  #: (n, 3) force acting on the tool (cutting + background)
    meta: dict = field(default_factory=dict)

    @property
    def peak_vibration_m(self) -> np.ndarray:
        """(3,) largest absolute noise-free tool-tip displacement per axis X, Y, Z [m]."""
        return np.abs(self.true_displacement_m).max(axis=0)

    def to_csv(self, path, *, inputs=(), force: bool = False, digits: int = 9) -> None:
        """CSV with ``time_s, force_{x,y,z}_n, displacement_{x,y,z}_m`` and the pose columns.

        Parameters
        ----------
        path : str or pathlib.Path
            The CSV file to write.
        inputs : sequence of path
            Files the output was made from (never overwritten unless ``force``).
        force : bool
            Allow ``path`` to be one of ``inputs``.
        digits : int
            Significant digits (17: every float read back exactly, e.g. for a replay).
        """
        import pandas as pd

        cols = {"time_s": self.time_s}
        for i, d in enumerate(DIRECTIONS):
            cols[f"force_{d}_n"] = self.force_n[:, i]
        for i, d in enumerate(DIRECTIONS):
            cols[f"displacement_{d}_m"] = self.displacement_m[:, i]
        if self.domain == "path":
            cols["path_s_m"] = self.coords
        else:
            cols["x_m"], cols["y_m"], cols["rz_deg"] = self.coords.T
        from ..files.safe_write import atomic_output

        with atomic_output(path, inputs=inputs, force=force) as tmp:
            pd.DataFrame(cols).to_csv(tmp, index=False, float_format=f"%.{int(digits)}g")


def _rng(rng) -> np.random.Generator:
    return rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)


def _check_positive(**values) -> None:
    for name, v in values.items():
        if not (isinstance(v, int | float) and math.isfinite(v) and v > 0):
            raise ValueError(f"{name} must be a positive number, got {v!r}")


def _integrating_adc(signals: np.ndarray, factor: int) -> np.ndarray:
    """Each output sample the mean of its ``factor`` internal samples (an integrating ADC).

    The same linear filter on force and response leaves their FRF unchanged; its kernel is
    non-negative, so a short pulse is not given filter ringing (which the hit checks would
    rightly call an overload or a double hit).
    """
    return signals.reshape(*signals.shape[:-1], -1, int(factor)).mean(axis=-1)


def simulate_hammer_test(
    robot: VirtualRobot,
    coords,
    direction: str,
    *,
    domain: str = "workspace",
    n_hits: int = 5,
    sample_rate_hz: float = 17066.0,
    duration_s: float = 4.0,
    pulse_width_s: float = 1e-3,
    peak_force_n: tuple[float, float] = (300.0, 600.0),
    snr_db: float = 40.0,
    allow_extrapolation: bool = False,
    rng=None,
    scatter: tuple[float, float, float] | None = None,
) -> HammerRecording:
    """Impact-hammer test at a fixed pose: half-sine pulses, accelerometer with noise.

    The pulse and the structure are simulated at an internal rate with at least 32 samples per
    pulse; both channels are then recorded by the same integrating ADC (the mean over each
    sample interval), so force and response stay one consistent pair at low sample rates.

    The response noise is white with power ``snr_db`` below the response's mean power over the
    record; the force channel gets 0.05 % of the peak as noise. See ``docs/methods.md`` section 8
    (virtual robot).

    Parameters
    ----------
    robot : VirtualRobot
        The simulated robot (pose-dependent tool-tip modes).
    coords : tuple of float
        The pose: (x [m], y [m], rz [deg]) for ``domain="workspace"``, (s [m],) for ``"path"``.
    direction : {"x", "y", "z"}
        Hit and response direction.
    domain : {"workspace", "path"}
        How ``coords`` is read.
    n_hits : int
        Number of hits (one record each).
    sample_rate_hz : float
        Sample rate [Hz] of both channels.
    duration_s : float
        Record length per hit [s].
    pulse_width_s : float
        Width of the half-sine force pulse [s].
    peak_force_n : tuple of float
        Range (low, high) [N] the peak force of each hit is drawn from.
    snr_db : float
        Response signal-to-noise ratio [dB].
    allow_extrapolation : bool
        Allow poses outside the robot's calibrated range (otherwise an error).
    rng : int or numpy.random.Generator, optional
        Seed of the forces and the noise.
    scatter : tuple of float, optional
        Test-to-test scatter: relative standard deviations of (fn, k, ζ), one Gaussian factor
        per test applied to every mode (a re-clamped tool, another hammer spot, temperature).
        Table A1's replicates scatter by about (0.01, 0.04, 0.04) (RMS of the within-pose
        relative std). ``None``: every test sees the same modes.

    Returns
    -------
    HammerRecording
        ``forces`` [N] and ``responses`` [m/s²], (n_hits, n_samples), with direction and pose.

    Raises
    ------
    ValueError
        Unknown direction or domain, a pose outside the range, non-positive rates or durations.

    Examples
    --------
    >>> from robovib.sim import VirtualRobot, simulate_hammer_test
    >>> rec = simulate_hammer_test(VirtualRobot(), (2.4, 0.0, 45.0), "x", n_hits=2, rng=0)
    >>> rec.forces.shape[0]
    2
    """
    _check_positive(
        sample_rate_hz=sample_rate_hz, duration_s=duration_s, pulse_width_s=pulse_width_s
    )
    if int(n_hits) < 1:
        raise ValueError(f"n_hits must be >= 1, got {n_hits}")
    modes = robot.domain(domain).modes(coords, direction, allow_extrapolation=allow_extrapolation)
    if modes.fn_hz.shape[0] != 1:
        raise ValueError("a hammer test takes one pose")
    gen = _rng(rng)
    fn_hz, k_n_per_m, zeta = modes.fn_hz, modes.stiffness_n_per_m, modes.damping_ratio
    if scatter is not None:
        rel = np.asarray(scatter, float)
        if (
            rel.shape != (3,)
            or not np.all(np.isfinite(rel))
            or np.any(rel < 0)
            or np.any(rel >= 0.3)
        ):
            raise ValueError(
                f"scatter must be 3 relative stds (fn, k, zeta) in [0, 0.3), got {scatter!r}"
            )
        f_fn, f_k, f_z = 1.0 + rel * gen.standard_normal(3)
        fn_hz, k_n_per_m, zeta = fn_hz * f_fn, k_n_per_m * f_k, zeta * f_z
    n = round(duration_s * sample_rate_hz)
    # The pulse and the structure run at an internal rate with >= 32 samples per pulse, and
    # both channels are averaged over each sample interval (integrating ADC): a pulse sampled
    # at one or two points and held (zero-order hold) drove the structure half a sample late,
    # which biased every fitted fn low (-0.45 % at the campaign's 1280 Hz).
    over = max(1, math.ceil(32.0 / (pulse_width_s * sample_rate_hz)))
    rate_hz = over * sample_rate_hz
    t = np.arange(n * over) / rate_hz
    params = [np.repeat(a.T, t.size, axis=1) for a in (fn_hz, k_n_per_m, zeta)]
    forces, responses = [], []
    for _ in range(int(n_hits)):
        t0 = 0.02 + gen.uniform(0.0, 0.01)
        peak = gen.uniform(*peak_force_n)
        pulse = np.where(
            (t >= t0) & (t <= t0 + pulse_width_s), np.sin(np.pi * (t - t0) / pulse_width_s), 0.0
        )
        f = peak * np.clip(pulse, 0.0, None)
        _, _, acc = modal_response(*params, f, 1.0 / rate_hz)
        if over > 1:
            f, acc = _integrating_adc(np.stack([f, acc]), over)
        noise = gen.normal(size=n) * math.sqrt(np.mean(acc**2) / 10 ** (snr_db / 10))
        forces.append(f + gen.normal(size=n) * 5e-4 * peak)
        responses.append(acc + noise)
    c = np.atleast_1d(np.asarray(coords, float))
    pose = (c[0], c[1], 0.325, 0.0, 0.0, c[2]) if domain == "workspace" else None
    return HammerRecording(
        np.array(forces), np.array(responses), sample_rate_hz, "acceleration", direction, pose
    )


def _moving_response(
    robot, move, force_sim, fs_sim, allow_extrapolation, command=None, sample_offset=0.0
):
    n = force_sim.shape[0]
    duration = n / fs_sim
    coarse_t = np.arange(0.0, duration + _TRUTH_STEP_S, _TRUTH_STEP_S)
    coarse_coords = move.coords_at(np.clip(coarse_t / duration, 0.0, 1.0))
    t = np.arange(n) / fs_sim
    truth = robot.domain(move.domain)
    disp = np.zeros((n, 3))
    for i, d in enumerate(DIRECTIONS):
        ms = truth.modes(coarse_coords, d, allow_extrapolation=allow_extrapolation)
        params = [
            np.vstack([np.interp(t, coarse_t, a[:, j]) for j in range(ms.n_modes)])
            for a in (ms.fn_hz, ms.stiffness_n_per_m, ms.damping_ratio)
        ]
        cmd = None if command is None else command[:, i]
        disp[:, i], _, _ = modal_response(
            *params, force_sim[:, i], 1.0 / fs_sim, command=cmd, sample_offset=sample_offset
        )
    return disp, move.coords_at(t / duration)


def _sensors(
    gen, force, disp, fs_sim, fs_sensor, force_noise_n, tracker_noise_m, tracker_resolution_m
):
    step = fs_sim / fs_sensor
    if abs(step - round(step)) > 1e-9 or step < 1:
        raise ValueError(
            f"the simulation rate {fs_sim} Hz must be an integer multiple of the sensor rate {fs_sensor} Hz"
        )
    step = round(step)
    if step > 1:
        from scipy import signal

        force_meas = signal.decimate(force, step, axis=0, ftype="fir", zero_phase=True)
    else:
        force_meas = force.copy()
    disp_s = disp[::step]
    force_meas = (
        force_meas[: disp_s.shape[0]]
        + gen.normal(size=force_meas[: disp_s.shape[0]].shape) * force_noise_n
    )
    tracked = disp_s + gen.normal(size=disp_s.shape) * tracker_noise_m
    if tracker_resolution_m > 0:
        tracked = np.round(tracked / tracker_resolution_m) * tracker_resolution_m
    return force_meas, tracked, step


#: Half-length of the anti-alias filter in simulation samples (its taps: 2 x this x the
#: oversampling + 1).
_ANTI_ALIAS_HALF_SAMPLES = 16


def _band_limited_force(
    cutting, n: int, fs: float, oversampling: int, block: int | None = None
) -> np.ndarray:
    """(n, 3) force ``cutting(t)`` at ``t = i / fs``, band-limited below ``fs / 2``.

    ``cutting`` is evaluated at ``oversampling x fs`` on ``[-L, n / fs + L)`` (``L`` the
    filter's half-length: the cut runs on before and after the record, so the filter has no
    edge), filtered by a linear-phase Kaiser FIR (``beta`` 8: >= 80 dB stop band; cut-off
    0.45 fs, transition ~0.16 fs) centred on each output sample (zero phase), and every
    ``oversampling``-th sample kept (:func:`scipy.signal.upfirdn`). ``block``: at most this
    many output samples per pass, in blocks of near-equal size (``cutting`` then sees only
    the fine times of a block and its filter's reach, so its value at a time must not depend
    on the other times: :func:`~robovib.milling.forces.milling_forces` interpolates its angle
    table alike for any array longer than ``n_angles``); None: all in one pass. Blocks keep
    the fine grid small (a 177 s pass at 128 x 1 kHz is 23 million fine samples) and give the
    same numbers.
    """
    if oversampling == 1:
        return cutting(np.arange(n) / fs)
    from scipy import signal

    k = oversampling
    half = _ANTI_ALIAS_HALF_SAMPLES * k  # fine samples each side of the filter's centre
    taps = signal.firwin(2 * half + 1, 0.45 * fs, window=("kaiser", 8.0), fs=fs * k)
    # y[m] = sum_j taps[j] fine[m k - j]: the output centred on fine sample half + i k (time
    # i / fs) is m = i + 2 half / k
    first = 2 * half // k
    n_blocks = 1 if block is None else max(1, -(-n // max(int(block), 1)))
    ends = np.linspace(0, n, n_blocks + 1).round().astype(int)  # blocks of near-equal size
    parts = []
    for i0, i1 in itertools.pairwise(ends.tolist()):
        # fine samples i0 k ... i1 k + 2 half - 1 cover the reach of outputs i0 .. i1 - 1
        fine_t = (np.arange(i0 * k, i1 * k + 2 * half) - half) / (fs * k)
        out = signal.upfirdn(taps, cutting(fine_t), up=1, down=k, axis=0)
        parts.append(out[first : first + i1 - i0])
    return parts[0] if len(parts) == 1 else np.concatenate(parts)


#: Output samples per pass of the band-limited force where the force depends on time alone
#: (~25 MB of fine samples at 128 x oversampling).
_FORCE_BLOCK = 8192


def simulate_milling(
    robot: VirtualRobot,
    move: LinearMove,
    tool: MillingTool,
    conditions: CuttingConditions,
    coefficients: CuttingCoefficients,
    *,
    background_noise_rel: float = 0.15,
    simulation_rate_hz: float = 1000.0,
    sensor_rate_hz: float = 1000.0,
    force_noise_n: float = 0.5,
    tracker_noise_m: float = 2e-6,
    tracker_resolution_m: float = 1e-5,
    allow_extrapolation: bool = False,
    disturbances=None,
    force_oversampling: int = 128,
    rng=None,
) -> MotionRecord:
    """A milling pass along ``move`` at the feed speed set by the cutting conditions.

    Force on the tool = mechanistic cutting force (tool frame rotated to the base frame: feed
    along the move, normal = Z x feed, axial = +Z) + broadband background force (white,
    ``background_noise_rel`` x the RMS of each cutting-force component about its mean): the
    excitation that makes OMA possible (§5.2.2). The tool tip responds through the
    pose-varying modes of the robot along the path.

    The cutting force has tooth harmonics far above the simulation's Nyquist frequency (the
    17th of a 2-flute cut at 1750 rpm is 991.7 Hz); sampled as it is, each would fold to
    ``|fs - h f_tooth|`` (8.3 Hz, onto the Y mode) and drive the modes there. So it is computed
    at ``force_oversampling`` x the simulation rate and low-passed before it is sampled at
    the simulation rate (:func:`_band_limited_force`: a zero-phase Kaiser FIR, flat to 0.37 fs,
    >= 80 dB down from 0.53 fs, on a window padded by the force itself before and after the
    pass); ``force_oversampling=1`` samples it as it is (the records of robovib < 0.11). The
    band-limited force is held over each simulation step and the response is sampled
    mid-step, so force and displacement samples are simultaneous (start-of-step samples would
    lag the force by half a step: a -omega h / 2 phase, 0.5 ms at 1 kHz, in every FRF
    estimated from the record).

    Parameters
    ----------
    robot : VirtualRobot
        The virtual robot.
    move : LinearMove
        The pass.
    tool : MillingTool
        The cutter.
    conditions : CuttingConditions
        Spindle speed, feed, depths.
    coefficients : CuttingCoefficients
        Cutting-force coefficients of the material.
    background_noise_rel : float
        Background force relative to the RMS cutting force.
    sensor_rate_hz : float
        Rate of the recorded channels [Hz].
    force_noise_n : float
        Force-sensor white noise (std) [N].
    simulation_rate_hz : float
        Simulation rate [Hz].
    tracker_noise_m, tracker_resolution_m : float
        Laser tracker white noise (std) and quantisation [m].
    allow_extrapolation : bool
        Allow poses outside the robot's calibrated range.
    disturbances : CutDisturbances, optional
        The disturbances of a real cut (:class:`~robovib.sim.disturbances.CutDisturbances`):
        spindle-speed error and drift, runout, non-periodic force and engagement change act on
        the cutting force; the force-sensor noise (added to ``force_noise_n`` in quadrature)
        and bias on the measured force. The actuator gain and delay errors need a controller
        (open loop here: recorded in ``meta`` only).
    force_oversampling : int
        The cutting force is computed at this multiple of the simulation rate and low-passed
        (1: sampled at the simulation rate, with its aliases). The entry and exit of the teeth
        are jumps, so the harmonics fall only as ~1/h and the fine grid folds those near its
        own rate too: at 128 (128 kHz at 1 kHz) a tooth harmonic folded onto a lightly damped
        mode is < 0.1 % of the first tooth line in the displacement, at 32 ~6 %, at 1 ~30x
        (``tests/sim/test_milling_force_alias.py``).
    rng : int or numpy.random.Generator, optional
        Seed of the noise.

    Returns
    -------
    MotionRecord
        Forces, tracker and true displacements along the pass; ``meta["disturbances"]`` the
        active disturbances (name -> value).
    """
    _check_positive(simulation_rate_hz=simulation_rate_hz, sensor_rate_hz=sensor_rate_hz)
    if background_noise_rel < 0:
        raise ValueError(f"background_noise_rel must be >= 0, got {background_noise_rel}")
    gen = _rng(rng)
    speed = conditions.feed_speed_m_per_s(tool)
    duration = move.length_m / speed
    n = round(duration * simulation_rate_hz)
    if n < 10:
        raise ValueError(f"the pass is too short: {move.length_m} m at {speed * 1e3:.3g} mm/s")
    if isinstance(force_oversampling, bool) or int(force_oversampling) != force_oversampling:
        raise ValueError(f"force_oversampling must be an integer >= 1, got {force_oversampling!r}")
    if force_oversampling < 1:
        raise ValueError(f"force_oversampling must be an integer >= 1, got {force_oversampling!r}")
    t = np.arange(n) / simulation_rate_hz
    if disturbances is None:

        def cutting(tt):
            return milling_forces(tt, tool, conditions, coefficients)
    else:

        def cutting(tt):
            return disturbances.cutting_force(tt, tool, conditions, coefficients, rng=gen)

        force_noise_n = math.hypot(force_noise_n, disturbances.force_noise_n)
    # The disturbances' non-periodic force, engagement and speed drift are drawn over the
    # whole pass: one block there.
    local = _band_limited_force(cutting, n, simulation_rate_hz, int(force_oversampling),
                                _FORCE_BLOCK if disturbances is None else None)  # fmt: skip
    feed = move.feed_direction()
    normal = np.array([-feed[1], feed[0], 0.0])
    force = local[:, :1] * feed[None, :] + local[:, 1:2] * normal[None, :]
    force[:, 2] = local[:, 2]
    spread = force.std(axis=0)
    force = force + gen.normal(size=force.shape) * background_noise_rel * spread[None, :]
    # Response sampled mid-step, where the held force sample acts: force and displacement
    # are simultaneous samples (a held force lags its samples by half a step, 0.5 ms at
    # 1 kHz, which would show as a -omega h / 2 phase in every OMA FRF).
    disp, coords = _moving_response(
        robot, move, force, simulation_rate_hz, allow_extrapolation, sample_offset=0.5
    )
    force_meas, tracked, step = _sensors(
        gen,
        force,
        disp,
        simulation_rate_hz,
        sensor_rate_hz,
        force_noise_n,
        tracker_noise_m,
        tracker_resolution_m,
    )
    if disturbances is not None and disturbances.force_bias_n != 0:
        force_meas = force_meas + disturbances.force_bias_n
    m = tracked.shape[0]
    return MotionRecord(
        time_s=t[::step][:m],
        force_n=force_meas,
        displacement_m=tracked,
        coords=coords[::step][:m],
        domain=move.domain,
        true_displacement_m=disp[::step][:m],
        true_force_n=force[::step][:m],
        meta={
            "spindle_rpm": conditions.spindle_rpm,
            "feed_per_tooth_m": conditions.feed_per_tooth_m,
            "axial_depth_m": conditions.axial_depth_m,
            "radial_depth_m": conditions.radial_depth_m,
            "feed_speed_m_per_s": speed,
            "tooth_passing_hz": conditions.tooth_passing_hz(tool),
            "disturbances": {} if disturbances is None else disturbances.active(),
        },
    )


def offset_mass_force(
    time_s, spindle_rpm: float, mass_kg: float = 1.0, radius_m: float = 0.0508
) -> np.ndarray:
    """Rotating-unbalance force (n, 3) in the base XY plane (tool axis along Z).

    Thesis Eq. 27 with the physical frequency: ``m_o L (2 pi f)^2 [cos, sin](2 pi f t)``,
    ``f = rpm / 60`` (the printed ``sin(2 pi t / Omega)`` with Omega in rpm is a typo).

    Parameters
    ----------
    time_s : array_like
        (n,) times [s].
    spindle_rpm : float
        Spindle speed [rpm].
    mass_kg : float
        Offset mass [kg].
    radius_m : float
        Its radius [m].

    Returns
    -------
    numpy.ndarray
        (n, 3) force [N].
    """
    _check_positive(spindle_rpm=spindle_rpm, mass_kg=mass_kg, radius_m=radius_m)
    w = 2 * math.pi * spindle_rpm / 60.0
    t = np.asarray(time_s, float)
    amp = mass_kg * radius_m * w**2
    return np.column_stack([amp * np.cos(w * t), amp * np.sin(w * t), np.zeros_like(t)])


def simulate_offset_mass(
    robot: VirtualRobot,
    move: LinearMove,
    spindle_rpm: float,
    *,
    speed_m_per_s: float = 0.084,
    mass_kg: float = 1.0,
    radius_m: float = 0.0508,
    simulation_rate_hz: float = 1000.0,
    tracker_noise_m: float = 2e-6,
    tracker_resolution_m: float = 1e-5,
    allow_extrapolation: bool = False,
    rng=None,
) -> MotionRecord:
    """Open-loop rotating offset-mass run along ``move`` (§4.3.2-4.3.3; defaults: 1 kg, 50.8 mm, 84 mm/s).

    Parameters
    ----------
    robot : VirtualRobot
        The virtual robot.
    move : LinearMove
        The move.
    spindle_rpm : float
        Spindle speed [rpm] (the unbalance frequency is rpm / 60).
    speed_m_per_s : float
        Feed speed [m/s].
    mass_kg, radius_m : float
        Offset mass [kg] and its radius [m].
    simulation_rate_hz : float
        Simulation rate [Hz].
    tracker_noise_m, tracker_resolution_m : float
        Laser tracker white noise (std) and quantisation [m].
    allow_extrapolation : bool
        Allow poses outside the robot's calibrated range.
    rng : int or numpy.random.Generator, optional
        Seed of the noise.

    Returns
    -------
    MotionRecord
        Forces, tracker and true displacements along the move.
    """
    _check_positive(speed_m_per_s=speed_m_per_s)
    gen = _rng(rng)
    duration = move.length_m / speed_m_per_s
    n = round(duration * simulation_rate_hz)
    if n < 10:
        raise ValueError("the move is too short for the given speed")
    t = np.arange(n) / simulation_rate_hz
    force = offset_mass_force(t, spindle_rpm, mass_kg, radius_m)
    disp, coords = _moving_response(robot, move, force, simulation_rate_hz, allow_extrapolation)
    force_meas, tracked, _step = _sensors(
        gen,
        force,
        disp,
        simulation_rate_hz,
        simulation_rate_hz,
        0.0,
        tracker_noise_m,
        tracker_resolution_m,
    )
    return MotionRecord(
        t,
        force_meas,
        tracked,
        coords,
        move.domain,
        disp,
        force,
        {"spindle_rpm": spindle_rpm, "speed_m_per_s": speed_m_per_s},
    )


def default_path_move(reverse: bool = False) -> LinearMove:
    """The whole chapter-4 path (start -> end, or end -> start as in the offset-mass runs).

    Parameters
    ----------
    reverse : bool
        End -> start.

    Returns
    -------
    LinearMove
        The move along the path.
    """
    return LinearMove(
        "path", (PATH_LENGTH_M,) if reverse else (0.0,), (0.0,) if reverse else (PATH_LENGTH_M,)
    )
