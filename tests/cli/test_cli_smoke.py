"""One ``--json`` run per CLI command with fast settings: exit code, JSON document, key fields.

The chapter-3 model is fitted once for the session (commands that fit it get the memoised one).
"""

from __future__ import annotations

import ast
import json
from pathlib import Path

import numpy as np
import pytest
from helpers import assert_self_describing
from typer.testing import CliRunner

from robovib.cli import app
from robovib.datasets import example_path
from robovib.studies.hybrid import MODELS

runner = CliRunner()


@pytest.fixture(scope="module", autouse=True)
def _memoised_chapter3(chapter3_factory, chapter3_regressor_factory):
    mp = pytest.MonkeyPatch()
    mp.setattr("robovib.gp.fit_chapter3_model", chapter3_factory)
    mp.setattr("robovib.studies.chapter3.fit_chapter3_regressor", chapter3_regressor_factory)
    yield
    mp.undo()


def run_json(*args: str) -> dict:
    argv = [*args, "--json"]
    result = runner.invoke(app, argv)
    assert result.exit_code == 0, result.output
    text = result.stdout
    assert "NaN" not in text and "Infinity" not in text
    doc = json.loads(text)
    assert_self_describing(doc, argv)
    return doc


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """Hammer recordings and FRFs along the path, shared by the frf/modal/hybrid commands."""
    d = tmp_path_factory.mktemp("cli")
    for s in ("0", "0.585", "1.235"):
        run_json("sim", "hammer", "--path-s", s, "--hits", "2", "--sample-rate-hz", "1024",
                 "-o", str(d / f"e{s}.uff"))  # fmt: skip
        run_json("frf", "compute", str(d / f"e{s}.uff"), "--path-s", s, "--fmax", "60",
                 "-o", str(d / f"e{s}.h5"))  # fmt: skip
    return d


def test_version_and_help_units():
    result = runner.invoke(app, ["--version"])
    assert result.exit_code == 0 and result.stdout.startswith("robovib ")
    hammer_help = runner.invoke(app, ["sim", "hammer", "--help"])
    assert hammer_help.exit_code == 0, hammer_help.output
    assert "error" not in hammer_help.output
    assert "[mm]" in hammer_help.stdout
    assert "[w1, w2]" in runner.invoke(app, ["control", "gains", "--help"]).stdout
    assert "[dB]" in runner.invoke(app, ["sim", "hammer", "--help"]).stdout


def test_library_error_is_one_line_exit_1(tmp_path):
    result = runner.invoke(app, ["modal", "fit", str(tmp_path / "missing.h5")])
    assert result.exit_code == 1
    assert result.stderr.startswith("error: ") and result.stderr.count("\n") == 1
    result = runner.invoke(app, ["sim", "hammer", "-o", str(tmp_path / "x.foo")])
    assert result.exit_code == 1 and "unknown output format" in result.stderr


def test_examples_listed_and_copied(tmp_path):
    doc = run_json("examples")
    assert len(doc["examples"]) >= 6
    doc = run_json("examples", "--to", str(tmp_path / "ex"))
    assert (tmp_path / "ex" / "hammer.uff").is_file()
    doc = run_json(
        "frf", "compute", str(tmp_path / "ex" / "hammer.uff"), "-o", str(tmp_path / "f.h5")
    )
    assert doc["direction"] == "x" and doc["input_files"][0]["path"].endswith("hammer.uff")
    doc = run_json("modal", "fit", str(tmp_path / "ex" / "frf.csv"))
    assert 10 < doc["frfs"][0]["dominant_mode"]["natural_frequency_hz"] < 25


def test_plot_without_matplotlib_prints_results_then_one_line_error(tmp_path, monkeypatch):
    import sys

    for name in [m for m in sys.modules if m == "matplotlib" or m.startswith("matplotlib.")]:
        monkeypatch.delitem(sys.modules, name)
    monkeypatch.setitem(sys.modules, "matplotlib", None)  # import matplotlib -> ImportError
    frf = str(example_path("frf.csv"))
    result = runner.invoke(app, ["modal", "fit", frf, "--plot", str(tmp_path / "f.png")])
    assert result.exit_code == 1
    assert "Dominant mode" in result.stdout and "16." in result.stdout  # the fit came first
    assert result.stderr.count("\n") == 1 and "pip install 'robovib[plot]'" in result.stderr
    result = runner.invoke(app, ["modal", "fit", frf, "--json", "--plot", str(tmp_path / "f.png")])
    assert result.exit_code == 1 and json.loads(result.stdout)["frfs"][0]["dominant_mode"]
    assert not (tmp_path / "f.png").exists()


def test_gpr_predict():
    doc = run_json("gpr", "predict", "--x", "2400", "--y", "0", "--rz", "45")
    assert len(doc["predictions"]) == 9 and doc["extrapolating"] is False


def test_sim_hammer_csv_and_frf_compute_modal_fit(tmp_path):
    doc = run_json("sim", "hammer", "--hits", "2", "--sample-rate-hz", "1024", "--duration-s", "2",
                   "-o", str(tmp_path / "h.csv"))  # fmt: skip
    assert doc["hits"] == 2 and doc["samples_per_hit"] == 2048
    doc = run_json("frf", "compute", str(tmp_path / "h.csv"), "--direction", "x",
                   "-o", str(tmp_path / "f.h5"))  # fmt: skip
    assert doc["n_averaged"] == 2 and doc["direction"] == "x"
    doc = run_json("modal", "fit", str(tmp_path / "f.h5"))
    fn = doc["frfs"][0]["dominant_mode"]["natural_frequency_hz"]
    assert 5 < fn < 100


def test_sim_mill_and_offset_mass_along_path(tmp_path):
    doc = run_json("sim", "mill", "--path-s-from", "0.635", "--path-s-to", "0.735", "--rpm", "2700",
                   "--fz", "0.3", "--ap", "6", "--ae", "6", "--material", "acetal",
                   "-o", str(tmp_path / "cut.csv"))  # fmt: skip
    assert doc["samples"] > 0 and len(doc["mean_deflection_mm"]) == 3
    doc = run_json("sim", "offset-mass", "--path-s-from", "1.235", "--path-s-to", "1.135",
                   "-o", str(tmp_path / "om.csv"))  # fmt: skip
    assert len(doc["peak_vibration_mm"]) == 3
    doc = run_json("hybrid", "oma", str(tmp_path / "cut.csv"), "--rpm", "2700",
                   "-o", str(tmp_path / "oma.h5"))  # fmt: skip
    assert doc["segments"] >= 1 and 0 <= doc["flagged_fraction"] <= 1


def test_sim_mill_needs_both_path_ends(tmp_path):
    result = runner.invoke(
        app, ["sim", "mill", "--path-s-from", "0.6", "-o", str(tmp_path / "c.csv")]
    )
    assert result.exit_code != 0 and "--path-s-to" in result.output


def test_robot_commands(tmp_path):
    doc = run_json(
        "robot", "fk", "--joints", "-0.11", "-27.46", "94.04", "179.42", "66.83", "-0.58"
    )
    assert len(doc["tool_tip_mm"]) == 3
    doc = run_json("robot", "ik", "--x", "2400", "--y", "0", "--rz", "45")
    assert len(doc["joints_deg"]) == 6
    doc = run_json("robot", "stiffness", "--x", "2400", "--y", "0", "--rz", "45")
    assert set(doc["directional_stiffness_n_per_m"]) == {"x", "y", "z"}
    doc = run_json("robot", "compare")
    assert set(doc["summary"]) >= {"fn_x", "stiffness_z"}


def test_robot_identify_recovers_joint_stiffness(tmp_path):
    from robovib.robot import KR500
    from robovib.robot.dynamics import TABLE_4_JOINT_STIFFNESS, cartesian_stiffness

    robot = KR500()
    rng = np.random.default_rng(0)
    rows = []
    for _ in range(6):
        q = robot.ik(np.array([2.4, rng.uniform(-0.3, 0.6), 0.325]), np.diag([1.0, -1.0, -1.0]))
        k = cartesian_stiffness(robot, q)
        for w in np.eye(6) * 1000.0:
            d = np.linalg.solve(k, w)
            rows.append([*q, *w, *d])
    header = [f"a{i}_deg" for i in range(1, 7)] + ["fx_n", "fy_n", "fz_n", "mx_nm", "my_nm",
                                                    "mz_nm", "dx_m", "dy_m", "dz_m", "rx_rad", "ry_rad", "rz_rad"]  # fmt: skip
    path = tmp_path / "tests.csv"
    np.savetxt(path, np.array(rows), delimiter=",", header=",".join(header), comments="")
    doc = run_json("robot", "identify", str(path))
    np.testing.assert_allclose(
        doc["joint_stiffness_n_m_per_rad"], TABLE_4_JOINT_STIFFNESS, rtol=0.05
    )


def test_mill_commands(tmp_path):
    doc = run_json("mill", "predict", "--x", "2700", "--y", "0", "--rz", "0", "--samples", "5")
    assert [r["direction"] for r in doc["predictions"]] == ["x", "y", "z"]
    doc = run_json("mill", "lobes", "--x", "2400", "--y", "0", "--rz", "45")
    assert doc["minimum_depth_m"] > 0 and len(doc["rpm"]) == len(doc["a_lim_m"]) == 200
    doc = run_json("mill", "map", "--nx", "3", "--ny", "2", "--plot", str(tmp_path / "map.png"))
    assert np.shape(doc["critical_depth_m"]) == (2, 3) and (tmp_path / "map.png").stat().st_size


def test_mill_plan_and_detect(tmp_path):
    """A short planned path and a simulated record's chatter labels, each self-describing."""
    doc = run_json("mill", "plan", "--start", "2150,-250", "--end", "2650,500", "--segments", "5",
                   "-o", str(tmp_path / "plan.csv"))  # fmt: skip
    assert (tmp_path / "plan.csv").stat().st_size > 0 and doc
    run_json("sim", "mill", "--x0", "2300", "--x1", "2400", "--ap", "2", "--ae", "6",
             "-o", str(tmp_path / "rec.csv"))  # fmt: skip
    doc = run_json("mill", "detect", str(tmp_path / "rec.csv"), "--rpm", "1750")
    assert doc


def test_control_gains_table9_and_schedule_file(tmp_path):
    from robovib.io import write_path_modes_csv
    from robovib.modal import ModalParameters

    doc = run_json("control", "gains", "--x", "2400", "--y", "0", "--rz", "45")
    assert {"w1", "w2", "stable_with_delay"} <= set(doc)
    doc = run_json("control", "table9")
    assert len(doc["rows"]) > 0 and "thesis_w1" in doc["rows"][0]
    s = np.linspace(0.335, 1.235, 6)
    write_path_modes_csv(tmp_path / "m.csv", s, [ModalParameters(f, 2e6, 0.05) for f in 14 + 4 * s])
    doc = run_json("control", "schedule", "--path-file", str(tmp_path / "m.csv"))
    np.testing.assert_allclose(doc["s_m"], s)
    assert len(doc["w1"]) == 6
    # A line through a pose model (here the shipped chapter-3 model, saved as a user's file).
    from robovib.gp import get_chapter3_model

    get_chapter3_model().save(tmp_path / "robot.h5")
    line = ["--start", "2400,-200,0", "--end", "2400,400,0", "--points", "7"]
    doc = run_json("control", "schedule", *line, "--model", str(tmp_path / "robot.h5"))
    np.testing.assert_allclose(doc["s_m"], np.linspace(0.0, 0.6, 7))
    assert doc["input_names"] == ["x_mm", "y_mm", "rz_deg"] and len(doc["extrapolating"]) == 7
    # default: the same model (the shipped file and its re-saved copy agree to ~1e-13, not bitwise)
    np.testing.assert_allclose(doc["w1"], run_json("control", "schedule", *line)["w1"], rtol=1e-9)


def test_hybrid_fit_update_predict_next_poses(files, tmp_path):
    ema = [str(files / f"e{s}.h5") for s in ("0", "1.235")]
    doc = run_json("hybrid", "fit", *ema, "--fmax", "30", "-o", str(tmp_path / "m.h5"))
    assert doc["n_frfs"] == 2
    # an EMA file is refused as OMA data (issue 18); relabel a copy as an OMA measurement
    from dataclasses import replace

    from robovib.io import read_frfs, write_frfs

    err = CliRunner().invoke(app, ["hybrid", "update", str(tmp_path / "m.h5"),
                                   str(files / "e0.585.h5"), "-o", str(tmp_path / "m2.h5")])  # fmt: skip
    assert err.exit_code != 0 and "expects OMA" in err.output
    oma = tmp_path / "o0.585.h5"
    write_frfs(oma, [replace(f, source="OMA") for f in read_frfs(files / "e0.585.h5")])
    doc = run_json("hybrid", "update", str(tmp_path / "m.h5"), str(oma),
                   "--mode", "posterior", "-o", str(tmp_path / "m2.h5"))  # fmt: skip
    assert doc["n_oma"] == 1
    doc = run_json("hybrid", "predict", str(tmp_path / "m2.h5"), "--path-s", "0.585",
                   "--measured", str(files / "e0.585.h5"), "--plot", str(tmp_path / "p.png"))  # fmt: skip
    assert doc["s_m"] == 0.585 and doc["rmse_um_per_n"] >= 0 and not doc["extrapolating"]
    doc = run_json("hybrid", "next-poses", "--k", "2", "--path-s", "0", "--path-s", "1.235")
    assert doc["tested_s_m"] == [0.0, 1.235] and len(doc["next_s_m"]) == 2


@pytest.mark.slow
def test_slow_studies():
    assert len(run_json("control", "simulate", "milling")["rows"]) > 0
    assert len(run_json("control", "simulate", "offset-mass")["rows"]) > 0
    study = run_json("hybrid", "study")  # seed 0, background 1, every model
    assert {"settings", "result_settings", "rows", "summary"} <= set(study)
    assert study["result_settings"]["seeds"] == [0]
    pairs = {(r["direction"], r["model"]) for r in study["rows"]}
    assert pairs == {(d, m) for d in "xyz" for m in MODELS}
    assert len(study["rows"]) == len(pairs)
    assert {(r["direction"], r["model"]) for r in study["summary"]} == pairs
    bg = run_json("hybrid", "study", "--background", "0.5,2", "--seeds", "0")
    assert bg["result_settings"]["backgrounds"] == [0.5, 2.0]
    assert {(r["background"], r["direction"]) for r in bg["summary"]} == {
        (b, d) for b in (0.5, 2.0) for d in "xyz"
    }
    assert all(0.0 <= r["held_back_fraction"] <= 1.0 for r in bg["summary"])
    assert len(run_json("demo")["outputs"]) == 9
    assert len(run_json("control", "schedule")["w1"]) == 20


#: Slow commands: their --json documents are checked in test_slow_studies (``-m slow``).
SLOW_COMMANDS = {"demo", "control simulate", "hybrid study"}
#: Checked with assert_self_describing in tests/report/test_report_kinds.py, test_cli_campaign.py
#: and test_control_runtime.py.
ELSEWHERE = {"report chapter3", "report model", "report lobes", "report control",
             "sim campaign", "campaign process", "model fit", "model next-poses",
             "control design", "control replay"}  # fmt: skip


def _leaf_commands() -> set[str]:
    import typer

    def walk(cmd, prefix):
        subs = getattr(cmd, "commands", None)
        if not subs:
            return {" ".join(prefix)}
        return set().union(*(walk(c, [*prefix, n]) for n, c in subs.items()))

    return walk(typer.main.get_command(app), [])


def commands_run_in(source: str) -> set[str]:
    """Command paths (``"frf compute"``) of the ``run_json(...)`` calls written in ``source``:
    the leading string arguments that are not options (as the CLI reads them)."""
    found = set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Call) and getattr(node.func, "id", None) == "run_json":
            words = []
            for arg in node.args[:2]:
                if not (isinstance(arg, ast.Constant) and isinstance(arg.value, str)):
                    break
                if not arg.value.startswith("-"):
                    words.append(arg.value)
            if words:
                found.add(" ".join(words))
    return found


def test_json_provenance_on_every_command():
    """Every command has a --json smoke run (run_json, which checks assert_self_describing) in
    this module: read from the source, so the test checks the same alone, under ``-k`` or in
    any order (each run asserts in its own test)."""
    leaves = _leaf_commands()
    fast = leaves - SLOW_COMMANDS - ELSEWHERE
    assert SLOW_COMMANDS <= leaves and ELSEWHERE <= leaves
    here = commands_run_in(Path(__file__).read_text(encoding="utf-8"))
    assert fast | SLOW_COMMANDS <= here, (
        f"commands without a --json smoke run: {sorted((fast | SLOW_COMMANDS) - here)}"
    )


def test_command_coverage_check_can_fail():
    """A module without a run of ``frf compute`` is seen to lack it."""
    planted = 'def test_a():\n    run_json("frf", "modal", "x.h5")\n    run_json("demo")\n'
    planted += (
        'def test_b(p):\n    run_json(str(p), "fit")\n    run_json("examples", "--to", "d")\n'
    )
    assert commands_run_in(planted) == {"frf modal", "demo", "examples"}
    assert "frf compute" not in commands_run_in(planted)
