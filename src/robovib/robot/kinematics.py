"""KUKA KR500-3 kinematics: forward kinematics, geometric Jacobian, numerical inverse kinematics.

Geometry: the KR500-3 shares its arm with the KR 500/600 R2830 family; the public KUKA data
sheets and a public URDF of the KR 600 R2830 agree on these standard DH rows (d, a, alpha,
theta offset; metres, radians), flange frame last (``docs/methods.md`` section 4)::

    1: 1.045   0.500  -pi/2   0
    2: 0       1.300   0      0
    3: 0      -0.055  -pi/2  -pi/2
    4: 1.025   0       pi/2   0
    5: 0       0      -pi/2   0
    6: 0.290   0       0      pi

KUKA controller angles (A1..A6) map to DH angles with the sign vector [-1, 1, 1, -1, 1, -1]:
``theta_DH = sign * A + offset``. Joint limits (KUKA angles): A1 ±185°, A2 -130/+20°,
A3 -100/+144°, A4 ±350°, A5 ±120°, A6 ±350°. A configurable tool transform maps the flange
to the tool tip (default: a spindle + tool 0.35 m along the flange z axis — an assumption;
the thesis gives no tool frame).

Check (test anchor): the §4.3.2 joints [-0.11, -27.46, 94.04, 179.42, 66.83, -0.58]° put the
flange at (2300.5, 1.7, 683.3) mm against the printed (2300, 0, 680) mm.

The core is plain NumPy; Robotics Toolbox / Pinocchio / ikpy are far too heavy to depend on.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

__all__ = [
    "DH_TABLE",
    "JOINT_LIMITS_DEG",
    "KR500",
    "KUKA_SIGNS",
    "IKError",
    "euler_zyx",
    "tool_down_orientation",
]

#: Standard DH rows (d [m], a [m], alpha [rad], theta offset [rad]), joints 1..6.
DH_TABLE = np.array(
    [
        [1.045, 0.500, -math.pi / 2, 0.0],
        [0.0, 1.300, 0.0, 0.0],
        [0.0, -0.055, -math.pi / 2, -math.pi / 2],
        [1.025, 0.0, math.pi / 2, 0.0],
        [0.0, 0.0, -math.pi / 2, 0.0],
        [0.290, 0.0, 0.0, math.pi],
    ]
)
KUKA_SIGNS = np.array([-1.0, 1.0, 1.0, -1.0, 1.0, -1.0])
JOINT_LIMITS_DEG = np.array(
    [[-185, 185], [-130, 20], [-100, 144], [-350, 350], [-120, 120], [-350, 350]], float
)


class IKError(ValueError):
    """Inverse kinematics failed: unreachable target, joint limits, or a singular pose."""


def _dh(d, a, alpha, theta):
    ct, st, ca, sa = math.cos(theta), math.sin(theta), math.cos(alpha), math.sin(alpha)
    return np.array(
        [
            [ct, -st * ca, st * sa, a * ct],
            [st, ct * ca, -ct * sa, a * st],
            [0, sa, ca, d],
            [0, 0, 0, 1.0],
        ]
    )


def euler_zyx(a_deg: float, b_deg: float, c_deg: float) -> np.ndarray:
    """KUKA A, B, C (Z-Y'-X'') rotation matrix: ``Rz(A) Ry(B) Rx(C)``.

    Parameters
    ----------
    a_deg, b_deg, c_deg : float
        KUKA A, B, C angles [deg].

    Returns
    -------
    numpy.ndarray
        (3, 3) rotation matrix.
    """
    a, b, c = np.radians([a_deg, b_deg, c_deg])
    rz = np.array([[math.cos(a), -math.sin(a), 0], [math.sin(a), math.cos(a), 0], [0, 0, 1]])
    ry = np.array([[math.cos(b), 0, math.sin(b)], [0, 1, 0], [-math.sin(b), 0, math.cos(b)]])
    rx = np.array([[1, 0, 0], [0, math.cos(c), -math.sin(c)], [0, math.sin(c), math.cos(c)]])
    return rz @ ry @ rx


def tool_down_orientation(rz_deg: float) -> np.ndarray:
    """Tool axis pointing down (-Z base), rotated by ``rz_deg`` about the vertical.

    Our reading of the chapter-3 poses "Rx = Ry = 0, Rz" (tool axis perpendicular to the
    X-Y plane): ``Rz(rz) Ry(180°)``.

    Parameters
    ----------
    rz_deg : float
        Rotation about the vertical [deg].

    Returns
    -------
    numpy.ndarray
        (3, 3) rotation matrix.
    """
    return euler_zyx(rz_deg, 180.0, 0.0)


def _rotation_error(r_target: np.ndarray, r: np.ndarray) -> np.ndarray:
    """Axis-angle vector (base frame) of the rotation from ``r`` to ``r_target``."""
    r_err = r_target @ r.T
    cos_angle = np.clip((np.trace(r_err) - 1) / 2, -1.0, 1.0)
    angle = math.acos(cos_angle)
    vec = np.array(
        [r_err[2, 1] - r_err[1, 2], r_err[0, 2] - r_err[2, 0], r_err[1, 0] - r_err[0, 1]]
    )
    if angle < 1e-9:
        return 0.5 * vec
    if math.pi - angle < 1e-6:
        # Near 180°: axis from the symmetric part.
        axis = np.sqrt(np.clip((np.diag(r_err) + 1) / 2, 0, None))
        axis = axis * np.sign(np.where(vec == 0, 1.0, vec))
        return angle * axis / np.linalg.norm(axis)
    return angle / (2 * math.sin(angle)) * vec


@dataclass(frozen=True)
class KR500:
    """KR500-3 kinematic model with a tool (flange -> tool-tip transform, metres).

    Attributes
    ----------
    tool
        (4, 4) flange -> tool-tip homogeneous transform [m].
    joint_limits_deg
        (6, 2) joint limits [deg].
    """

    tool: np.ndarray = field(default_factory=lambda: _translation(0.0, 0.0, 0.35))
    joint_limits_deg: np.ndarray = field(default_factory=lambda: JOINT_LIMITS_DEG.copy())

    # ------------------------------------------------------------------ forward kinematics
    def _check_joints(self, joints_deg) -> np.ndarray:
        q = np.asarray(joints_deg, float)
        if q.shape != (6,):
            raise ValueError(f"joint angles must have shape (6,), got {q.shape}")
        if not np.all(np.isfinite(q)):
            raise ValueError("joint angles contain NaN or inf")
        return q

    def check_limits(self, joints_deg) -> None:
        q = self._check_joints(joints_deg)
        lo, hi = self.joint_limits_deg[:, 0], self.joint_limits_deg[:, 1]
        bad = np.flatnonzero((q < lo - 1e-9) | (q > hi + 1e-9))
        if bad.size:
            i = int(bad[0])
            raise IKError(
                f"joint A{i + 1} = {q[i]:.2f}° outside its limits [{lo[i]:g}, {hi[i]:g}]°"
            )

    def link_frames(self, joints_deg) -> list[np.ndarray]:
        """Base -> frame i transforms for i = 0 (base), 1..6 (DH frames), 7 (tool tip).

        Parameters
        ----------
        joints_deg : array_like
            (6,) joint angles [deg].

        Returns
        -------
        list of numpy.ndarray
            Eight (4, 4) homogeneous transforms [m].
        """
        q = self._check_joints(joints_deg)
        theta = KUKA_SIGNS * np.radians(q) + DH_TABLE[:, 3]
        frames = [np.eye(4)]
        for (d, a, alpha, _), th in zip(DH_TABLE, theta, strict=True):
            frames.append(frames[-1] @ _dh(d, a, alpha, th))
        frames.append(frames[-1] @ self.tool)
        return frames

    def fk(self, joints_deg, *, flange: bool = False) -> np.ndarray:
        """Forward kinematics: homogeneous transform of the tool tip (or the flange) in the base frame.

        See ``docs/methods.md`` section 4 (Eq. 1, DH parameters).

        Parameters
        ----------
        joints_deg : array_like, shape (6,)
            Joint angles A1..A6 [deg].
        flange : bool
            Return the flange frame instead of the tool tip.

        Returns
        -------
        numpy.ndarray
            (4, 4) transform; translation in metres.

        Raises
        ------
        ValueError
            ``joints_deg`` not 6 finite angles.

        Examples
        --------
        >>> from robovib.robot import KR500
        >>> KR500().fk([0.0, -90.0, 90.0, 0.0, 0.0, 0.0]).shape
        (4, 4)
        """
        frames = self.link_frames(joints_deg)
        return frames[6] if flange else frames[7]

    # ------------------------------------------------------------------ Jacobian
    def jacobian(self, joints_deg) -> np.ndarray:
        """Geometric Jacobian (6, 6) of the tool tip w.r.t. the KUKA joint angles [rad].

        Rows: linear velocity (m/s), angular velocity (rad/s), base frame.

        Parameters
        ----------
        joints_deg : array_like
            (6,) joint angles [deg].

        Returns
        -------
        numpy.ndarray
            (6, 6) Jacobian.
        """
        frames = self.link_frames(joints_deg)
        p_tip = frames[7][:3, 3]
        jac = np.zeros((6, 6))
        for i in range(6):
            z = frames[i][:3, 2]
            p = frames[i][:3, 3]
            jac[:3, i] = np.cross(z, p_tip - p) * KUKA_SIGNS[i]
            jac[3:, i] = z * KUKA_SIGNS[i]
        return jac

    def condition_number(self, joints_deg) -> float:
        """2-norm condition number of the Jacobian with the rotation rows scaled by 1 m.

        Parameters
        ----------
        joints_deg : array_like
            (6,) joint angles [deg].

        Returns
        -------
        float
            The condition number.
        """
        return float(np.linalg.cond(self.jacobian(joints_deg)))

    def manipulability(self, joints_deg) -> float:
        jac = self.jacobian(joints_deg)
        return float(math.sqrt(max(np.linalg.det(jac @ jac.T), 0.0)))

    def _within_limits(self, joints_deg) -> bool:
        try:
            self.check_limits(joints_deg)
        except IKError:
            return False
        return True

    # ------------------------------------------------------------------ inverse kinematics
    def ik(
        self,
        position_m,
        rotation: np.ndarray,
        *,
        reference_deg=(0.0, -60.0, 100.0, 0.0, 50.0, 0.0),
        tol_m: float = 1e-7,
        tol_rad: float = 1e-7,
        max_iter: int = 200,
        max_condition: float = 1e6,
    ) -> np.ndarray:
        """Joint angles [deg] placing the tool tip at ``position_m`` with ``rotation`` (3, 3).

        Damped least squares (Levenberg-Marquardt) from ``reference_deg``; only if that start
        fails (or ends outside the joint limits) a few perturbed starts are tried, and the
        converged solution inside the limits nearest the reference is returned. Raises :class:`IKError` if none converges (unreachable target),
        if every solution violates the limits, or if the pose is singular.

        Parameters
        ----------
        position_m : array_like
            (3,) tool-tip position in the base frame [m].
        rotation : numpy.ndarray
            (3, 3) tool orientation.
        reference_deg : array_like
            (6,) start and preferred configuration [deg].
        tol_m, tol_rad : float
            Position and orientation tolerances.
        max_iter : int
            Iterations per start.
        max_condition : float
            Jacobian condition number above which the pose counts as singular.

        Returns
        -------
        numpy.ndarray
            (6,) joint angles [deg].
        """
        target_p = np.asarray(position_m, float)
        target_r = np.asarray(rotation, float)
        if target_p.shape != (3,) or target_r.shape != (3, 3) or not np.all(np.isfinite(target_p)):
            raise ValueError("ik needs a finite position (3,) and a rotation matrix (3, 3)")
        ref = self._check_joints(reference_deg)
        reach = np.linalg.norm(target_p[:2]) - 0.5
        if (
            math.hypot(reach, target_p[2] - 1.045)
            > 1.3 + math.hypot(1.025, 0.055) + 0.29 + np.linalg.norm(self.tool[:3, 3]) + 1e-6
        ):
            raise IKError(f"target {np.round(target_p, 4).tolist()} m is beyond the arm's reach")
        rng = np.random.default_rng(0)
        starts = [ref] + [ref + rng.normal(scale=25.0, size=6) for _ in range(8)]
        solutions = []
        for n_start, start in enumerate(starts):
            if n_start > 0 and any(self._within_limits(s) for s in solutions):
                break  # the reference start converged inside the limits: nearest by continuity
            q = np.radians(start)
            lam = 1e-3
            for _ in range(max_iter):
                frame = self.fk(np.degrees(q))
                err = np.concatenate(
                    [target_p - frame[:3, 3], _rotation_error(target_r, frame[:3, :3])]
                )
                if np.linalg.norm(err[:3]) < tol_m and np.linalg.norm(err[3:]) < tol_rad:
                    solutions.append(np.degrees(q))
                    break
                jac = self.jacobian(np.degrees(q))
                step = jac.T @ np.linalg.solve(jac @ jac.T + lam * np.eye(6), err)
                q = q + step
        inside = []
        for s in solutions:
            try:
                self.check_limits(s)
                inside.append(s)
            except IKError:
                continue
        if not solutions:
            raise IKError(
                f"no IK solution found for target {np.round(target_p, 4).tolist()} m (unreachable?)"
            )
        if not inside:
            raise IKError("every IK solution found violates the joint limits")
        best = min(inside, key=lambda s: float(np.linalg.norm(s - ref)))
        cond = self.condition_number(best)
        if cond > max_condition:
            raise IKError(
                f"the pose is singular or nearly so (Jacobian condition number {cond:.3g})"
            )
        return best


def _translation(x: float, y: float, z: float) -> np.ndarray:
    t = np.eye(4)
    t[:3, 3] = (x, y, z)
    return t
