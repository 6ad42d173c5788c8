"""Pose-dependent LQR of the dominant tool-tip mode (thesis §4.3.1, Eq. 18-26).

Plant per direction, state ``[x, x']`` (m, m/s)::

    x'' + 2 zeta wn x' + wn^2 x = b u,   A = [[0, 1], [-wn^2, -2 zeta wn]]

* ``input="displacement"`` (default): ``u`` is the path correction [m] sent to the robot
  controller (the experiment's actuator), ``b = wn^2`` — a held ``u`` moves the tip by ``u``.
* ``input="force"``: ``u`` is a force [N] at the tool tip, ``b = 1/m``.

The thesis prints ``A = [[0, 1], [-k, -c]]`` and ``c = 2 m wn / zeta`` (Eq. 21-22): dimensionally
wrong (k and c must be divided by m) and the damping relation inverted (``c = 2 zeta m wn``).
The physical form is the default; ``formulation="thesis_printed"`` builds the printed matrices
(``B = [0, 1/m]``, SI) for comparison only. Neither reproduces Table 9's absolute gains (see
:func:`robovib.studies.table9.table_9_comparison`); the displacement-input physical model reproduces all the trends
the thesis states.

Discretisation (Eq. 19-20) is the exact zero-order hold through the matrix exponential of the
augmented matrix ``[[A, B], [0, 0]] T``, valid also for singular ``A`` (Eq. 20 needs A^-1).
The Riccati equation (Eq. 26) is solved by structure-preserving doubling
(:func:`robovib._linalg.solve_dare`, NumPy; tested against :func:`scipy.linalg.solve_discrete_are`,
whose import alone costs a one-pose command ~0.2 s); the gain is Eq. 25. The closed loop is ``A_d - B_d W`` (Eq. 23 prints the continuous A, B: a typo).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

from .._linalg import batched_expm, solve_dare
from ..modal.parameters import ModalParameters

__all__ = [
    "THESIS_Q",
    "THESIS_R",
    "DelayAnalysis",
    "DelayAwareDesign",
    "KalmanDesign",
    "LQRDesign",
    "LoopMargins",
    "closed_loop_with_delay",
    "continuous_model",
    "delay_analysis",
    "design_delay_aware_lqr",
    "design_kalman",
    "design_lqr",
    "discretize",
    "loop_margins",
    "spectral_radius",
    "tune_r_for_delay",
]

THESIS_Q = np.diag([1.0, 0.001])
THESIS_R = np.array([[0.001]])


def continuous_model(
    mode: ModalParameters,
    *,
    input: Literal["displacement", "force"] = "displacement",
    formulation: Literal["physical", "thesis_printed"] = "physical",
) -> tuple[np.ndarray, np.ndarray]:
    """Continuous (A, B) of one mode (see module docs).

    Parameters
    ----------
    mode : ModalParameters
        The mode.
    input : {"displacement", "force"}
        What the control input is.
    formulation : {"physical", "thesis_printed"}
        The physical model, or the thesis' printed matrices.

    Returns
    -------
    a, b : numpy.ndarray
        (2, 2) and (2, 1) state-space matrices.
    """
    wn, z, k, m = mode.omega_n, mode.damping_ratio, mode.stiffness_n_per_m, mode.mass_kg
    if formulation == "thesis_printed":
        c_printed = 2 * m * wn / max(z, 1e-12)
        return np.array([[0.0, 1.0], [-k, -c_printed]]), np.array([[0.0], [1.0 / m]])
    if formulation != "physical":
        raise ValueError(
            f"unknown formulation {formulation!r}; expected 'physical' or 'thesis_printed'"
        )
    a = np.array([[0.0, 1.0], [-(wn**2), -2 * z * wn]])
    if input == "displacement":
        return a, np.array([[0.0], [wn**2]])
    if input == "force":
        return a, np.array([[0.0], [1.0 / m]])
    raise ValueError(f"unknown input {input!r}; expected 'displacement' or 'force'")


def discretize(a: np.ndarray, b: np.ndarray, period_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Exact zero-order-hold discretisation (Eq. 19-20) via the augmented matrix exponential.

    Parameters
    ----------
    a, b : numpy.ndarray
        Continuous state-space matrices.
    period_s : float
        Sample period [s].

    Returns
    -------
    ad, bd : numpy.ndarray
        Discrete matrices.
    """
    if not (np.isfinite(period_s) and period_s > 0):
        raise ValueError(f"the sampling period must be positive, got {period_s!r}")
    n, m = a.shape[0], b.shape[1]
    aug = np.zeros((n + m, n + m))
    aug[:n, :n], aug[:n, n:] = a, b
    e = batched_expm(aug * period_s)  # Padé 13 with scaling and squaring, as scipy.linalg.expm
    return e[:n, :n], e[:n, n:]


def _check_weights(q, r):
    q = np.atleast_2d(np.asarray(q, float))
    r = np.atleast_2d(np.asarray(r, float))
    if q.shape != (2, 2) or r.shape != (1, 1):
        raise ValueError(f"Q must be 2x2 and R 1x1, got {q.shape} and {r.shape}")
    if not np.allclose(q, q.T) or np.min(np.linalg.eigvalsh(q)) < -1e-12:
        raise ValueError("Q must be symmetric positive semi-definite")
    if not r[0, 0] > 0:
        raise ValueError("R must be positive definite")
    return q, r


@dataclass(frozen=True)
class LQRDesign:
    """Discrete model, Riccati solution and gains W = [w1, w2] of one mode.

    Attributes
    ----------
    ad, bd
        Discrete model (A_d, B_d).
    p
        Riccati solution.
    gains
        (2,) w1 [u per m], w2 [u per m/s].
    period_s
        Command period [s].
    """

    ad: np.ndarray
    bd: np.ndarray
    p: np.ndarray
    gains: np.ndarray  #: (2,) w1 [u per m], w2 [u per m/s]
    period_s: float

    @property
    def closed_loop(self) -> np.ndarray:
        """A_d - B_d W (Eq. 23, discrete)."""
        return self.ad - self.bd @ self.gains[None, :]

    @property
    def spectral_radius(self) -> float:
        return spectral_radius(self.closed_loop)


def design_lqr(
    mode: ModalParameters,
    period_s: float = 0.004,
    q=THESIS_Q,
    r=THESIS_R,
    *,
    input: Literal["displacement", "force"] = "displacement",
    formulation: Literal["physical", "thesis_printed"] = "physical",
) -> LQRDesign:
    """LQR gains of one mode (Eq. 24-26); defaults: thesis weights, 250 Hz command rate.

    See ``docs/methods.md`` section 6 (pose-dependent vibration control).

    Parameters
    ----------
    mode : ModalParameters
        The mode to damp (fn [Hz], k [N/m], zeta).
    period_s : float
        Command period [s] of the zero-order-hold discretisation (> 0).
    q : array_like, shape (2, 2)
        State weight (displacement [m], velocity [m/s]); symmetric positive semi-definite.
    r : array_like, shape (1, 1)
        Input weight; positive definite.
    input : {"displacement", "force"}
        Whether the controller commands a displacement offset [m] or a force [N].
    formulation : {"physical", "thesis_printed"}
        State-space form: the physical one or the thesis' printed Eq. 18 (see docs/data.md).

    Returns
    -------
    LQRDesign
        Discrete model ``ad``, ``bd``, Riccati solution ``p`` and gains ``gains`` = [w1, w2].

    Raises
    ------
    ValueError
        Weights of the wrong shape or not (semi-)definite, non-positive period, unknown
        ``input`` or ``formulation``.

    Examples
    --------
    >>> from robovib.control import design_lqr
    >>> from robovib.modal import ModalParameters
    >>> design = design_lqr(ModalParameters(14.0, 2e6, 0.05))
    >>> design.gains.shape, design.spectral_radius < 1
    ((2,), True)
    """
    q, r = _check_weights(q, r)
    a, b = continuous_model(mode, input=input, formulation=formulation)
    ad, bd = discretize(a, b, period_s)
    p = solve_dare(ad, bd, q, r)
    w = np.linalg.solve(r + bd.T @ p @ bd, bd.T @ p @ ad)[0]
    return LQRDesign(ad, bd, p, w, period_s)


def _delay_augmented(
    ad: np.ndarray, bd: np.ndarray, delay_steps: int
) -> tuple[np.ndarray, np.ndarray]:
    """(A, B) of the plant with a ``d``-step input delay line.

    State ``[x_k, v_k, u_{k-1}, ..., u_{k-d}]``; input ``u_k``; the plant sees ``u_{k-d}``.
    """
    d = int(delay_steps)
    if d < 0:
        raise ValueError("delay_steps must be >= 0")
    if d == 0:
        return ad, bd
    n = 2 + d
    big_a = np.zeros((n, n))
    big_b = np.zeros((n, 1))
    big_a[:2, :2] = ad
    big_a[:2, n - 1 : n] = bd
    big_b[2, 0] = 1.0
    for i in range(3, n):
        big_a[i, i - 1] = 1.0
    return big_a, big_b


def closed_loop_with_delay(design: LQRDesign, delay_steps: int) -> np.ndarray:
    """Closed-loop matrix with the command applied ``delay_steps`` periods late.

    State ``[x_k, v_k, u_{k-1}, ..., u_{k-d}]``; ``u_k = -W [x_k, v_k]``, the plant sees ``u_{k-d}``.

    Parameters
    ----------
    design : LQRDesign
        The design.
    delay_steps : int
        Delay in command periods.

    Returns
    -------
    numpy.ndarray
        (2 + d, 2 + d) closed-loop matrix.
    """
    big_a, big_b = _delay_augmented(design.ad, design.bd, delay_steps)
    gains = np.zeros(big_a.shape[0])
    gains[:2] = design.gains
    return big_a - big_b @ gains[None, :]


@dataclass(frozen=True)
class DelayAnalysis:
    """Stability of an LQR loop with a transport delay.

    Attributes
    ----------
    delay_steps
        The delay in command periods.
    spectral_radius
        Of the delayed closed loop (< 1: stable).
    stable
        Whether the loop is stable with that delay.
    max_stable_delay_steps, max_stable_delay_s
        The largest stable delay (periods, seconds).
    """

    delay_steps: int
    spectral_radius: float
    stable: bool
    max_stable_delay_steps: int
    max_stable_delay_s: float


MAX_DELAY_S = 1.0  #: largest transport delay accepted (the KRC4's is 0.032 s)
MAX_DELAY_STEPS = 500  #: largest delay in command periods (state augmentation size)


def _delay_steps(delay_s, period_s, rounding) -> int:
    """Delay in whole command periods, checked: finite, 0 <= delay <= 1 s, known rounding."""
    from .._checks import check_choice, check_number

    check_choice("rounding", rounding, ("reject", "round"))
    delay_s = check_number("delay_s", delay_s, "s", lo=0.0, hi=MAX_DELAY_S)
    period_s = check_number("period_s", period_s, "s", lo=0.0, lo_open=True)
    steps_f = delay_s / period_s
    if abs(steps_f - round(steps_f)) > 1e-9 and rounding == "reject":
        raise ValueError(
            f"delay {delay_s} s is not a multiple of the command period {period_s} s "
            "(pass rounding='round' to round it)"
        )
    steps = round(steps_f)
    if steps > MAX_DELAY_STEPS:
        raise ValueError(
            f"delay {delay_s} s is {steps} command periods of {period_s} s; at most "
            f"{MAX_DELAY_STEPS} are supported"
        )
    return steps


def delay_analysis(
    design: LQRDesign,
    delay_s: float = 0.032,
    *,
    rounding: Literal["reject", "round"] = "reject",
    max_search_steps: int = 64,
) -> DelayAnalysis:
    """Stability of the loop with a transport delay, and the largest stable delay.

    The delay must be a whole number of command periods: ``rounding="reject"`` (default)
    raises otherwise, ``"round"`` rounds to the nearest period. The largest stable delay is
    searched up to ``max_search_steps`` periods (reported as that bound if all are stable).

    Parameters
    ----------
    design : LQRDesign
        The design.
    delay_s : float
        Transport delay [s].
    rounding : {"reject", "round"}
        What to do with a delay that is not a whole number of periods.
    max_search_steps : int
        Longest delay searched [periods].

    Returns
    -------
    DelayAnalysis
        Stability with ``delay_s`` and the largest stable delay.
    """
    steps = _delay_steps(delay_s, design.period_s, rounding)
    from .._checks import check_int

    max_search_steps = check_int("max_search_steps", max_search_steps, lo=0, hi=MAX_DELAY_STEPS)
    rho = spectral_radius(closed_loop_with_delay(design, steps))
    max_ok = -1
    for d in range(0, int(max_search_steps) + 1):
        if spectral_radius(closed_loop_with_delay(design, d)) < 1:
            max_ok = d
        else:
            break
    return DelayAnalysis(steps, rho, rho < 1, max_ok, max_ok * design.period_s)


def tune_r_for_delay(
    mode: ModalParameters,
    period_s: float = 0.004,
    delay_s: float = 0.032,
    q=THESIS_Q,
    *,
    r_grid=None,
    input: Literal["displacement", "force"] = "displacement",
) -> tuple[LQRDesign, float]:
    """LQR whose R gives the best-damped loop *with* the transport delay.

    The thesis chose R "through simulation ... to produce a stable response" (§4.3.1). Here
    that choice is explicit: over ``r_grid`` (default 1e-3 ... 1e4, 8 per decade) the R whose
    delayed closed loop has the smallest spectral radius (the fastest-decaying slowest pole).
    Merely stable designs can have a closed-loop pole closer to the unit circle than the open
    loop and amplify disturbances near it. Raises ``ValueError`` if no R is stable.

    Parameters
    ----------
    mode : ModalParameters
        The mode.
    period_s, delay_s : float
        Command period and transport delay [s].
    q : numpy.ndarray
        (2, 2) state weight (thesis: diag(1, 0.001)).
    r_grid : array_like, optional
        Candidate R values.
    input : {"displacement", "force"}
        What the control input is.

    Returns
    -------
    design : LQRDesign
        The design with the chosen R.
    r : float
        The chosen R.
    """
    grid = np.logspace(-3, 4, 57) if r_grid is None else np.asarray(r_grid, float)
    if grid.ndim != 1 or grid.size == 0 or not np.all(np.isfinite(grid) & (grid > 0)):
        raise ValueError("r_grid must be a non-empty 1-D array of finite positive weights")
    steps = _delay_steps(delay_s, period_s, "round")
    best = None
    for r in grid:
        design = design_lqr(mode, period_s, q, [[r]], input=input)
        rho = spectral_radius(closed_loop_with_delay(design, steps))
        if rho < 1 and (best is None or rho < best[0]):
            best = (rho, design, float(r))
    if best is None:
        raise ValueError(
            f"no R in [{grid[0]:g}, {grid[-1]:g}] gives a stable loop with a {delay_s} s delay"
        )
    return best[1], best[2]


@dataclass(frozen=True)
class DelayAwareDesign:
    """LQR of the delay-augmented model: ``u_k = -K [x_k, v_k, u_{k-1}, ..., u_{k-d}]``.

    Attributes
    ----------
    gains
        (2 + d,) gains K.
    delay_steps
        d, the delay in command periods.
    period_s
        Command period [s].
    closed_loop
        The delayed closed-loop matrix.
    """

    gains: np.ndarray  #: (2 + d,)
    delay_steps: int
    period_s: float
    closed_loop: np.ndarray

    @property
    def spectral_radius(self) -> float:
        return spectral_radius(self.closed_loop)


def design_delay_aware_lqr(
    mode: ModalParameters,
    period_s: float = 0.004,
    delay_s: float = 0.032,
    q=THESIS_Q,
    r=THESIS_R,
    *,
    input: Literal["displacement", "force"] = "displacement",
    rounding: Literal["reject", "round"] = "reject",
) -> DelayAwareDesign:
    """Optimal state feedback for a plant whose input arrives ``delay_s`` late.

    The plant state is augmented with the ``d`` commands still in flight; LQR on that exact
    model (same Q on the plant state, same R) gives a controller that also feeds back its own
    command history — the discrete equivalent of a Smith predictor. It is stable by
    construction with the delay, unlike ``[w1, w2]`` designed without it. A beyond-thesis
    option: the thesis' controller is :func:`design_lqr`.

    Parameters
    ----------
    mode : ModalParameters
        The mode.
    period_s, delay_s : float
        Command period and transport delay [s].
    q : numpy.ndarray
        (2, 2) state weight (thesis: diag(1, 0.001)).
    r : numpy.ndarray
        (1, 1) control weight.
    input : {"displacement", "force"}
        What the control input is.
    rounding : {"reject", "round"}
        What to do with a delay that is not a whole number of periods.

    Returns
    -------
    DelayAwareDesign
        Gains on the augmented state and the closed loop.
    """
    q, r = _check_weights(q, r)
    d = _delay_steps(delay_s, period_s, rounding)
    a, b = continuous_model(mode, input=input)
    big_a, big_b = _delay_augmented(*discretize(a, b, period_s), d)
    n = big_a.shape[0]
    big_q = np.zeros((n, n))
    big_q[:2, :2] = q
    p = solve_dare(big_a, big_b, big_q + 1e-12 * np.eye(n), r)
    k = np.linalg.solve(r + big_b.T @ p @ big_b, big_b.T @ p @ big_a)[0]
    return DelayAwareDesign(k, d, period_s, big_a - big_b @ k[None, :])


@dataclass(frozen=True)
class LoopMargins:
    """Stability margins of the loop broken at the plant input, with the delay included.

    Every crossing is reported (a lightly damped plant can cross |L| = 1 more than once), like
    python-control's ``stability_margins(..., returnall=True)``.

    Attributes
    ----------
    gain_margins
        Factors at the -180° phase crossings.
    phase_crossovers_hz
        Frequencies of those crossings [Hz].
    phase_margins_deg
        Phase margins at the |L| = 1 crossings [deg], wrapped to (-180, 180].
    gain_crossovers_hz
        Frequencies of the |L| = 1 crossings [Hz].
    """

    gain_margins: np.ndarray  #: factors at the -180° phase crossings
    phase_crossovers_hz: np.ndarray
    phase_margins_deg: np.ndarray  #: at the |L| = 1 crossings, wrapped to (-180, 180]
    gain_crossovers_hz: np.ndarray


def loop_margins(design: LQRDesign, delay_steps: int = 0, n_points: int = 20000) -> LoopMargins:
    """Gain and phase margins of ``L(z) = W (zI - A_d)^-1 B_d z^-d`` on the unit circle.

    Evaluated on a dense frequency grid up to Nyquist with linear interpolation at the
    crossings (tested against python-control). A delay of d periods adds ``-w T d`` of phase:
    this is what limits the bandwidth of the pose-dependent controller (thesis §4.3.2).

    Parameters
    ----------
    design : LQRDesign
        The design.
    delay_steps : int
        Delay in command periods.
    n_points : int
        Frequency grid points up to Nyquist.

    Returns
    -------
    LoopMargins
        Every gain and phase crossing.
    """
    t = design.period_s
    w = np.linspace(1e-4, np.pi / t, int(n_points))
    z = np.exp(1j * w * t)
    n = design.ad.shape[0]
    lhs = z[:, None, None] * np.eye(n) - design.ad  # (m, n, n), one solve per frequency
    rhs = np.broadcast_to(design.bd[:, :1], (z.size, n, 1))
    resp = (np.linalg.solve(lhs, rhs)[:, :, 0] @ design.gains) * z ** (-int(delay_steps))
    mag = np.abs(resp)
    phase = np.unwrap(np.angle(resp))

    def interp(i, target, values):
        frac = (target - values[i]) / (values[i + 1] - values[i])
        return frac

    pms, wcs = [], []
    for i in np.flatnonzero(np.diff(np.sign(mag - 1.0)) != 0):
        frac = interp(i, 1.0, mag)
        ph = phase[i] + frac * (phase[i + 1] - phase[i])
        pms.append((np.degrees(ph) + 360.0) % 360.0 - 180.0)
        wcs.append(w[i] + frac * (w[i + 1] - w[i]))
    gms, wps = [], []
    turns = (phase + np.pi) / (2 * np.pi)  # integer values at -180° (mod 360°)
    for i in np.flatnonzero(np.diff(np.floor(turns)) != 0):
        target = max(np.floor(turns[i]), np.floor(turns[i + 1]))
        if i + 2 == turns.size and abs(turns[-1] - target) < 1e-9:
            # L is real at Nyquist: a phase of exactly -180° there is no crossing of the band
            # (rounding alone decides which side it falls on; python-control ignores it too).
            continue
        frac = interp(i, target, turns)
        gms.append(1.0 / (mag[i] + frac * (mag[i + 1] - mag[i])))
        wps.append(w[i] + frac * (w[i + 1] - w[i]))
    return LoopMargins(
        np.array(gms), np.array(wps) / (2 * np.pi), np.array(pms), np.array(wcs) / (2 * np.pi)
    )


def spectral_radius(matrix: np.ndarray) -> float:
    """Largest eigenvalue magnitude (< 1: the discrete loop is stable).

    The one definition every loop analysis of :mod:`robovib.control` uses.

    Parameters
    ----------
    matrix : numpy.ndarray
        Square matrix.

    Returns
    -------
    float
        max |eigenvalue|.

    Examples
    --------
    >>> import numpy as np
    >>> spectral_radius(np.array([[0.5, 1.0], [0.0, -0.9]]))
    0.9
    """
    return float(np.max(np.abs(np.linalg.eigvals(matrix))))


@dataclass(frozen=True)
class KalmanDesign:
    """Steady-state Kalman filter of one mode at the sensor rate (state [x, v]).

    ``phi`` (2, 2), ``gamma_u`` (2,) (applied correction [m] -> state), ``gain`` (2,) the
    filter gain ``L`` of the update ``x += L (y - x[0])``, ``p`` the a-priori covariance.

    Attributes
    ----------
    phi
        (2, 2) state transition over one sensor sample.
    gamma_u
        (2,) applied correction [m] -> state.
    gain
        (2,) filter gain ``L``.
    p
        (2, 2) a-priori covariance.
    """

    phi: np.ndarray
    gamma_u: np.ndarray
    gain: np.ndarray
    p: np.ndarray


def design_kalman(
    mode: ModalParameters,
    dt_s: float = 1e-3,
    *,
    force_std_n: float = 20.0,
    tracker_noise_m: float = 2e-6,
    tracker_resolution_m: float = 1e-5,
) -> KalmanDesign:
    """Kalman filter for ``[x, v]`` of ``mode`` from tracker samples every ``dt_s``.

    The unmeasured force is white process noise of std ``force_std_n`` [N] held over each
    sample; the tracker noise variance is ``tracker_noise_m**2 + tracker_resolution_m**2 / 12``
    (quantisation). The steady-state a-priori covariance solves the filter Riccati equation
    (DARE on the dual problem, :func:`robovib._linalg.solve_dare`; the same as python-control
    ``dlqe``, tested).

    Parameters
    ----------
    mode : ModalParameters
        The (model) mode.
    dt_s : float
        Sensor sample period [s].
    force_std_n : float
        Std of the unmeasured force [N] (process noise).
    tracker_noise_m, tracker_resolution_m : float
        Tracker white noise (std) and quantisation [m].

    Returns
    -------
    KalmanDesign
        The steady-state filter.
    """
    a, bu = continuous_model(mode, input="displacement")
    _, bf = continuous_model(mode, input="force")
    phi, gu = discretize(a, bu, dt_s)
    _, gf = discretize(a, bf, dt_s)
    qn = (gf @ gf.T) * force_std_n**2
    rn = np.array([[tracker_noise_m**2 + tracker_resolution_m**2 / 12.0]])
    c = np.array([[1.0, 0.0]])
    p = solve_dare(phi.T, c.T, qn, rn)
    gain = (p @ c.T @ np.linalg.inv(c @ p @ c.T + rn))[:, 0]
    return KalmanDesign(phi, gu[:, 0], gain, p)
