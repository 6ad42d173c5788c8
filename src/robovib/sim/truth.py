"""Ground truth of the virtual robot: pose -> modes (fn, k, zeta) per direction.

This is a *plausible synthetic robot* built to reproduce the thesis' measured trends, not a
claim about the real KR500-3. It has two documented pose domains:

**Workspace** (chapter 3; X 2100-2700 mm, Y -300-600 mm, Rz 0-180°, Z = 325 mm, tool axis
vertical). Coordinates ``(x_m, y_m, rz_deg)``.

* Dominant ("low") mode per direction: thin-plate-spline fields
  (:class:`scipy.interpolate.RBFInterpolator`, smoothing 1e-3 on scaled inputs) fitted to the
  Table A1 *pose means* of fn, k, c (corrected stiffness reading; the X fields leave out the
  poses where the ~63 Hz mode dominates). Smooth in pose, so a moving robot sees time-varying
  dynamics.
* X-direction "high" mode, always present: fn, k and damping coefficient from the means of the
  Table A1 rows where it dominates (61.9-64.5 Hz, ~4.3 MN/m, ~1.2 kN·s/m). Its modal stiffness
  is ``k_high / w`` with the weight ``w = 0.1 + 0.9 s(pose)``,
  ``s = logistic((x - 2.62 m) / 0.02 m) * cos(Rz)^8``: near 1 at full extension with
  Rz = 0°/180° (where it out-peaks the low mode and becomes dominant, as in Table A1) and ~0
  elsewhere, where it is a weak secondary mode (Table A2 at X = 2550 mm shows none).
* A weak secondary mode in every direction: fn x 2.6, k x 10, zeta = 0.05 of the low mode

**Path** (chapters 4-5): the 1.235 m linear path in -Y from the Table 5 start (arm retracted)
to its end (arm extended). Coordinate: distance ``s_m`` from the start. Dominant modes follow
monotone cubic (PCHIP) curves through anchors: Table 8's *measured* Position 1/2 values for X
and Z, placed at s = 0.35 m (Position 1) and s = 1.00 m (Position 2) — an assumption, the
thesis gives those poses only in a figure — and end values extrapolated along the §4.2.2
trends (X, Z stiffness and fn fall with extension, Y stiffness rises, damping ratio
nonlinear); Y's dominant mode near 22.9 Hz as in §5.4.1. Secondary modes as above.

**Other robots** (``VirtualRobot.variant(seed)``): :class:`VariantWorkspaceTruth` and
:class:`VariantPathTruth` change this robot's physics by a draw of :mod:`robovib.sim.family`
(joint stiffness and masses through the analytical model, damping, tool orientation, the
secondary modes, the switch region); the distributions are documented there.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import ClassVar

import numpy as np
from scipy.interpolate import PchipInterpolator, RBFInterpolator, RegularGridInterpolator

from ..datasets import load_table_a1
from ..modal.parameters import ModalParameters
from .family import PLAUSIBLE_DAMPING_RATIO, PLAUSIBLE_FN_HZ, RobotDraw, draw_robot

__all__ = [
    "PATH_LENGTH_M",
    "POSITION_1_S_M",
    "POSITION_2_S_M",
    "WORKSPACE_BOUNDS",
    "ModeSet",
    "PathTruth",
    "VariantPathTruth",
    "VariantWorkspaceTruth",
    "VirtualRobot",
    "WorkspaceTruth",
]

DIRECTIONS = ("x", "y", "z")
#: (min, max) of x_m, y_m, rz_deg of the chapter-3 workspace.
WORKSPACE_BOUNDS = ((2.1, 2.7), (-0.3, 0.6), (0.0, 180.0))
PATH_LENGTH_M = 1.235
POSITION_1_S_M = 0.35
POSITION_2_S_M = 1.00
_SECONDARY = (2.6, 10.0, 0.05)  # fn factor, k factor, zeta


@dataclass(frozen=True)
class ModeSet:
    """Modes of one direction at n poses: arrays (n, n_modes) of fn [Hz], k [N/m], zeta.

    Attributes
    ----------
    fn_hz
        (n, n_modes) natural frequencies [Hz].
    stiffness_n_per_m
        (n, n_modes) modal stiffnesses [N/m].
    damping_ratio
        (n, n_modes) damping ratios.
    """

    fn_hz: np.ndarray
    stiffness_n_per_m: np.ndarray
    damping_ratio: np.ndarray

    @property
    def n_modes(self) -> int:
        return self.fn_hz.shape[-1]

    def mass_kg(self) -> np.ndarray:
        return self.stiffness_n_per_m / (2 * np.pi * self.fn_hz) ** 2

    def damping_ns_per_m(self) -> np.ndarray:
        return 2 * self.damping_ratio * self.stiffness_n_per_m / (2 * np.pi * self.fn_hz)

    def peak_compliance(self) -> np.ndarray:
        """1 / (2 zeta k) per mode (n, n_modes): the height of each resonance peak.

        Returns
        -------
        numpy.ndarray
            (n, n_modes) peak compliance [m/N].
        """
        return 1.0 / (2 * self.damping_ratio * self.stiffness_n_per_m)

    def dominant(self) -> ModeSet:
        """The mode with the largest peak compliance at each pose, as (n, 1) arrays.

        Returns
        -------
        ModeSet
            One mode per pose.
        """
        idx = np.argmax(self.peak_compliance(), axis=1)[:, None]
        take = lambda a: np.take_along_axis(a, idx, axis=1)  # noqa: E731
        return ModeSet(take(self.fn_hz), take(self.stiffness_n_per_m), take(self.damping_ratio))

    def at(self, i: int) -> list[ModalParameters]:
        return [
            ModalParameters(float(f), float(k), float(z))
            for f, k, z in zip(
                self.fn_hz[i], self.stiffness_n_per_m[i], self.damping_ratio[i], strict=True
            )
        ]

    def compliance(self, frequency_hz) -> np.ndarray:
        """Receptance (n, n_f) of the sum of the modes.

        Parameters
        ----------
        frequency_hz : array_like
            (n_f,) frequencies [Hz].

        Returns
        -------
        numpy.ndarray
            (n, n_f) complex compliance [m/N].
        """
        r = np.asarray(frequency_hz, float)[None, None, :] / self.fn_hz[:, :, None]
        terms = 1.0 / (
            self.stiffness_n_per_m[:, :, None]
            * (1 - r**2 + 2j * self.damping_ratio[:, :, None] * r)
        )
        return terms.sum(axis=1)


def _with_secondary(fn, k, zeta):
    f2, k2, z2 = _SECONDARY
    return (
        np.column_stack([fn, f2 * fn]),
        np.column_stack([k, k2 * k]),
        np.column_stack([zeta, np.full_like(zeta, z2)]),
    )


class WorkspaceTruth:
    """Modes over the chapter-3 workspace, coordinates ``(x_m, y_m, rz_deg)`` (see module docs)."""

    def __init__(self) -> None:
        a1 = load_table_a1(units="si")
        cols = [c for c in a1.columns if c.startswith(("fn_", "stiffness_", "damping_"))]
        means = a1.groupby("test")[["x_m", "y_m", "rz_deg", "x_high_mode", *cols]].mean()
        high = means["x_high_mode"] > 0.5
        self._fields = {}
        for d in DIRECTIONS:
            sel = ~high if d == "x" else np.ones(len(means), bool)
            coords = self._scaled(means.loc[sel, ["x_m", "y_m", "rz_deg"]].to_numpy())
            for q in ("fn", "stiffness", "damping"):
                col = next(c for c in cols if c.startswith(f"{q}_{d}_"))
                vals = means.loc[sel, col].to_numpy()
                ok = np.isfinite(vals)
                self._fields[(d, q)] = RBFInterpolator(
                    coords[ok], np.log(vals[ok]), kernel="thin_plate_spline", smoothing=1e-3
                )
        hm = means.loc[high]
        self.high_fn_hz = float(hm["fn_x_hz"].mean())
        self.high_stiffness_n_per_m = float(np.nanmean(hm["stiffness_x_n_per_m"]))
        high_c = float(hm["damping_x_ns_per_m"].mean())
        self.high_damping_ratio = (
            high_c * 2 * np.pi * self.high_fn_hz / (2 * self.high_stiffness_n_per_m)
        )

    @staticmethod
    def _scaled(coords: np.ndarray) -> np.ndarray:
        return (coords - np.array([2.4, 0.15, 90.0])) / np.array([0.3, 0.45, 90.0])

    @staticmethod
    def check_coords(coords, allow_extrapolation: bool = False) -> np.ndarray:
        c = np.atleast_2d(np.asarray(coords, float))
        if c.ndim != 2 or c.shape[1] != 3:
            raise ValueError(
                f"workspace coordinates must be (n, 3) = (x_m, y_m, rz_deg), got shape {c.shape}"
            )
        if not np.all(np.isfinite(c)):
            raise ValueError("workspace coordinates contain NaN or inf")
        if not allow_extrapolation:
            for j, (name, (lo, hi)) in enumerate(
                zip(("x_m", "y_m", "rz_deg"), WORKSPACE_BOUNDS, strict=True)
            ):
                tol = 1e-9 * max(1.0, abs(hi))
                bad = (c[:, j] < lo - tol) | (c[:, j] > hi + tol)
                if np.any(bad):
                    raise ValueError(
                        f"pose outside the modelled workspace: {name}={c[bad, j][0]:g} not in [{lo:g}, {hi:g}] "
                        "(pass allow_extrapolation=True to evaluate anyway)"
                    )
        return c

    def switch_weight(self, coords) -> np.ndarray:
        """s(pose) in [0, 1]: how strongly the ~63 Hz X mode is excited (1 = dominant regime).

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
        return 1.0 / (1.0 + np.exp(-(c[:, 0] - 2.62) / 0.02)) * np.cos(np.radians(c[:, 2])) ** 8

    def _low_mode(self, c: np.ndarray, direction: str):
        """fn [Hz], k [N/m], zeta (n,) of the Table A1 fields' dominant mode at checked poses."""
        s = self._scaled(c)
        fn, k, c_ns = (
            np.exp(self._fields[(direction, q)](s)) for q in ("fn", "stiffness", "damping")
        )
        return fn, k, c_ns * 2 * np.pi * fn / (2 * k)

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
            Dominant, secondary (and in X the ~63 Hz) modes per pose.
        """
        if direction not in DIRECTIONS:
            raise ValueError(f"unknown direction {direction!r}; expected x, y or z")
        c = self.check_coords(coords, allow_extrapolation)
        fn, k, zeta = self._low_mode(c, direction)
        fns, ks, zetas = _with_secondary(fn, k, zeta)
        if direction == "x":
            weight = 0.1 + 0.9 * self.switch_weight(c)
            fns = np.column_stack([fns, np.full(len(c), self.high_fn_hz)])
            ks = np.column_stack([ks, self.high_stiffness_n_per_m / weight])
            zetas = np.column_stack([zetas, np.full(len(c), self.high_damping_ratio)])
        return ModeSet(fns, ks, zetas)


class PathTruth:
    """Modes along the chapter-4/5 path, coordinate ``s_m`` in [0, 1.235] (see module docs)."""

    # Anchors at e = s / L: start, Position 1, Position 2, end. Units: Hz, MN/m, -.
    _E: ClassVar[tuple[float, ...]] = (
        0.0,
        POSITION_1_S_M / PATH_LENGTH_M,
        POSITION_2_S_M / PATH_LENGTH_M,
        1.0,
    )
    _ANCHORS: ClassVar[dict[str, tuple]] = {
        "x": ((10.4, 9.50, 7.40, 6.9), (1.45, 1.20, 0.74, 0.66), (0.13, 0.150, 0.190, 0.17)),
        "y": ((21.5, 22.2, 23.0, 23.2), (0.70, 0.78, 0.95, 1.00), (0.17, 0.180, 0.175, 0.17)),
        "z": ((12.6, 11.88, 9.06, 8.7), (2.30, 1.99, 1.15, 1.05), (0.12, 0.130, 0.150, 0.14)),
    }

    def __init__(self) -> None:
        self._curves = {
            d: [PchipInterpolator(self._E, np.asarray(v, float)) for v in vals]
            for d, vals in self._ANCHORS.items()
        }

    @staticmethod
    def check_coords(s_m, allow_extrapolation: bool = False) -> np.ndarray:
        s = np.atleast_1d(np.asarray(s_m, float))
        if s.ndim != 1:
            raise ValueError(
                f"path coordinates must be 1-D (distance along the path), got shape {s.shape}"
            )
        if not np.all(np.isfinite(s)):
            raise ValueError("path coordinates contain NaN or inf")
        if not allow_extrapolation and (np.any(s < -1e-9) or np.any(s > PATH_LENGTH_M + 1e-9)):
            raise ValueError(f"path coordinate outside [0, {PATH_LENGTH_M}] m")
        return s

    def modes(self, s_m, direction: str, *, allow_extrapolation: bool = False) -> ModeSet:
        if direction not in DIRECTIONS:
            raise ValueError(f"unknown direction {direction!r}; expected x, y or z")
        s = self.check_coords(s_m, allow_extrapolation)
        e = s / PATH_LENGTH_M
        fn, k_mn, zeta = (curve(e) for curve in self._curves[direction])
        return ModeSet(*_with_secondary(fn, k_mn * 1e6, zeta))


_Z_M = 0.325
_GRID_N = 7


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


class VirtualRobot:
    """The virtual KR500-3: ``workspace`` and ``path`` truths (see the module docstring).

    ``VirtualRobot()`` is the thesis robot; :meth:`variant` builds another member of the robot
    family (:mod:`robovib.sim.family`), a robot robovib has never seen.

    Attributes
    ----------
    robot_seed
        ``None`` for the thesis robot, else the seed of the variant.
    draw
        ``None`` for the thesis robot, else the variant's :class:`~robovib.sim.family.RobotDraw`.
    """

    def __init__(self) -> None:
        self.workspace = WorkspaceTruth()
        self.path = PathTruth()
        self.robot_seed: int | None = None
        self.draw = None

    @classmethod
    def variant(cls, seed: int | None) -> VirtualRobot:
        """The robot of the family drawn from ``seed`` (``None``: the thesis robot).

        Parameters
        ----------
        seed : int or None
            Non-negative seed of :func:`robovib.sim.family.draw_robot`.

        Returns
        -------
        VirtualRobot
            A robot with the drawn physics (its ``workspace``, ``path``, ``draw``).

        Raises
        ------
        ValueError
            A bad seed, or a draw that is not physical.

        Examples
        --------
        >>> from robovib.sim import VirtualRobot
        >>> VirtualRobot.variant(1).robot_seed
        1
        """
        if seed is None:
            return cls()
        draw = draw_robot(seed)
        robot = cls.__new__(cls)
        robot.workspace = VariantWorkspaceTruth(draw)  # (validated: raises if not physical)
        robot.path = VariantPathTruth(
            draw, robot.workspace.mean_stiffness_ratio, robot.workspace.mean_mass_ratio
        )
        robot.robot_seed, robot.draw = int(seed), draw
        return robot

    def domain(self, name: str):
        if name not in ("workspace", "path"):
            raise ValueError(f"unknown pose domain {name!r}; expected 'workspace' or 'path'")
        return self.workspace if name == "workspace" else self.path
