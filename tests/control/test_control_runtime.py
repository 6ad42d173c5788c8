"""Controller files, the run-time controller and replay (issue 40)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from robovib.control.controller_file import (
    design_controller,
    load_controller,
    write_controller_file,
)
from robovib.control.controllers import PathCursor, ScheduledTable
from robovib.control.cut_replay import replay
from robovib.control.path_design import ControlPath, PathDesign
from robovib.control.runtime import RuntimeController
from robovib.gp.dominant_modes import PoseMode
from robovib.modal.parameters import ModalParameters


class _LineModel:
    """A pose model in (x_mm, y_mm, rz_deg) with closed-form modes: two X modes, one Z mode.

    x1: 9 Hz, 1 MN/m, zeta 0.1 (peak compliance 5e-6 m/N); x2: 20 Hz, 0.5 MN/m, zeta 0.02
    (5e-5 m/N: the one that matters for control); z1 from y.
    """

    input_names = ("x_mm", "y_mm", "rz_deg")
    directions_ = ("x1", "x2", "z1")

    def __init__(self):
        self.calls = 0

    def modes(self, X):
        self.calls += 1
        X = np.atleast_2d(np.asarray(X, float))
        out = []
        for x, y, _ in X:
            fz = 9.0 + 2e-3 * (y + 300.0)
            row = {
                "x1": ModalParameters(9.0, 1.0e6, 0.1),
                "x2": ModalParameters(20.0 + 1e-3 * (x - 2300.0), 0.5e6, 0.02),
                "z1": ModalParameters(fz, 1.5e6, 0.12),
            }
            out.append({k: PoseMode(m, 0.05 * m.natural_frequency_hz,
                                     0.05 * m.stiffness_n_per_m, 0.05 * m.damping_ns_per_m,
                                     False, None) for k, m in row.items()})  # fmt: skip
        return out


def _line():
    return ControlPath.through(_LineModel.input_names, [[2350, 500, 30], [2350, -200, 100]])


def test_path_travel_and_projection_are_the_closed_form():
    path = ControlPath.through(
        ("x_mm", "y_mm", "rz_deg"), [[0, 0, 0], [300, 400, 10], [300, 0, 20]]
    )
    np.testing.assert_allclose(path.s_m, [0.0, 0.5, 0.9])
    # (150, 200) is the middle of the first leg; (400, 200) is 100 mm beside the second leg
    np.testing.assert_allclose(path.coordinate([[150, 200, 99], [400, 200, 0]]), [0.25, 0.7])
    np.testing.assert_allclose(path.poses_at([0.7])[0], [300, 200, 15])
    with pytest.raises(ValueError, match="same position"):
        ControlPath.through(("x_mm", "y_mm"), [[0, 0], [0, 0]])
    with pytest.raises(ValueError, match="no position"):
        ControlPath.through(("a1_deg",), [[0], [1]])


def test_multi_mode_model_controls_the_mode_of_largest_peak_compliance_and_asks_once():
    model = _LineModel()
    design = PathDesign(model, _line(), ("x", "z"), n_points=7)
    assert design.mode_names == {"x": "x2", "z": "z1"}
    assert model.calls == 1
    # the design points come from the cache
    assert design.modes(design.grid_s_m[:, None])[3]["x"].parameters.natural_frequency_hz == 20.05
    assert model.calls == 1


def test_live_rows_interpolate_like_the_planned_table():
    rng = np.random.default_rng(0)
    s = np.sort(rng.uniform(0, 1.2, 9))
    vals = rng.normal(size=(9, 4))
    table = ScheduledTable(s, vals)
    cursor = PathCursor(10, 0.5)
    live = table.at(cursor)
    col = live[:, 2]
    for x in [-0.1, *rng.uniform(0, 1.2, 20), 1.5]:
        cursor.move_to(x)
        ref = np.array([np.interp(x, s, vals[:, j]) for j in range(4)])
        np.testing.assert_allclose(live[0], ref, rtol=0, atol=1e-12)
        assert col[5] == pytest.approx(ref[2], abs=1e-12)


def _path_file(tmp_path, controller="adaptive+force", rpm=250.0):
    model = _LineModel()
    doc = design_controller(model, _line(), controller, n_points=7, spindle_rpm=rpm)
    return write_controller_file(tmp_path / "ctl.json", doc), doc


def test_controller_file_says_what_it_is(tmp_path):
    path, _ = _path_file(tmp_path)
    back = json.loads(path.read_text())
    assert back["format"] == "robovib.controller" and back["format_version"] == 3
    assert back["provenance"]["control_modes"] == {"x": "x2", "z": "z1"}
    assert back["timing"] == {"command_period_s": 0.004, "sample_rate_hz": 1000.0,
                              "delay_s": 0.032, "budget_s": 0.004}  # fmt: skip
    assert set(back["stability"]["force_model_worst_rms_ratio"]) == {"x", "z"}
    assert back["units"]["step.output"].startswith("mm")
    ctl = load_controller(path)
    assert isinstance(ctl, RuntimeController) and ctl.name == "adaptive+force"


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (lambda d: d.update(format="other"), "not a robovib controller"),
        (lambda d: d.update(format_version=99), "format version"),
        (lambda d: d.update(controller="magic"), "unknown controllers"),
        (lambda d: d["gains"].pop("force_model_r"), "malformed design table"),
        (lambda d: d["timing"].update(delay_s=0.03), "whole number of command"),
    ],
)
def test_bad_controller_files_are_refused_with_the_reason(tmp_path, edit, message):
    _, doc = _path_file(tmp_path)
    edit(doc)
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(doc))
    with pytest.raises(ValueError, match=message):
        load_controller(bad)


def test_tuned_cannot_go_to_a_file_and_names_are_checked_before_design():
    model = _LineModel()
    with pytest.raises(ValueError, match="cannot go to a controller file"):
        design_controller(model, _line(), "tuned")
    with pytest.raises(ValueError, match="unknown controllers"):
        design_controller(model, _line(), "nope")
    assert model.calls == 0


def test_step_needs_a_spindle_speed_and_refuses_a_run_longer_than_its_buffers(tmp_path):
    path, _ = _path_file(tmp_path, rpm=None)
    ctl = load_controller(path)
    with pytest.raises(ValueError, match="spindle"):
        ctl.step_arrays(np.zeros(3), np.zeros(3), 0.1)
    ctl.reset(spindle_rpm=250, max_duration_s=0.008)
    for _ in range(2):
        ctl.step_arrays(np.zeros((4, 3)), np.zeros((4, 3)), 0.1)
    with pytest.raises(ValueError, match="longer than the buffers"):
        ctl.step_arrays(np.zeros((4, 3)), np.zeros((4, 3)), 0.1)


def test_replay_of_a_simulated_record_reproduces_the_closed_loop_commands(tmp_path):
    from robovib.io import read_milling_record_csv
    from robovib.milling.forces import ACETAL, CuttingConditions, MillingTool
    from robovib.sim import LinearMove, VirtualRobot, run_closed_loop
    from robovib.sim.disturbances import REALISTIC_LEVELS

    path, _ = _path_file(tmp_path)
    ctl = load_controller(path)
    tool, cond = MillingTool(), CuttingConditions(250.0, 0.3e-3, 3e-3, 6e-3)
    t = np.arange(1500) / 1000.0
    local = REALISTIC_LEVELS.cutting_force(t, tool, cond, ACETAL, rng=np.random.default_rng(3))
    force = np.column_stack([local[:, 1], -local[:, 0], local[:, 2]])
    move = LinearMove("workspace", (2.35, 0.30, 45.0), (2.35, 0.25, 50.0))
    planned = ctl.planned(250.0, tool.n_flutes)
    rec = run_closed_loop(VirtualRobot(), move, force, 1000.0, planned, rng=5,
                          force_noise_n=2.0, force_bias_n=5.0)  # fmt: skip
    assert np.max(np.abs(planned.commands_mm)) > 1e-4  # it did correct
    rec.to_csv(tmp_path / "cut.csv", digits=17)
    again = replay(load_controller(path), read_milling_record_csv(tmp_path / "cut.csv"),
                   spindle_rpm=250.0)  # fmt: skip
    np.testing.assert_allclose(again.commands_mm, planned.commands_mm, rtol=0, atol=1e-9)
    # the simulator applied exactly those commands, 32 ms late
    applied = rec.meta["commands_m"][32::4][: again.commands_mm.shape[0] - 8] * 1e3
    np.testing.assert_allclose(applied, again.commands_mm[: applied.shape[0]], atol=1e-12)
    assert set(again.rms_mm) == {"x", "z"}


def test_live_lookup_matches_the_planned_lookup_of_the_same_controller(tmp_path):
    """One controller, gains looked up per step (PathCursor) or tabulated for the run."""
    from robovib.control.design import assemble_controller

    path, _ = _path_file(tmp_path)
    ctl = load_controller(path)
    rng = np.random.default_rng(1)
    n = 300
    s = np.linspace(0.1, 0.6, n)
    ctl.reset(spindle_rpm=250.0, max_duration_s=2.0, nominal_s_m=s[n // 2])
    planned = assemble_controller("adaptive+force", ctl.tables, excitation_period_s=0.12,
                                  teeth=2, learner=ctl.learner_settings,
                                  tracker=ctl.tracker_settings)  # fmt: skip
    planned.reset(s, 0.004, 1000.0)
    tt = np.arange(4 * n) / 1000.0
    f = np.column_stack([np.sin(2 * np.pi * 8.3 * tt), np.cos(2 * np.pi * 16.6 * tt), 0.5 * tt])
    f = 100 * f + rng.normal(size=f.shape)
    y = 1e-5 * rng.normal(size=f.shape)
    for k in range(n):
        lo, hi = max(0, 4 * k - 3), 4 * k + 1
        u_ref = planned.command(k, y[lo:hi], f[lo:hi])
        u = ctl.step_arrays(f[lo:hi], y[lo:hi] * 1e3, s[k])
        np.testing.assert_allclose(u * 1e-3, u_ref, rtol=1e-9, atol=1e-15)


def test_cli_design_and_replay_on_a_logged_cut(tmp_path):
    from helpers import assert_self_describing
    from typer.testing import CliRunner

    from robovib.cli import app
    from robovib.milling.forces import ACETAL, CuttingConditions, MillingTool
    from robovib.sim import LinearMove, VirtualRobot, run_closed_loop
    from robovib.sim.disturbances import REALISTIC_LEVELS

    runner = CliRunner()
    ctl = tmp_path / "ctl.json"
    args = ["control", "design", "--start", "2350,400,30", "--end", "2350,0,80", "--points", "7",
            "--controller", "adaptive+force", "-o", str(ctl), "--json"]  # fmt: skip
    res = runner.invoke(app, args)
    assert res.exit_code == 0, res.output
    doc = json.loads(res.stdout)
    assert_self_describing(doc, args)
    assert doc["control_modes"] == {"x": "x", "z": "z"}
    # an open-loop cut, logged (no controller ran): what would the controller have sent?
    tool, cond = MillingTool(), CuttingConditions(250.0, 0.3e-3, 3e-3, 6e-3)
    t = np.arange(2000) / 1000.0
    local = REALISTIC_LEVELS.cutting_force(t, tool, cond, ACETAL, rng=np.random.default_rng(2))
    force = np.column_stack([local[:, 1], -local[:, 0], local[:, 2]])
    move = LinearMove("workspace", (2.35, 0.30, 42.5), (2.35, 0.25, 48.75))
    run_closed_loop(VirtualRobot(), move, force, 1000.0, None, rng=1).to_csv(tmp_path / "cut.csv")
    out = tmp_path / "cmds.csv"
    args = ["control", "replay", str(ctl), "--record", str(tmp_path / "cut.csv"), "--rpm", "250",
            "-o", str(out), "--json"]  # fmt: skip
    res = runner.invoke(app, args)
    assert res.exit_code == 0, res.output
    doc = json.loads(res.stdout)
    assert_self_describing(doc, args)
    assert doc["commands"] == 500 and set(doc["rms_mm"]) == {"x", "z"}
    cmds = np.loadtxt(out, delimiter=",", skiprows=1)
    assert cmds.shape == (500, 6)
    np.testing.assert_allclose(np.max(np.abs(cmds[:, 2:5]), axis=0),
                               [doc["peak_correction_mm"][d] for d in "xyz"])  # fmt: skip
    # the model's open-loop response to the logged force is the size of the logged vibration
    for d in "xz":
        assert 0.3 < doc["rms_mm"][d]["predicted_open"] / doc["rms_mm"][d]["measured"] < 3
    res = runner.invoke(app, ["control", "replay", str(ctl), "--record", str(tmp_path / "cut.csv")])
    assert res.exit_code == 1 and "spindle speed" in res.output


def test_gains_lead_with_a_design_stable_with_the_delay():
    from typer.testing import CliRunner

    from robovib.cli import app

    res = CliRunner().invoke(app, ["control", "gains", "--x", "2400", "--y", "0", "--rz", "45"])
    assert res.exit_code == 0, res.output
    first = res.stdout.splitlines()[1]
    assert first.startswith("stable with the 32 ms delay: delay-aware LQR")
    res = CliRunner().invoke(app, ["control", "schedule"])
    line = res.stdout.splitlines()[0]
    assert "m/m" in line and " s " in line and "stable with 32 ms delay: yes" in line
    assert "0.00001" not in res.stdout


def test_replay_of_a_cut_logged_without_the_controller_feeds_it_the_corrections_effect(tmp_path):
    """record_made="without": the controller sees the logged tracker plus the SDOF response of
    the file's mode to its own corrections, 32 ms late and held for a 4 ms cycle (checked
    against SciPy's ZOH discretisation and dlsim, not robovib's)."""
    from scipy import signal

    from robovib.milling.forces import ACETAL, CuttingConditions, MillingTool
    from robovib.sim.disturbances import REALISTIC_LEVELS

    path, _ = _path_file(tmp_path)
    ctl = load_controller(path)
    tool, cond = MillingTool(), CuttingConditions(250.0, 0.3e-3, 3e-3, 6e-3)
    t = np.arange(1500) / 1000.0
    local = REALISTIC_LEVELS.cutting_force(t, tool, cond, ACETAL, rng=np.random.default_rng(3))
    force = np.column_stack([local[:, 1], -local[:, 0], local[:, 2]])
    pose = np.tile([2.35, 0.28, 47.0], (t.size, 1))
    logged = np.zeros((t.size, 3))  # a tooth-passing vibration the controller can act on
    logged[:, [0, 2]] = 20e-6 * np.sin(2 * np.pi * (250.0 * 2 / 60) * t)[:, None]
    record = {"time_s": t, "force_n": force, "displacement_m": logged, "pose": pose}
    res = replay(ctl, record, spindle_rpm=250.0, record_made="without")
    assert np.max(np.abs(res.commands_mm)) > 1e-5  # it corrected
    s_mid = float(np.median(res.path_s_m))
    delay, every = 32, 4
    applied = np.zeros((t.size, 3))
    held = np.repeat(res.commands_mm * 1e-3, every, axis=0)[: t.size]
    applied[delay:] = held[: t.size - delay]
    for a in ctl.tables.axes:
        fn, zeta = ctl.tables.fz(a).at(np.array([s_mid]))[0]
        wn = 2 * np.pi * fn
        # x'' + 2 zeta wn x' + wn^2 x = wn^2 u: a correction u [m] moves the tool by u statically
        sys_d = signal.cont2discrete(
            tuple(
                np.array(m, float)
                for m in ([[0, 1], [-(wn**2), -2 * zeta * wn]], [[0], [wn**2]], [[1, 0]], [[0]])
            ),
            1e-3,
            "zoh",
        )
        _, y, _ = signal.dlsim((*sys_d[:4], 1e-3), applied[:, a])
        seen = (t.size - 1) // every * every + 1  # samples up to the last command
        np.testing.assert_allclose(
            res.tracker_fed_m[:seen, a] - logged[:seen, a], y[:seen, 0], rtol=1e-6, atol=1e-12
        )
    with_it = replay(load_controller(path), record, spindle_rpm=250.0, record_made="with")
    np.testing.assert_array_equal(with_it.tracker_fed_m, logged)
    with pytest.raises(ValueError, match="record_made"):
        replay(load_controller(path), record, spindle_rpm=250.0, record_made="maybe")


def test_the_closed_loop_study_reads_a_controller_file_through_the_library(tmp_path):
    """``control simulate milling --controller-file`` reaches the library's loader: a missing
    file is the loader's error, not an import error of the study (it imported
    ``robovib.studies.control.runtime``, which does not exist)."""
    from robovib.studies.control import simulate_control

    with pytest.raises(ValueError, match="no such controller file"):
        simulate_control("milling", controller_file=tmp_path / "missing.json")
