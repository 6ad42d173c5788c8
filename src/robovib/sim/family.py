"""A family of virtual robots robovib has never seen: seeded draws that change the physics.

The thesis robot (:class:`~robovib.sim.VirtualRobot` with no seed) is one member of a family.
:func:`draw_robot` draws the physical parameters of another member from a seed, and
``VirtualRobot.variant(seed)`` builds that robot, so a method tuned on the thesis robot can be
checked on robots it has never seen (issue 36). Every draw keeps the thesis robot's *structure*
(a dominant mode per direction that varies smoothly with pose, a weak secondary mode per
direction, an X mode that takes over in a region of the workspace) and changes its *physics*:

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

Every robot is checked at construction (:meth:`VariantWorkspaceTruth.check_physics`) on a grid
of the workspace and the path: finite, positive stiffness, natural frequencies within
:data:`PLAUSIBLE_FN_HZ`, damping ratios within :data:`PLAUSIBLE_DAMPING_RATIO`, each secondary
mode above its dominant mode, and a switch region that exists (dominant somewhere, not over
most of the workspace) exactly when the draw says so; anything else raises ``ValueError``.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, replace

import numpy as np
from scipy.interpolate import RegularGridInterpolator

from .truth import DIRECTIONS, WORKSPACE_BOUNDS, ModeSet, PathTruth, WorkspaceTruth

__all__ = [
    "PLAUSIBLE_DAMPING_RATIO",
    "PLAUSIBLE_FN_HZ",
    "RobotDraw",
    "VariantPathTruth",
    "VariantWorkspaceTruth",
    "draw_robot",
    "tooth_passing_speeds_rpm",
]

#: Natural frequencies a heavy machining robot's tool tip plausibly has [Hz].
PLAUSIBLE_FN_HZ = (5.0, 120.0)
#: Plausible modal damping ratios (the thesis robot's dominant modes reach 22 %).
PLAUSIBLE_DAMPING_RATIO = (0.005, 0.35)
_Z_M = 0.325
_GRID_N = 7
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


def _joint_model_ratios(draw: RobotDraw):
    """log r_k, log r_m (3, 7, 7) on the (x, y) grid, and the grid axes."""
    from ..robot import KR500, tool_down_orientation
    from ..robot.dynamics import LINK_SOLIDS, TABLE_4_JOINT_STIFFNESS, joint_space_inertia

    robot = KR500()
    k_nominal = TABLE_4_JOINT_STIFFNESS
    k_variant = k_nominal * np.asarray(draw.joint_stiffness_scale)
    links = tuple(
        replace(link, mass_kg=link.mass_kg * f)
        for link, f in zip(LINK_SOLIDS, draw.link_mass_scale, strict=True)
    )
    xs = np.linspace(*WORKSPACE_BOUNDS[0], _GRID_N)
    ys = np.linspace(*WORKSPACE_BOUNDS[1], _GRID_N)
    log_rk = np.empty((3, _GRID_N, _GRID_N))
    log_rm = np.empty((3, _GRID_N, _GRID_N))
    ref = np.array([0.0, -30.0, 70.0, 0.0, 50.0, 0.0])
    for i, x in enumerate(xs):
        for j, y in enumerate(ys):
            q = robot.ik(np.array([x, y, _Z_M]), tool_down_orientation(0.0), reference_deg=ref)
            jac = robot.jacobian(q)
            jv = jac[:3]
            # directional compliance (J K^-1 J^T)_dd and inverse apparent mass (Jv Mq^-1 Jv^T)_dd
            c_nom = np.diag(jac @ np.diag(1 / k_nominal) @ jac.T)[:3]
            c_var = np.diag(jac @ np.diag(1 / k_variant) @ jac.T)[:3]
            mi_nom = np.diag(jv @ np.linalg.solve(joint_space_inertia(robot, q), jv.T))
            mi_var = np.diag(jv @ np.linalg.solve(joint_space_inertia(robot, q, links), jv.T))
            log_rk[:, i, j] = np.log(c_nom / c_var)
            log_rm[:, i, j] = np.log(mi_nom / mi_var)
    return xs, ys, log_rk, log_rm


class VariantWorkspaceTruth(WorkspaceTruth):
    """The chapter-3 workspace truth of one drawn robot (see the module docstring).

    Parameters
    ----------
    draw : RobotDraw
        The robot's physical parameters.

    Raises
    ------
    ValueError
        The drawn robot is not physical (:meth:`check_physics`).
    """

    def __init__(self, draw: RobotDraw) -> None:
        super().__init__()
        self.draw = draw
        xs, ys, log_rk, log_rm = _joint_model_ratios(draw)
        grid = (xs, ys)
        self._log_rk = [RegularGridInterpolator(grid, log_rk[i], method="cubic", bounds_error=False,
                                                fill_value=None) for i in range(3)]  # fmt: skip
        self._log_rm = [RegularGridInterpolator(grid, log_rm[i], method="cubic", bounds_error=False,
                                                fill_value=None) for i in range(3)]  # fmt: skip
        #: Geometric means of the joint model's stiffness and mass ratios (X, Y, Z).
        self.mean_stiffness_ratio = np.exp(log_rk.mean(axis=(1, 2)))
        self.mean_mass_ratio = np.exp(log_rm.mean(axis=(1, 2)))
        grid3 = self.check_grid()
        #: (3,) X, Y, Z stiffness factors of the secondary modes on the dominant ones.
        self.secondary_stiffness_factor = _secondary_factors(
            draw, [self._low_mode(grid3, d)[2] for d in DIRECTIONS]
        )
        fn_x, k_x, zeta_x = self._low_mode(grid3, "x")
        f_max = float(fn_x.max())
        lo, hi = max(1.8 * f_max, 45.0), min(3.2 * f_max, 100.0)
        if lo >= hi:
            raise ValueError(
                f"robot seed {draw.seed}: the dominant X mode reaches {f_max:.1f} Hz, leaving no "
                "room for a switching mode below 100 Hz"
            )
        self.high_fn_hz = float(np.exp(np.log(lo) + draw.high_fn_quantile * np.log(hi / lo)))
        self.high_damping_ratio = draw.high_damping_ratio
        largest_peak = float(np.max(1.0 / (2 * zeta_x * k_x)))
        self.high_stiffness_n_per_m = 1.0 / (
            2 * self.high_damping_ratio * draw.high_dominance * largest_peak
        )
        self.check_physics()

    @staticmethod
    def check_grid() -> np.ndarray:
        """(n, 3) poses ``(x_m, y_m, rz_deg)`` on which a robot is checked: 9 x 9 x 19.

        Returns
        -------
        numpy.ndarray
            The grid poses.
        """
        axes = [
            np.linspace(lo, hi, n) for (lo, hi), n in zip(WORKSPACE_BOUNDS, (9, 9, 19), strict=True)
        ]
        return np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)

    def _low_mode(self, c: np.ndarray, direction: str):
        fn, k, zeta = super()._low_mode(c, direction)
        i = DIRECTIONS.index(direction)
        xy = c[:, :2]
        log_rk = self._log_rk[i](xy)
        if direction in ("x", "y"):
            sign = 1.0 if direction == "x" else -1.0
            phase = np.radians(2 * (c[:, 2] - self.draw.orientation_phase_deg))
            log_rk = log_rk + sign * self.draw.orientation_amplitude * np.cos(phase)
        rk, rm = np.exp(log_rk), np.exp(self._log_rm[i](xy))
        return fn * np.sqrt(rk / rm), k * rk, zeta * self.draw.damping_scale[i]

    def switch_weight(self, coords) -> np.ndarray:
        """s(pose) in [0, 1]: how strongly the switching X mode is excited (0 without a switch).

        Parameters
        ----------
        coords : array_like
            (n, 3) poses ``(x_m, y_m, rz_deg)``.

        Returns
        -------
        numpy.ndarray
            (n,) weights in [0, 1].
        """
        c = np.atleast_2d(np.asarray(coords, float))
        d = self.draw
        if not d.switch:
            return np.zeros(len(c))
        along = 1.0 / (1.0 + np.exp(-(c[:, 0] - d.switch_x_m) / d.switch_width_m))
        return along * np.abs(np.cos(np.radians(c[:, 2] - d.switch_rz_deg))) ** d.switch_power

    def modes(self, coords, direction: str, *, allow_extrapolation: bool = False) -> ModeSet:
        """All modes of ``direction`` at the poses ``coords`` (n, 3).

        Parameters
        ----------
        coords : array_like
            (n, 3) poses ``(x_m, y_m, rz_deg)``.
        direction : {"x", "y", "z"}
            Direction.
        allow_extrapolation : bool
            Allow poses outside the workspace.

        Returns
        -------
        ModeSet
            Dominant, secondary (and in X the switching) modes per pose.
        """
        if direction not in DIRECTIONS:
            raise ValueError(f"unknown direction {direction!r}; expected x, y or z")
        c = self.check_coords(coords, allow_extrapolation)
        fn, k, zeta = self._low_mode(c, direction)
        i = DIRECTIONS.index(direction)
        d = self.draw
        fns = np.column_stack([fn, d.secondary_fn_factor[i] * fn])
        ks = np.column_stack([k, self.secondary_stiffness_factor[i] * k])
        zetas = np.column_stack([zeta, np.full_like(zeta, d.secondary_damping_ratio[i])])
        if direction == "x":
            weight = d.high_floor_weight + (1 - d.high_floor_weight) * self.switch_weight(c)
            fns = np.column_stack([fns, np.full(len(c), self.high_fn_hz)])
            ks = np.column_stack([ks, self.high_stiffness_n_per_m / weight])
            zetas = np.column_stack([zetas, np.full(len(c), self.high_damping_ratio)])
        return ModeSet(fns, ks, zetas)

    def check_physics(self) -> None:
        """Raise ``ValueError`` if the robot is not physical on :meth:`check_grid`.

        Checked: finite values, positive stiffness, fn in :data:`PLAUSIBLE_FN_HZ`, damping
        ratios in :data:`PLAUSIBLE_DAMPING_RATIO`, each secondary mode above its dominant
        mode, the switching X mode above the dominant X mode; with a switch, the switching mode
        dominant at some but under half of the grid poses; without one, nowhere.

        Raises
        ------
        ValueError
            Naming the seed, the direction and the quantity out of range.
        """
        _check_modes(
            self.draw.seed, "workspace", {d: self.modes(self.check_grid(), d) for d in DIRECTIONS}
        )
        x = self.modes(self.check_grid(), "x")
        if np.any(x.fn_hz[:, 2] <= 1.3 * x.fn_hz[:, 0]):
            raise ValueError(
                f"robot seed {self.draw.seed}: the switching X mode is not above the dominant X mode"
            )
        share = float(np.mean(np.argmax(x.peak_compliance(), axis=1) == 2))
        if self.draw.switch and not 0.0 < share < 0.5:
            raise ValueError(
                f"robot seed {self.draw.seed}: the switching X mode dominates {100 * share:.0f} % "
                "of the workspace (a switch region needs 0 < share < 50 %)"
            )
        if not self.draw.switch and share > 0:
            raise ValueError(f"robot seed {self.draw.seed}: a robot without a switch has one")

    def switch_share(self) -> float:
        """The share of :meth:`check_grid` poses where the switching X mode dominates.

        Returns
        -------
        float
            In [0, 1).
        """
        x = self.modes(self.check_grid(), "x")
        return float(np.mean(np.argmax(x.peak_compliance(), axis=1) == 2))


def _secondary_factors(draw: RobotDraw, dominant_damping) -> np.ndarray:
    """Stiffness factors k2 / k putting each secondary peak at its drawn ratio (median zeta)."""
    zeta = np.array([np.median(z) for z in dominant_damping])
    return zeta / (np.asarray(draw.secondary_damping_ratio) * np.asarray(draw.secondary_peak_ratio))


def _check_modes(seed: int, where: str, modes: dict[str, ModeSet]) -> None:
    lo_f, hi_f = PLAUSIBLE_FN_HZ
    lo_z, hi_z = PLAUSIBLE_DAMPING_RATIO
    for d, m in modes.items():
        for name, a in (
            ("fn", m.fn_hz),
            ("stiffness", m.stiffness_n_per_m),
            ("damping ratio", m.damping_ratio),
        ):
            if not np.all(np.isfinite(a)):
                raise ValueError(f"robot seed {seed}: non-finite {name} in {d} ({where})")
        if np.any(m.stiffness_n_per_m <= 0):
            raise ValueError(f"robot seed {seed}: non-positive stiffness in {d} ({where})")
        if np.any((m.fn_hz < lo_f) | (m.fn_hz > hi_f)):
            raise ValueError(
                f"robot seed {seed}: {d} natural frequencies {m.fn_hz.min():.1f}-{m.fn_hz.max():.1f} Hz "
                f"leave the plausible {lo_f:g}-{hi_f:g} Hz ({where})"
            )
        if np.any((m.damping_ratio < lo_z) | (m.damping_ratio > hi_z)):
            raise ValueError(
                f"robot seed {seed}: {d} damping ratios {m.damping_ratio.min():.3f}-"
                f"{m.damping_ratio.max():.3f} leave the plausible {lo_z:g}-{hi_z:g} ({where})"
            )
        peaks = m.peak_compliance()
        if np.any(peaks[:, 1] >= 0.9 * peaks[:, 0]):
            raise ValueError(
                f"robot seed {seed}: the {d} secondary mode's peak reaches the dominant one's ({where})"
            )
        if np.any(m.fn_hz[:, 1] <= m.fn_hz[:, 0]):
            raise ValueError(
                f"robot seed {seed}: the {d} secondary mode is not above the dominant one ({where})"
            )


class VariantPathTruth(PathTruth):
    """The chapter-4/5 path truth of one drawn robot (see the module docstring).

    Parameters
    ----------
    draw : RobotDraw
        The robot's physical parameters.
    stiffness_ratio, mass_ratio : array_like
        (3,) X, Y, Z ratios of the joint model (the workspace's geometric means).
    """

    def __init__(self, draw: RobotDraw, stiffness_ratio, mass_ratio) -> None:
        super().__init__()
        self.draw = draw
        self._rk = np.asarray(stiffness_ratio, float)
        self._rm = np.asarray(mass_ratio, float)
        s = np.linspace(0.0, 1.235, 50)
        self.secondary_stiffness_factor = _secondary_factors(
            draw, [super(VariantPathTruth, self).modes(s, d).damping_ratio[:, 0] * draw.damping_scale[i]
                   for i, d in enumerate(DIRECTIONS)]
        )  # fmt: skip
        _check_modes(draw.seed, "path", {d: self.modes(s, d) for d in DIRECTIONS})

    def modes(self, s_m, direction: str, *, allow_extrapolation: bool = False) -> ModeSet:
        """All modes of ``direction`` at path coordinates ``s_m`` [m].

        Parameters
        ----------
        s_m : array_like
            (n,) distances along the path [m].
        direction : {"x", "y", "z"}
            Direction.
        allow_extrapolation : bool
            Allow coordinates outside the path.

        Returns
        -------
        ModeSet
            Dominant and secondary mode per coordinate.
        """
        base = super().modes(s_m, direction, allow_extrapolation=allow_extrapolation)
        i = DIRECTIONS.index(direction)
        d = self.draw
        fn = base.fn_hz[:, 0] * np.sqrt(self._rk[i] / self._rm[i])
        k = base.stiffness_n_per_m[:, 0] * self._rk[i]
        zeta = base.damping_ratio[:, 0] * d.damping_scale[i]
        return ModeSet(
            np.column_stack([fn, d.secondary_fn_factor[i] * fn]),
            np.column_stack([k, self.secondary_stiffness_factor[i] * k]),
            np.column_stack([zeta, np.full_like(zeta, d.secondary_damping_ratio[i])]),
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
