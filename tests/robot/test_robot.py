"""KR500 kinematics, stiffness, mass and identification against independent references."""

import numpy as np
import pytest
from scipy import linalg

from robovib.datasets import load_reference_table
from robovib.robot import KR500, IKError, tool_down_orientation
from robovib.robot.dynamics import (
    TABLE_4_JOINT_STIFFNESS,
    cartesian_modes,
    cartesian_stiffness,
    deflection,
    identify_joint_stiffness,
    joint_space_inertia,
)

robot = KR500()


def test_fk_matches_the_thesis_offset_mass_pose():
    """§4.3.2: these joints put the flange at (2300, 0, 680) mm (printed, rounded; the notes'
    independent FK gives (2300.5, 1.7, 683.3) mm)."""
    flange = robot.fk([-0.11, -27.46, 94.04, 179.42, 66.83, -0.58], flange=True)[:3, 3] * 1e3
    np.testing.assert_allclose(flange, [2300.5, 1.7, 683.3], atol=0.5)
    np.testing.assert_allclose(flange, [2300.0, 0.0, 680.0], atol=5.0)


def test_fk_geometric_invariants():
    """Link lengths of the data sheet hold at random configurations (hand-derived facts)."""
    rng = np.random.default_rng(0)
    for _ in range(20):
        q = rng.uniform(JOINT_LO, JOINT_HI)
        f = robot.link_frames(q)
        a2, a3, wrist = f[1][:3, 3], f[2][:3, 3], f[5][:3, 3]
        assert a2[2] == pytest.approx(1.045)
        assert np.hypot(*a2[:2]) == pytest.approx(0.5)
        assert np.linalg.norm(a3 - a2) == pytest.approx(1.3)
        assert np.linalg.norm(wrist - a3) == pytest.approx(np.hypot(1.025, 0.055))
        assert np.linalg.norm(f[6][:3, 3] - wrist) == pytest.approx(0.29)


JOINT_LO = np.array([-150, -110, -80, -300, -110, -300.0])
JOINT_HI = np.array([150, 10, 130, 300, 110, 300.0])


def _rot_log(r):
    angle = np.arccos(np.clip((np.trace(r) - 1) / 2, -1, 1))
    vec = np.array([r[2, 1] - r[1, 2], r[0, 2] - r[2, 0], r[1, 0] - r[0, 1]])
    return vec * (0.5 if angle < 1e-9 else angle / (2 * np.sin(angle)))


def test_jacobian_matches_finite_differences():
    q = np.array([10.0, -40.0, 80.0, 30.0, 45.0, -20.0])
    jac = robot.jacobian(q)
    h = 1e-6
    t0 = robot.fk(q)
    for i in range(6):
        dq = np.zeros(6)
        dq[i] = np.degrees(h)
        tp, tm = robot.fk(q + dq), robot.fk(q - dq)
        np.testing.assert_allclose(jac[:3, i], (tp[:3, 3] - tm[:3, 3]) / (2 * h), atol=1e-7)
        np.testing.assert_allclose(jac[3:, i], _rot_log(tp[:3, :3] @ t0[:3, :3].T) / h, atol=1e-5)


def test_ik_round_trip_across_the_workspace():
    rng = np.random.default_rng(1)
    for _ in range(15):
        p = np.array([rng.uniform(2.1, 2.7), rng.uniform(-0.3, 0.6), 0.325])
        r = tool_down_orientation(rng.uniform(0, 180))
        q = robot.ik(p, r)
        t = robot.fk(q)
        np.testing.assert_allclose(t[:3, 3], p, atol=1e-6)
        np.testing.assert_allclose(t[:3, :3], r, atol=1e-6)


def test_ik_errors():
    with pytest.raises(IKError, match="reach"):
        robot.ik(np.array([4.5, 0.0, 0.3]), tool_down_orientation(0))
    with pytest.raises(IKError, match="limits"):
        robot.check_limits([0, 30, 0, 0, 0, 0])
    with pytest.raises(ValueError, match="shape"):
        robot.fk([0, 0, 0])


def test_stiffness_is_spd_and_deflection_consistent():
    q = robot.ik(np.array([2.4, 0.0, 0.325]), tool_down_orientation(45))
    k = cartesian_stiffness(robot, q)
    np.testing.assert_allclose(k, k.T, rtol=1e-10, atol=1e-6)
    assert np.all(np.linalg.eigvalsh(k) > 0)
    w = np.array([100.0, -50.0, 200.0, 5.0, -3.0, 1.0])
    np.testing.assert_allclose(deflection(robot, q, w), np.linalg.solve(k, w), rtol=1e-8)
    with pytest.raises(ValueError, match="positive"):
        cartesian_stiffness(robot, q, k_theta=[1e6, 1e6, 1e6, 1e6, 0.0, 1e6])
    with pytest.raises(ValueError, match="singular"):
        cartesian_stiffness(robot, [0.0, -60.0, 90.0, 0.0, 0.0, 0.0])  # A5 = 0: wrist singularity


def test_modes_satisfy_the_eigenproblem():
    q = robot.ik(np.array([2.4, 0.3, 0.325]), tool_down_orientation(90))
    modes = cartesian_modes(robot, q)
    w2 = (2 * np.pi * modes.natural_frequencies_hz) ** 2
    for i in range(3):
        u = modes.directions[:, i]
        np.testing.assert_allclose(
            modes.stiffness_n_per_m @ u, w2[i] * modes.mass_kg @ u, rtol=1e-8
        )
    assert np.all(linalg.eigvalsh(joint_space_inertia(robot, q)) > 0)


def test_identification_recovers_table_4_from_table_3_tests():
    """Synthetic compliance tests at the thesis' Table 3 poses, noise like a laser tracker."""
    poses = load_reference_table(3)[[f"theta{i}_deg" for i in range(1, 7)]].to_numpy()
    rng = np.random.default_rng(2)
    joints, wrenches, disp = [], [], []
    for q in np.repeat(poses, 3, axis=0):
        w = np.concatenate([rng.uniform(-1500, 1500, 3), rng.uniform(-400, 400, 3)])
        d = deflection(robot, q, w, TABLE_4_JOINT_STIFFNESS)
        d = d + np.concatenate([rng.normal(0, 1e-6, 3), rng.normal(0, 1e-7, 3)])
        joints.append(q)
        wrenches.append(w)
        disp.append(d)
    k = identify_joint_stiffness(robot, joints, wrenches, disp)
    np.testing.assert_allclose(k, TABLE_4_JOINT_STIFFNESS, rtol=0.02)
    with pytest.raises(ValueError, match="need"):
        identify_joint_stiffness(robot, joints, wrenches, np.array(disp)[:, :2])
    # One test with translations only: 3 equations for 6 compliances (it printed A6 = 0 before).
    with pytest.raises(ValueError, match="rank 3 for the 6 joint compliances"):
        identify_joint_stiffness(robot, joints[:1], wrenches[:1], np.array(disp)[:1, :3])


def test_hybrid_learning_curve_runs_and_scores_both_models():
    from robovib.studies.hybrid_learning_curve import hybrid_learning_curve

    result = hybrid_learning_curve(n_poses=(10, 60), n_repeats=1)
    df = result.to_frame()
    assert result.to_dict()["rows"] and result.ratio().shape == (6, 2)
    assert set(df["model"]) == {"pure GP", "hybrid"}
    assert set(df["n_poses"]) == {10, 60}
    assert np.all(np.isfinite(df["rmse"])) and np.all(df["rmse"] > 0)


def test_robot_cli():
    import json

    from typer.testing import CliRunner

    from robovib.cli import app

    runner = CliRunner()
    res = runner.invoke(
        app,
        [
            "robot",
            "fk",
            "--joints",
            "-0.11",
            "-27.46",
            "94.04",
            "179.42",
            "66.83",
            "-0.58",
            "--json",
        ],
    )
    assert res.exit_code == 0, res.output
    np.testing.assert_allclose(json.loads(res.output)["flange_mm"], [2300.5, 1.7, 683.3], atol=0.5)
    res = runner.invoke(app, ["robot", "ik", "--x", "2400", "--y", "100", "--rz", "30", "--json"])
    assert res.exit_code == 0, res.output
    q = json.loads(res.output)["joints_deg"]
    np.testing.assert_allclose(KR500().fk(q)[:3, 3], [2.4, 0.1, 0.325], atol=1e-6)
    res = runner.invoke(app, ["robot", "ik", "--x", "5000", "--y", "0"])
    assert res.exit_code == 1 and "reach" in res.output
    res = runner.invoke(app, ["robot", "stiffness", "--x", "2400", "--y", "0", "--json"])
    assert res.exit_code == 0 and len(json.loads(res.output)["natural_frequencies_hz"]) == 3
