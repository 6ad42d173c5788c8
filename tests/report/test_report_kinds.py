"""``robovib report chapter3|model|lobes|control``: each page loads in headless Chromium with
its tables and non-empty figures, and carries settings and provenance (small settings: fast)."""

from __future__ import annotations

import json

import matplotlib
import numpy as np
import pytest
from browser import assert_page_ok
from helpers import assert_self_describing
from typer.testing import CliRunner

from robovib.cli import app

matplotlib.use("Agg")
runner = CliRunner()


def report(tmp_path, kind: str, *args: str) -> tuple:
    out = tmp_path / f"{kind}.html"
    result = runner.invoke(app, ["report", kind, *args, "-o", str(out), "--json"])
    assert result.exit_code == 0, result.output
    doc = json.loads(result.stdout)
    assert_self_describing(doc, ["report", kind, *args, "-o", str(out), "--json"])
    assert doc["output"] == str(out)
    text = out.read_text()
    assert "Settings" in text and "Provenance" in text and "robovib_version" in text
    assert "robovib report " + kind in text  # the command that made it
    return out, text


@pytest.mark.browser
def test_chapter3_report(tmp_path):
    out, text = report(tmp_path, "chapter3", "--n-splits", "2", "--no-mode-switch")
    assert "Thesis Table 2" in text
    assert_page_ok(out, "report_chapter3.png")


@pytest.mark.browser
def test_lobes_report(tmp_path):
    out, text = report(tmp_path, "lobes", "--x", "2400", "--y", "0", "--rz", "45",
                       "--rpm-range", "500:2500:40")  # fmt: skip
    assert "depth stable at every speed [mm]" in text and "x_mm" in text
    assert_page_ok(out, "report_lobes.png")
    # One stability answer per question: the page and `mill lobes` agree at the same settings.
    res = runner.invoke(app, ["mill", "lobes", "--x", "2400", "--y", "0", "--rz", "45",
                              "--rpm-range", "500:2500:40", "--json"])  # fmt: skip
    assert res.exit_code == 0, res.output
    mill = json.loads(res.stdout)
    row = text.split("depth stable at every speed [mm]", 1)[1]
    shown = float(row.split("<td>", 1)[1].split("<", 1)[0])
    assert shown == pytest.approx(1e3 * mill["minimum_depth_m"], abs=1e-3)
    assert f"<td>{mill['method']}</td>" in text


@pytest.mark.browser
def test_control_report(tmp_path):
    from robovib.io import write_path_modes_csv
    from robovib.modal import ModalParameters

    s = np.linspace(0.335, 1.235, 6)
    write_path_modes_csv(tmp_path / "m.csv", s, [ModalParameters(f, 2e6, 0.05) for f in 14 + 4 * s])
    out, text = report(tmp_path, "control", "--path-file", str(tmp_path / "m.csv"))
    assert "w1_m_per_m" in text and "thesis_w1" in text
    assert "sha256" in text  # the path file is hashed
    assert_page_ok(out, "report_control.png", min_figures=1)


@pytest.mark.browser
def test_model_report_pose_model(tmp_path):
    """A user's pose model (campaign format) fitted on a known smooth truth."""
    from robovib.gp import PoseModalModel

    rng = np.random.default_rng(0)
    X = np.column_stack(
        [rng.uniform(2100, 2700, 25), rng.uniform(-300, 600, 25), rng.uniform(0, 180, 25)]
    )
    fn = 10 + X[:, 0] / 300.0
    Y = np.column_stack([fn, 2e6 * (1 + X[:, 1] / 3000), 1e3 * (1 + X[:, 2] / 900)])
    model = PoseModalModel(directions=("x",), mode_switch=False).fit(X, Y)
    model.save(tmp_path / "pose.h5")
    out, text = report(tmp_path, "model", str(tmp_path / "pose.h5"))
    assert "x_fn_hz" in text and "x_mm" in text
    assert_page_ok(out, "report_model.png")


@pytest.mark.browser
def test_model_report_hybrid_frf_model(tmp_path):
    from robovib.hybrid import FRFPoseModel
    from robovib.modal import ModalParameters

    f = np.linspace(2, 40, 20)
    s = np.array([0.0, 0.6, 1.2])
    h = np.array([ModalParameters(15 + 5 * si, 2e6, 0.05).compliance(f) for si in s])
    FRFPoseModel(f).fit(s, h).save(tmp_path / "frf_model.h5")
    out, text = report(tmp_path, "model", str(tmp_path / "frf_model.h5"))
    assert "peak_compliance_um_per_n" in text
    assert_page_ok(out, "report_frf_model.png")


def test_model_report_rejects_other_files(tmp_path):
    import h5py

    with h5py.File(tmp_path / "x.h5", "w") as h5:
        h5.attrs["format"] = "something-else"
    result = runner.invoke(
        app, ["report", "model", str(tmp_path / "x.h5"), "-o", str(tmp_path / "r.html")]
    )
    assert result.exit_code == 1 and "not a robovib pose model" in result.stderr
    assert not (tmp_path / "r.html").exists()


@pytest.mark.parametrize("kind", ["chapter3", "model", "lobes", "control"])
def test_every_kind_has_help(kind):
    assert runner.invoke(app, ["report", kind, "--help"]).exit_code == 0
