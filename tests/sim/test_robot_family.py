"""The family of virtual robots (robovib.sim.family): physical draws, the thesis robot untouched,
and a campaign on a robot robovib has never seen recovering that robot's own modes.

Independent references: the analytical robot model (robot.dynamics.cartesian_modes, Eq. 11-16)
for the joint-stiffness and mass changes, and the variant's modal parameters for the campaign.
"""

from dataclasses import replace

import numpy as np
import pandas as pd
import pytest

from robovib.campaign import ProcessingSettings, process_campaign
from robovib.robot import KR500, tool_down_orientation
from robovib.robot.dynamics import LINK_SOLIDS, TABLE_4_JOINT_STIFFNESS, cartesian_modes
from robovib.sim import VirtualRobot, simulate_campaign, truth_table
from robovib.sim.family import draw_robot, tooth_passing_speeds_rpm

SEEDS = range(8)


def _random_poses(n, seed):
    rng = np.random.default_rng(seed)
    return np.column_stack(
        [rng.uniform(2.1, 2.7, n), rng.uniform(-0.3, 0.6, n), rng.uniform(0, 180, n)]
    )


@pytest.fixture(scope="module")
def robots():
    return {s: VirtualRobot.variant(s) for s in SEEDS}


def test_every_draw_is_physical(robots):
    """Over 8 seeds, at 400 random poses (not the construction's check grid) and along the path:
    positive stiffness, 5-120 Hz, damping 0.5-35 %, each secondary mode above and weaker than
    the dominant one, and a switching X mode that dominates somewhere exactly when drawn."""
    coords = _random_poses(400, 99)
    n_switch = 0
    for seed, robot in robots.items():
        for d in "xyz":
            for m in (
                robot.workspace.modes(coords, d),
                robot.path.modes(np.linspace(0, 1.235, 40), d),
            ):
                assert np.all(m.stiffness_n_per_m > 0), (seed, d)
                assert np.all((m.fn_hz >= 5) & (m.fn_hz <= 120)), (
                    seed,
                    d,
                    m.fn_hz.min(),
                    m.fn_hz.max(),
                )
                assert np.all((m.damping_ratio >= 0.005) & (m.damping_ratio <= 0.35)), (seed, d)
                assert np.all(m.fn_hz[:, 1] > m.fn_hz[:, 0]), (seed, d)
                peak = 1 / (2 * m.damping_ratio * m.stiffness_n_per_m)
                assert np.all(peak[:, 1] < peak[:, 0]), (seed, d)
        x = robot.workspace.modes(coords, "x")
        peak = 1 / (2 * x.damping_ratio * x.stiffness_n_per_m)
        share = np.mean(np.argmax(peak, axis=1) == 2)
        if robot.draw.switch:
            n_switch += 1
            assert 0 < share < 0.5, (seed, share)
            # where it dominates: near the drawn Rz, on the extended side of x_s
            where = coords[np.argmax(peak, axis=1) == 2]
            assert np.all(where[:, 0] > robot.draw.switch_x_m - 3 * robot.draw.switch_width_m)
        else:
            assert share == 0, seed
    assert 0 < n_switch < len(SEEDS)  # both kinds of robot occur


def test_draws_differ_and_repeat(robots):
    assert draw_robot(5) == draw_robot(5) and draw_robot(5) != draw_robot(6)
    c = _random_poses(50, 1)
    thesis = VirtualRobot().workspace.modes(c, "x").dominant().stiffness_n_per_m[:, 0]
    spread = [
        np.median(np.abs(r.workspace.modes(c, "x").dominant().stiffness_n_per_m[:, 0] / thesis - 1))
        for r in robots.values()
    ]
    # the physics changes (joint stiffness x0.61-1.65): most robots differ by more than 5 %
    assert np.mean(np.array(spread) > 0.05) > 0.5


@pytest.mark.parametrize("bad", [-1, 1.5, True, "3", None])
def test_bad_seeds_are_refused(bad):
    with pytest.raises(ValueError, match="robot seed"):
        draw_robot(bad)


def test_thesis_robot_is_the_default():
    """VirtualRobot() and variant(None) are the thesis robot: no seed, no draw, the same modes."""
    a, b = VirtualRobot(), VirtualRobot.variant(None)
    assert a.robot_seed is None and a.draw is None and b.draw is None
    c = _random_poses(30, 2)
    for d in "xyz":
        ma, mb = a.workspace.modes(c, d), b.workspace.modes(c, d)
        np.testing.assert_array_equal(ma.fn_hz, mb.fn_hz)
        np.testing.assert_array_equal(ma.stiffness_n_per_m, mb.stiffness_n_per_m)
    # the thesis robot's documented X structure: secondary at 2.6 fn, 10 k, 5 %; switch at Rz 0
    x = a.workspace.modes(c, "x")
    np.testing.assert_allclose(x.fn_hz[:, 1], 2.6 * x.fn_hz[:, 0], rtol=1e-12)
    np.testing.assert_allclose(
        x.stiffness_n_per_m[:, 1], 10 * x.stiffness_n_per_m[:, 0], rtol=1e-12
    )
    assert np.all(x.damping_ratio[:, 1] == 0.05)


@pytest.mark.parametrize("seed", [3, 11])
def test_joint_model_changes_against_the_analytical_model(seed):
    """At grid nodes of the ratio fields (x 2.1-2.7 step 0.1, y -0.3-0.6 step 0.15) and at an Rz
    where the orientation term vanishes, the variant's X/Y/Z stiffness over the thesis robot's is
    the ratio of the analytical directional stiffness with the scaled joint stiffnesses, and
    fn^2 / k the inverse ratio of the apparent masses with the scaled links (Eq. 11-16)."""
    robot = VirtualRobot.variant(seed)
    thesis = VirtualRobot()
    draw = robot.draw
    kr500 = KR500()
    links = tuple(
        replace(link, mass_kg=link.mass_kg * f)
        for link, f in zip(LINK_SOLIDS, draw.link_mass_scale, strict=True)
    )
    k_var = TABLE_4_JOINT_STIFFNESS * np.array(draw.joint_stiffness_scale)
    rz = draw.orientation_phase_deg + 45.0  # cos(2 (Rz - phi)) = 0
    for x, y in ((2.2, -0.15), (2.5, 0.3), (2.7, 0.6)):
        q = kr500.ik(
            np.array([x, y, 0.325]),
            tool_down_orientation(0.0),
            reference_deg=[0, -30, 70, 0, 50, 0],
        )
        nominal = cartesian_modes(kr500, q)
        variant = cartesian_modes(kr500, q, k_var, links)
        k_ratio = variant.directional_stiffness() / nominal.directional_stiffness()
        m_ratio = np.diag(np.linalg.inv(nominal.mass_kg)) / np.diag(np.linalg.inv(variant.mass_kg))
        coords = np.array([[x, y, rz % 180]])
        for i, d in enumerate("xyz"):
            a = robot.workspace.modes(coords, d)
            b = thesis.workspace.modes(coords, d)
            got_k = a.stiffness_n_per_m[0, 0] / b.stiffness_n_per_m[0, 0]
            np.testing.assert_allclose(got_k, k_ratio[i], rtol=1e-4)
            got_m = got_k * (b.fn_hz[0, 0] / a.fn_hz[0, 0]) ** 2
            np.testing.assert_allclose(got_m, m_ratio[i], rtol=1e-4)
            np.testing.assert_allclose(
                a.damping_ratio[0, 0] / b.damping_ratio[0, 0], draw.damping_scale[i], rtol=1e-12
            )


def test_campaign_on_an_unseen_robot_recovers_its_modes(tmp_path):
    """sim campaign -> campaign process (every mode in 5-100 Hz) on robot seed 7, a pose in its
    switch region included: the dominant modes match the variant's own truth (fn 1 %, k and
    zeta 6 %) where they are 8-30 % away from the thesis robot's, and every mode of the truth is
    found within 3 % in fn."""
    robot = VirtualRobot.variant(7)
    rng = np.random.default_rng(3)
    poses = np.column_stack(
        [np.linspace(2150, 2600, 6), rng.uniform(-300, 600, 6), rng.uniform(0, 180, 6)]
    )
    poses[-1] = [2695.0, 100.0, robot.draw.switch_rz_deg]
    coords = poses * [1e-3, 1e-3, 1]
    assert robot.draw.switch
    x_modes = robot.workspace.modes(coords[-1:], "x")
    assert (
        np.argmax(x_modes.peak_compliance()[0]) == 2
    )  # the last pose: the switching mode dominates
    sim = simulate_campaign(poses, tmp_path, rng=1, n_hits=2, n_truth=0, robot=robot)
    process_campaign(sim.manifest, tmp_path / "out", n_workers=1,
                     settings=ProcessingSettings(modes_band_hz=(5.0, 100.0)))  # fmt: skip
    modal = pd.read_csv(tmp_path / "out" / "modal.csv")
    truth, thesis = truth_table(robot, poses), truth_table(VirtualRobot(), poses)
    far = 0
    for d in "xyz":
        m = modal[modal["direction"] == d].sort_values("row")
        np.testing.assert_allclose(m["fn_hz"], truth[f"{d}_fn_hz"], rtol=0.01)
        np.testing.assert_allclose(
            m["stiffness_n_per_m"], truth[f"{d}_stiffness_n_per_m"], rtol=0.06
        )
        np.testing.assert_allclose(m["damping_ratio"], truth[f"{d}_damping_ratio"], rtol=0.06)
        far += np.sum(np.abs(thesis[f"{d}_fn_hz"] / truth[f"{d}_fn_hz"] - 1) > 0.08)
    assert far >= 6  # the campaign saw this robot, not the thesis one
    modes = pd.read_csv(tmp_path / "out" / "modes.csv")
    for i, c in enumerate(coords):
        for d in "xyz":
            fitted = modes[(modes["direction"] == d) & np.isclose(modes["x_mm"], poses[i, 0])][
                "fn_hz"
            ].to_numpy()
            for fn in robot.workspace.modes(c[None], d).fn_hz[0]:
                assert np.min(np.abs(fitted / fn - 1)) < 0.03, (i, d, fn, fitted)


def test_tooth_passing_speeds_sit_on_the_modes():
    robot = VirtualRobot.variant(4)
    c = _random_poses(20, 5)
    speeds = tooth_passing_speeds_rpm(robot, c, n_flutes=2)
    m = robot.workspace.modes(c, "x")
    assert speeds["x secondary"] * 2 / 60 == pytest.approx(np.median(m.fn_hz[:, 1]))
    assert speeds["x switching"] * 2 / 60 == pytest.approx(robot.workspace.high_fn_hz)
    with pytest.raises(ValueError, match="n_flutes"):
        tooth_passing_speeds_rpm(robot, c, n_flutes=0)


def test_cli_sim_campaign_on_an_unseen_robot(tmp_path):
    """`sim campaign --robot-seed 7`: truth.csv holds robot 7's dominant modes (not the thesis
    robot's) and the JSON settings say which robot it was."""
    import json

    from typer.testing import CliRunner

    from robovib.cli import app

    poses = tmp_path / "poses.csv"
    poses.write_text("x_mm,y_mm,rz_deg\n2300,0,45\n2500,200,120\n")
    args = ["sim", "campaign", "--poses", str(poses), "--hits", "1", "--duration-s", "1",
            "--truth", "4", "--json"]  # fmt: skip
    runner = CliRunner()
    res = runner.invoke(app, [*args, "-o", str(tmp_path / "seven"), "--robot-seed", "7"])
    assert res.exit_code == 0, res.output
    assert json.loads(res.output)["settings"]["robot_seed"] == 7
    res = runner.invoke(app, [*args, "-o", str(tmp_path / "thesis")])
    assert res.exit_code == 0, res.output
    seven = pd.read_csv(tmp_path / "seven" / "truth.csv")
    thesis = pd.read_csv(tmp_path / "thesis" / "truth.csv")
    np.testing.assert_array_equal(
        seven[["x_mm", "y_mm", "rz_deg"]], thesis[["x_mm", "y_mm", "rz_deg"]]
    )
    want = truth_table(VirtualRobot.variant(7), seven[["x_mm", "y_mm", "rz_deg"]].to_numpy())
    np.testing.assert_allclose(seven["z_fn_hz"], want["z_fn_hz"], rtol=1e-8)
    assert np.all(np.abs(seven["z_fn_hz"] / thesis["z_fn_hz"] - 1) > 0.05)


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"damping_scale": (4.0, 1.0, 1.0)}, "x damping ratios"),
        ({"switch": True, "switch_x_m": 3.5}, "switching X mode dominates 0 %"),
        ({"joint_stiffness_scale": (1.0, -1.0, 1.0, 1.0, 1.0, 1.0)}, "6 positive finite"),
        ({"high_damping_ratio": 0.0}, "high_damping_ratio"),
        ({"secondary_fn_factor": (0.8, 2.5, 2.5)}, "secondary mode"),
    ],
)
def test_a_non_physical_robot_is_refused(change, message):
    from robovib.sim.truth import VariantWorkspaceTruth

    with pytest.raises(ValueError, match=message):
        VariantWorkspaceTruth(replace(draw_robot(2), **change))
