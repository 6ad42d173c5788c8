"""A family of virtual robots robovib has never seen: seeded draws that change the physics.

The thesis robot (:class:`~robovib.sim.VirtualRobot` with no seed) is one member of a family.
:func:`draw_robot` draws the physical parameters of another member from a seed (this module: the
distributions), and ``VirtualRobot.variant(seed)`` builds that robot
(:class:`robovib.sim.truth.VariantWorkspaceTruth`, :class:`~robovib.sim.truth.VariantPathTruth`),
so a method tuned on the thesis robot can be checked on robots it has never seen (issue 36).
Every draw keeps the thesis robot's *structure* (a dominant mode per direction that varies
smoothly with pose, a weak secondary mode per direction, an X mode that takes over in a region
of the workspace) and changes its *physics*:

**Joint stiffness and masses** (the analytical model of thesis §3.4, Eq. 11-16). Each joint
stiffness is scaled by a lognormal factor ``exp(0.25 z)``, ``z ~ N(0, 1)`` truncated at
``|z| <= 2`` (x0.61-1.65); each arm link's mass by ``exp(0.15 z)`` (same truncation) and the
spindle+tool mass by a log-uniform factor in [0.7, 1.5]. Through the kinematic model
(:class:`~robovib.robot.KR500`, inverse kinematics at each ``(x, y)`` with the tool axis
vertical) this gives, per pose and direction, the ratio ``r_k`` of the directional stiffness
``1 / (J K_theta^-1 J^T)_dd`` and the ratio ``r_m`` of the apparent mass
``1 / (J_v M_q^-1 J_v^T)_dd`` of the variant to the nominal model. The dominant mode's
stiffness becomes ``k r_k`` and its frequency ``fn sqrt(r_k / r_m)``: which joint dominates
the compliance changes over the workspace, so the pose dependence changes, not only the level.
The ratios are computed on a 7 x 7 grid of ``(x, y)`` and interpolated (cubic in log).

**Damping.** The dominant modes' damping ratios (9-22 % in Table A1) are scaled per direction
by a log-uniform factor in [0.6, 1.4]; the secondary and the switching X mode draw their
damping ratio log-uniformly in [1 %, 8 %].

**Tool orientation.** An asymmetric spindle head: X stiffness x ``exp(a cos 2(Rz - phi))`` and
Y stiffness x ``exp(-a cos 2(Rz - phi))`` with ``a ~ U(0, 0.15)``, ``phi ~ U(0, 180)`` deg.

**Secondary modes**, one per direction: fn = ``U(2.0, 3.0)`` x the dominant fn, and a peak
compliance ``1 / (2 zeta k)`` log-uniform in [0.1, 0.5] x the dominant mode's (at its median
damping ratio over the workspace; a constant stiffness factor on the dominant stiffness). The
thesis robot: 2.6, a factor 10 and 5 %, peaks 0.2-0.4 x the dominant.

**The mode switch.** With probability 0.8 the robot has an X mode that takes over in a region:
modal stiffness ``k_high / w``, ``w = w0 + (1 - w0) s(pose)``,
``s = logistic((x - x_s) / width) |cos(Rz - Rz_s)|^p`` with ``x_s ~ U(2.40, 2.64)`` m,
``width ~ U(0.01, 0.03)`` m, ``Rz_s ~ U(0, 180)`` deg, ``p`` one of 4, 6, 8, 10, and the floor
``w0 ~ U(0.05, 0.2)``. Its frequency is log-uniform between ``max(1.8 f_max, 45)`` and
``min(3.2 f_max, 100)`` Hz, ``f_max`` the highest dominant X frequency over the workspace (the
thesis robot: 63.5 Hz, 2.8 f_max); ``k_high`` puts its peak compliance at ``w = 1`` at
``U(1.1, 1.8)`` x the largest peak compliance of the dominant X mode, so it dominates wherever
``s`` is near 1. Without a switch (probability 0.2) the mode is present at the floor weight
everywhere: a weak secondary mode that never dominates.

**The path** (chapters 4-5) takes the same changes, with the stiffness and mass ratios of the
joint model as their geometric means over the workspace (the path's poses are not modelled
kinematically).

Every robot is checked at construction
(:meth:`robovib.sim.truth.VariantWorkspaceTruth.check_physics`) on a grid of the workspace and
along the path: finite, positive stiffness, natural frequencies within :data:`PLAUSIBLE_FN_HZ`,
damping ratios within :data:`PLAUSIBLE_DAMPING_RATIO`, each secondary mode above its dominant
mode in frequency and below it in peak compliance, the switching X mode above the dominant X
mode, and a switch region that exists (dominant somewhere, not over
most of the workspace) exactly when the draw says so; anything else raises ``ValueError``.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

__all__ = [
    "PLAUSIBLE_DAMPING_RATIO",
    "PLAUSIBLE_FN_HZ",
    "RobotDraw",
    "draw_robot",
    "tooth_passing_speeds_rpm",
]

#: Natural frequencies a heavy machining robot's tool tip plausibly has [Hz].
PLAUSIBLE_FN_HZ = (5.0, 120.0)
#: Plausible modal damping ratios (the thesis robot's dominant modes reach 22 %).
PLAUSIBLE_DAMPING_RATIO = (0.005, 0.35)
_SWITCH_PROBABILITY = 0.8


def _truncated_lognormal(gen: np.random.Generator, sigma: float, size: int) -> np.ndarray:
    z = gen.standard_normal(size)
    while np.any(bad := np.abs(z) > 2.0):  # rejection: the truncated normal, exactly
        z[bad] = gen.standard_normal(int(bad.sum()))
    return np.exp(sigma * z)


def _log_uniform(gen: np.random.Generator, lo: float, hi: float, size=None):
    return np.exp(gen.uniform(np.log(lo), np.log(hi), size))


@dataclass(frozen=True)
class RobotDraw:
    """The physical parameters of one member of the robot family (see the module docstring).

    Per-direction tuples are ordered X, Y, Z.

    Attributes
    ----------
    seed
        The seed it was drawn from.
    joint_stiffness_scale
        (6,) factors on the joint stiffnesses A1-A6.
    link_mass_scale
        (6,) factors on the link masses (the last: flange + spindle + tool).
    damping_scale
        (3,) factors on the dominant modes' damping ratios.
    orientation_amplitude, orientation_phase_deg
        ``a`` and ``phi`` of the Rz dependence of the X/Y stiffness.
    secondary_fn_factor, secondary_peak_ratio, secondary_damping_ratio
        (3,) the secondary mode's frequency and peak compliance relative to the dominant
        mode's, and its damping ratio.
    switch
        Whether the X mode takes over in a region.
    switch_x_m, switch_width_m, switch_rz_deg, switch_power
        ``x_s``, ``width``, ``Rz_s`` and ``p`` of the switch weight ``s``.
    high_floor_weight
        ``w0``: the switching mode's weight away from its region.
    high_fn_quantile, high_dominance
        Where the switching mode's frequency lies in its log-uniform range (0-1), and its peak
        compliance at ``w = 1`` relative to the dominant X mode's largest.
    high_damping_ratio
        Its damping ratio.
    """

    seed: int
    joint_stiffness_scale: tuple[float, ...]
    link_mass_scale: tuple[float, ...]
    damping_scale: tuple[float, float, float]
    orientation_amplitude: float
    orientation_phase_deg: float
    secondary_fn_factor: tuple[float, float, float]
    secondary_peak_ratio: tuple[float, float, float]
    secondary_damping_ratio: tuple[float, float, float]
    switch: bool
    switch_x_m: float
    switch_width_m: float
    switch_rz_deg: float
    switch_power: int
    high_floor_weight: float
    high_fn_quantile: float
    high_dominance: float
    high_damping_ratio: float

    def __post_init__(self) -> None:
        sizes = {"joint_stiffness_scale": 6, "link_mass_scale": 6, "damping_scale": 3,
                 "secondary_fn_factor": 3, "secondary_peak_ratio": 3}  # fmt: skip
        for name, size in sizes.items():
            v = np.asarray(getattr(self, name), float)
            if v.shape != (size,) or not np.all(np.isfinite(v)) or np.any(v <= 0):
                raise ValueError(
                    f"robot draw: {name} must be {size} positive finite factors, got {v}"
                )
        lo, hi = PLAUSIBLE_DAMPING_RATIO
        for name in ("secondary_damping_ratio", "high_damping_ratio"):
            v = np.atleast_1d(np.asarray(getattr(self, name), float))
            if not np.all((v >= lo) & (v <= hi)):
                raise ValueError(f"robot draw: {name} must lie in [{lo:g}, {hi:g}], got {v}")
        if not (self.switch_width_m > 0 and 0 < self.high_floor_weight <= 1
                and 0 <= self.high_fn_quantile <= 1 and self.high_dominance > 0
                and self.switch_power > 0):  # fmt: skip
            raise ValueError(
                "robot draw: the switch needs width > 0, 0 < floor weight <= 1, a frequency "
                "quantile in [0, 1], dominance > 0 and power > 0"
            )

    def to_dict(self) -> dict:
        """The draw as plain JSON types.

        Returns
        -------
        dict
            Field name -> value (tuples as lists).
        """
        return {k: list(v) if isinstance(v, tuple) else v for k, v in asdict(self).items()}


def draw_robot(seed: int) -> RobotDraw:
    """Draw one robot of the family from ``seed`` (the distributions: module docstring).

    Parameters
    ----------
    seed : int
        A non-negative integer; the same seed gives the same robot.

    Returns
    -------
    RobotDraw
        The physical parameters.

    Raises
    ------
    ValueError
        A seed that is not a non-negative integer.

    Examples
    --------
    >>> from robovib.sim.family import draw_robot
    >>> draw_robot(3) == draw_robot(3)
    True
    """
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer) or seed < 0:
        raise ValueError(f"the robot seed must be a non-negative integer, got {seed!r}")
    gen = np.random.default_rng([int(seed), 0x0B07])  # its own stream: not the study's rng
    tup = lambda a: tuple(float(v) for v in a)  # noqa: E731
    links = np.append(_truncated_lognormal(gen, 0.15, 5), _log_uniform(gen, 0.7, 1.5))
    return RobotDraw(
        seed=int(seed),
        joint_stiffness_scale=tup(_truncated_lognormal(gen, 0.25, 6)),
        link_mass_scale=tup(links),
        damping_scale=tup(_log_uniform(gen, 0.6, 1.4, 3)),
        orientation_amplitude=float(gen.uniform(0.0, 0.15)),
        orientation_phase_deg=float(gen.uniform(0.0, 180.0)),
        secondary_fn_factor=tup(gen.uniform(2.0, 3.0, 3)),
        secondary_peak_ratio=tup(_log_uniform(gen, 0.1, 0.5, 3)),
        secondary_damping_ratio=tup(_log_uniform(gen, 0.01, 0.08, 3)),
        switch=bool(gen.uniform() < _SWITCH_PROBABILITY),
        switch_x_m=float(gen.uniform(2.40, 2.64)),
        switch_width_m=float(gen.uniform(0.01, 0.03)),
        switch_rz_deg=float(gen.uniform(0.0, 180.0)),
        switch_power=int(gen.choice([4, 6, 8, 10])),
        high_floor_weight=float(gen.uniform(0.05, 0.2)),
        high_fn_quantile=float(gen.uniform()),
        high_dominance=float(gen.uniform(1.1, 1.8)),
        high_damping_ratio=float(_log_uniform(gen, 0.01, 0.08)),
    )


def tooth_passing_speeds_rpm(robot, coords, n_flutes: int = 2) -> dict[str, float]:
    """Spindle speeds whose tooth-passing frequency sits on the robot's X modes at ``coords``.

    Parameters
    ----------
    robot : VirtualRobot
        The robot (the thesis robot or a variant).
    coords : array_like
        (n, 3) workspace poses ``(x_m, y_m, rz_deg)``; the median frequency over them is used.
    n_flutes : int
        Flutes (teeth) of the tool.

    Returns
    -------
    dict
        ``{"x secondary": rpm, "x switching": rpm}``: 60 fn / n_flutes of the X secondary mode
        (median over the poses) and of the switching X mode.
    """
    if int(n_flutes) < 1:
        raise ValueError(f"n_flutes must be >= 1, got {n_flutes}")
    m = robot.workspace.modes(coords, "x")
    fn = np.median(m.fn_hz, axis=0)
    return {
        "x secondary": float(60 * fn[1] / n_flutes),
        "x switching": float(60 * fn[2] / n_flutes),
    }
