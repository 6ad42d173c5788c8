"""Cartesian stiffness, joint-stiffness identification, Cartesian mass and eigenfrequencies.

* Stiffness (thesis Eq. 11-12): ``K = J^-T (K_theta - K_c) J^-1`` with the joint stiffness
  ``K_theta = diag(k_1..k_6)`` and the optional complementary stiffness of the applied wrench
  ``K_c = [d(J^T w)/d theta_1, ..., d(J^T w)/d theta_6]`` (Alici & Shirinzadeh 2005); the tool
  deflection under a wrench is ``dx = K^-1 w``.
* Identification: with ``K_c`` neglected, ``dx = sum_i c_i J_i (J_i^T w)``, *linear* in the joint
  compliances ``c_i = 1 / k_i``; all tests are stacked and solved by bounded linear least
  squares (:func:`scipy.optimize.lsq_linear`, c >= 0) — the exact solution of the thesis'
  "nonlinear least squares" in the stiffnesses.
* Mass (Eq. 13-14): links are uniform solid cylinders of documented mass and size (as the
  thesis assumes solid links); joint-space inertia ``M_q = sum m_i Jv_i^T Jv_i + Jw_i^T R_i I_i
  R_i^T Jw_i``; the tool tip's translational operational-space inertia
  ``M_t = (Jv M_q^-1 Jv^T)^-1`` and translational stiffness ``K_t = ((K^-1)_tt)^-1`` (rotations
  free) give the undamped eigenproblem ``K_t U = w^2 M_t U`` (Eq. 15-16, translational modes).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import linalg, optimize

from .kinematics import KR500

__all__ = [
    "LINK_SOLIDS",
    "TABLE_4_JOINT_STIFFNESS",
    "CartesianModes",
    "LinkSolid",
    "cartesian_modes",
    "cartesian_stiffness",
    "complementary_stiffness",
    "deflection",
    "identify_joint_stiffness",
    "joint_space_inertia",
]

#: Thesis Table 4 [N m / rad] (a published reference value, also the default of the model).
TABLE_4_JOINT_STIFFNESS = np.array([3.93, 3.46, 2.77, 1.57, 0.24, 0.17]) * 1e6


@dataclass(frozen=True)
class LinkSolid:
    """A link as a uniform solid cylinder along the segment p0 -> p1 of its DH frame [m].

    Attributes
    ----------
    mass_kg
        Link mass [kg].
    radius_m
        Cylinder radius [m].
    p0, p1
        Ends of the cylinder axis in the link's DH frame [m].
    frame
        The DH frame (1-6) the link moves with.
    """

    mass_kg: float
    radius_m: float
    p0: tuple[float, float, float]
    p1: tuple[float, float, float]
    frame: int  #: index into KR500.link_frames (1..7)


# Masses: KR 600 R2830 URDF (link1 851, link2 448, link3 545, link4 176 kg); wrist links and
# the spindle+tool are assumptions (the URDF's wrist masses are placeholders). Segments follow
# the DH geometry in each link's own frame.
LINK_SOLIDS = (
    LinkSolid(851.0, 0.35, (-0.5, 0.0, 0.0), (0.0, 0.0, 0.0), 1),  # A1 turret: base -> A2 axis
    LinkSolid(448.0, 0.20, (-1.3, 0.0, 0.0), (0.0, 0.0, 0.0), 2),  # upper arm
    LinkSolid(
        545.0, 0.22, (0.0, 0.0, 0.0), (0.0, -0.6, 0.0), 3
    ),  # forearm housing, toward the wrist
    LinkSolid(176.0, 0.15, (0.0, 0.0, -0.425), (0.0, 0.0, 0.0), 4),  # forearm tube to the wrist
    LinkSolid(60.0, 0.12, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), 5),  # wrist (assumption)
    LinkSolid(
        120.0, 0.10, (0.0, 0.0, 0.0), (0.0, 0.0, 0.35), 6
    ),  # flange + spindle + tool (assumption)
)


def _inverse(jac: np.ndarray) -> np.ndarray:
    cond = np.linalg.cond(jac)
    if cond > 1e8:
        raise ValueError(f"the Jacobian is singular at this pose (condition number {cond:.3g})")
    return np.linalg.inv(jac)


def _check_joint_stiffness(k_theta) -> np.ndarray:
    k = np.asarray(k_theta, float)
    if k.shape != (6,) or not np.all(np.isfinite(k)) or np.any(k <= 0):
        raise ValueError(f"joint stiffness must be 6 positive finite values [N m/rad], got {k}")
    return k


def complementary_stiffness(robot: KR500, joints_deg, wrench) -> np.ndarray:
    """K_c (6, 6): derivative of J^T w w.r.t. the joint angles (central differences).

    Parameters
    ----------
    robot : KR500
        The kinematic model.
    joints_deg : array_like
        (6,) joint angles [deg].
    wrench : array_like
        (6,) tool-tip wrench (F [N], M [N m]), base frame.

    Returns
    -------
    numpy.ndarray
        (6, 6) complementary stiffness [N m/rad].
    """
    w = np.asarray(wrench, float)
    q = np.asarray(joints_deg, float)
    out = np.zeros((6, 6))
    h = 1e-6
    for i in range(6):
        dq = np.zeros(6)
        dq[i] = np.degrees(h)
        out[:, i] = (robot.jacobian(q + dq).T @ w - robot.jacobian(q - dq).T @ w) / (2 * h)
    return out


def cartesian_stiffness(
    robot: KR500, joints_deg, k_theta=TABLE_4_JOINT_STIFFNESS, wrench=None
) -> np.ndarray:
    """Eq. 11: K = J^-T (K_theta - K_c) J^-1 (6x6; N/m, N/rad, N m/m, N m/rad).

    See ``docs/methods.md`` section 4 (analytical robot model).

    Parameters
    ----------
    robot : KR500
        Kinematic model (DH parameters, tool).
    joints_deg : array_like, shape (6,)
        Joint angles A1..A6 [deg].
    k_theta : array_like, shape (6,)
        Joint stiffnesses [N m/rad] (default: thesis Table 4).
    wrench : array_like, shape (6,), optional
        External load (F [N], M [N m]) for the complementary stiffness K_c; None: K_c = 0.

    Returns
    -------
    numpy.ndarray
        (6, 6) Cartesian stiffness at the tool tip, base frame (symmetric when ``wrench`` is None).

    Raises
    ------
    ValueError
        Non-positive joint stiffness, a singular pose, wrong shapes.

    Examples
    --------
    >>> import numpy as np
    >>> from robovib.robot import KR500
    >>> from robovib.robot.dynamics import cartesian_stiffness
    >>> k = cartesian_stiffness(KR500(), [0.0, -60.0, 90.0, 0.0, 60.0, 0.0])
    >>> k.shape, bool(np.allclose(k, k.T))
    ((6, 6), True)
    """
    k = _check_joint_stiffness(k_theta)
    jinv = _inverse(robot.jacobian(joints_deg))
    kq = np.diag(k)
    if wrench is not None:
        kq = kq - complementary_stiffness(robot, joints_deg, wrench)
    stiff = jinv.T @ kq @ jinv
    return 0.5 * (stiff + stiff.T) if wrench is None else stiff


def deflection(robot: KR500, joints_deg, wrench, k_theta=TABLE_4_JOINT_STIFFNESS) -> np.ndarray:
    """Eq. 12: tool-tip screw displacement (dx, dphi) under a wrench (K_c neglected).

    Parameters
    ----------
    robot : KR500
        The kinematic model.
    joints_deg : array_like
        (6,) joint angles [deg].
    wrench : array_like
        (6,) tool-tip wrench (F [N], M [N m]), base frame.
    k_theta : array_like
        (6,) joint stiffnesses [N m/rad] (default: thesis Table 4).

    Returns
    -------
    numpy.ndarray
        (6,) translation [m] and rotation [rad].
    """
    w = np.asarray(wrench, float)
    if w.shape != (6,):
        raise ValueError(f"wrench must have shape (6,) = (F [N], M [N m]), got {w.shape}")
    jac = robot.jacobian(joints_deg)
    return jac @ ((jac.T @ w) / _check_joint_stiffness(k_theta))


def identify_joint_stiffness(robot: KR500, joints_deg, wrenches, displacements) -> np.ndarray:
    """Joint stiffnesses [N m/rad] from compliance tests (thesis Table 3/4 procedure).

    Parameters
    ----------
    robot
        The kinematic model (:class:`KR500`).
    joints_deg
        (n_tests, 6) robot configurations.
    wrenches
        (n_tests, 6) applied wrench at the tool tip (F [N], M [N m]), base frame.
    displacements
        (n_tests, 6) or (n_tests, 3) measured screw displacement (translation [m] and, if
        given, rotation [rad]).

    Returns
    -------
    numpy.ndarray
        (6,) joint stiffnesses [N m/rad] (least squares over the tests).
    """
    q = np.atleast_2d(np.asarray(joints_deg, float))
    w = np.atleast_2d(np.asarray(wrenches, float))
    d = np.atleast_2d(np.asarray(displacements, float))
    if (
        q.shape[1] != 6
        or w.shape != q.shape
        or d.shape[0] != q.shape[0]
        or d.shape[1] not in (3, 6)
    ):
        raise ValueError(
            f"need (n, 6) joints and wrenches and (n, 3|6) displacements; got {q.shape}, {w.shape}, {d.shape}"
        )
    if not (np.all(np.isfinite(q)) and np.all(np.isfinite(w)) and np.all(np.isfinite(d))):
        raise ValueError("compliance-test data contain NaN or inf")
    rows, rhs = [], []
    m = d.shape[1]
    for qi, wi, di in zip(q, w, d, strict=True):
        jac = robot.jacobian(qi)
        torque = jac.T @ wi
        rows.append((jac * torque[None, :])[:m])  # column i: J_i (J_i^T w)
        rhs.append(di)
    a = np.vstack(rows)
    b = np.concatenate(rhs)
    scale = np.max(np.abs(a), axis=0)
    if np.any(scale == 0):
        raise ValueError(
            f"joints {np.flatnonzero(scale == 0) + 1} carry no torque in any test: not identifiable"
        )
    rank = int(np.linalg.matrix_rank(a / scale, tol=1e-9 * np.sqrt(a.shape[0])))
    if rank < a.shape[1]:
        raise ValueError(
            f"{q.shape[0]} compliance test(s) give {a.shape[0]} equations of rank {rank} for the "
            f"{a.shape[1]} joint compliances: not identifiable (add tests in other poses or "
            "load directions)"
        )
    sol = optimize.lsq_linear(a / scale, b, bounds=(0, np.inf))
    comp = sol.x / scale
    if np.any(comp <= 0):
        raise ValueError(
            "identification gave a zero compliance (infinite stiffness); the tests do not excite every joint"
        )
    return 1.0 / comp


def _cylinder_inertia(mass: float, radius: float, length: float) -> np.ndarray:
    """Inertia about the centroid of a solid cylinder with its axis along local z."""
    ixx = mass * (3 * radius**2 + length**2) / 12
    return np.diag([ixx, ixx, mass * radius**2 / 2])


def _axis_frame(p0: np.ndarray, p1: np.ndarray) -> np.ndarray:
    """Rotation whose z axis is along p1 - p0 (identity for a point)."""
    v = p1 - p0
    n = np.linalg.norm(v)
    if n == 0:
        return np.eye(3)
    z = v / n
    helper = np.array([1.0, 0, 0]) if abs(z[0]) < 0.9 else np.array([0, 1.0, 0])
    x = np.cross(helper, z)
    x /= np.linalg.norm(x)
    return np.column_stack([x, np.cross(z, x), z])


def joint_space_inertia(robot: KR500, joints_deg, links=LINK_SOLIDS) -> np.ndarray:
    """Eq. 13-14: M_q (6, 6) [kg m^2] from the links as uniform solid cylinders.

    Parameters
    ----------
    robot : KR500
        The kinematic model.
    joints_deg : array_like
        (6,) joint angles [deg].
    links : sequence of LinkSolid
        The link inertias.

    Returns
    -------
    numpy.ndarray
        (6, 6) joint-space inertia [kg m^2].
    """
    frames = robot.link_frames(joints_deg)
    jac_frames = [(frames[i][:3, 2], frames[i][:3, 3]) for i in range(6)]
    from .kinematics import KUKA_SIGNS

    m_q = np.zeros((6, 6))
    for link in links:
        t = frames[link.frame]
        p0, p1 = np.asarray(link.p0), np.asarray(link.p1)
        centre_local = 0.5 * (p0 + p1)
        centre = t[:3, :3] @ centre_local + t[:3, 3]
        r_cyl = t[:3, :3] @ _axis_frame(p0, p1)
        inertia = (
            r_cyl
            @ _cylinder_inertia(link.mass_kg, link.radius_m, float(np.linalg.norm(p1 - p0)))
            @ r_cyl.T
        )
        jv = np.zeros((3, 6))
        jw = np.zeros((3, 6))
        # Joint j moves link frame f when j < f (DH frame f is attached after joint f).
        for j in range(min(link.frame, 6)):
            z, p = jac_frames[j]
            jv[:, j] = np.cross(z, centre - p) * KUKA_SIGNS[j]
            jw[:, j] = z * KUKA_SIGNS[j]
        m_q += link.mass_kg * jv.T @ jv + jw.T @ inertia @ jw
    return 0.5 * (m_q + m_q.T)


@dataclass(frozen=True)
class CartesianModes:
    """Translational tool-tip modes: natural frequencies [Hz] and unit directions (columns).

    Attributes
    ----------
    natural_frequencies_hz
        (3,) natural frequencies [Hz], ascending.
    directions
        (3, 3) unit mode directions in the base frame (columns).
    stiffness_n_per_m
        (3, 3) translational stiffness matrix K_t [N/m].
    mass_kg
        (3, 3) translational mass matrix M_t [kg].
    """

    natural_frequencies_hz: np.ndarray  #: (3,) ascending
    directions: np.ndarray  #: (3, 3) mode shapes (columns), base frame
    stiffness_n_per_m: np.ndarray  #: (3, 3) translational stiffness K_t
    mass_kg: np.ndarray  #: (3, 3) translational operational-space inertia M_t

    def directional_stiffness(self) -> np.ndarray:
        """Stiffness along base X, Y, Z: 1 / (K_t^-1)_ii [N/m].

        Returns
        -------
        numpy.ndarray
            (3,) stiffness along X, Y, Z [N/m].
        """
        return 1.0 / np.diag(np.linalg.inv(self.stiffness_n_per_m))

    def principal_stiffness(self) -> tuple[np.ndarray, np.ndarray]:
        """Principal stiffnesses of K_t and their directions.

        Returns
        -------
        values : numpy.ndarray
            (3,) eigenvalues of the translational stiffness K_t [N/m], ascending.
        directions : numpy.ndarray
            (3, 3) unit eigenvectors (columns), base frame.
        """
        values, vectors = np.linalg.eigh(self.stiffness_n_per_m)
        return values, vectors


def cartesian_modes(
    robot: KR500, joints_deg, k_theta=TABLE_4_JOINT_STIFFNESS, links=LINK_SOLIDS
) -> CartesianModes:
    """Eq. 15-16 for the translational tool-tip dynamics: K_t U = w^2 M_t U.

    Parameters
    ----------
    robot : KR500
        The kinematic model.
    joints_deg : array_like
        (6,) joint angles [deg].
    k_theta : array_like
        (6,) joint stiffnesses [N m/rad] (default: thesis Table 4).
    links : sequence of LinkSolid
        The link inertias.

    Returns
    -------
    CartesianModes
        The three translational modes.
    """
    k = _check_joint_stiffness(k_theta)
    jac = robot.jacobian(joints_deg)
    _inverse(jac)  # singularity check
    compliance = jac @ np.diag(1.0 / k) @ jac.T  # K^-1 = J K_theta^-1 J^T
    k_t = np.linalg.inv(compliance[:3, :3])
    m_q = joint_space_inertia(robot, joints_deg, links)
    jv = jac[:3]
    m_t = np.linalg.inv(jv @ np.linalg.solve(m_q, jv.T))
    k_t, m_t = 0.5 * (k_t + k_t.T), 0.5 * (m_t + m_t.T)
    eigval, eigvec = linalg.eigh(k_t, m_t)
    if np.any(eigval <= 0):
        raise ValueError("non-positive eigenvalue: stiffness or mass matrix not positive definite")
    dirs = eigvec / np.linalg.norm(eigvec, axis=0)
    return CartesianModes(np.sqrt(eigval) / (2 * np.pi), dirs, k_t, m_t)
