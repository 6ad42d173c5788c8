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
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from scipy.interpolate import PchipInterpolator, RBFInterpolator

from ..datasets import load_table_a1
from ..modal.parameters import ModalParameters

__all__ = [
    "PATH_LENGTH_M",
    "POSITION_1_S_M",
    "POSITION_2_S_M",
    "WORKSPACE_BOUNDS",
    "ModeSet",
    "PathTruth",
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
        from .family import VariantPathTruth, VariantWorkspaceTruth, draw_robot

        draw = draw_robot(seed)
        robot = cls.__new__(cls)
        robot.workspace = VariantWorkspaceTruth(draw)
        robot.path = VariantPathTruth(
            draw, robot.workspace.mean_stiffness_ratio, robot.workspace.mean_mass_ratio
        )
        robot.robot_seed, robot.draw = int(seed), draw
        return robot

    def domain(self, name: str):
        if name not in ("workspace", "path"):
            raise ValueError(f"unknown pose domain {name!r}; expected 'workspace' or 'path'")
        return self.workspace if name == "workspace" else self.path
