"""CLI safety behaviours that are not errors: --force, --keep-flagged, extrapolation flags, JSON."""

import hashlib
import json

import numpy as np
import pytest
from typer.testing import CliRunner

from robovib.cli import app
from robovib.frf import FRF
from robovib.io import read_frfs, write_frfs
from robovib.modal import ModalParameters

MODE = ModalParameters(16.5, 2e6, 0.04)


def _strict_json(text):
    def refuse(token):
        raise AssertionError(f"non-JSON token {token}")

    return json.loads(text, parse_constant=refuse)


def test_force_allows_replacing_the_input(tmp_path):
    from synthetic import hammer_hits

    from robovib.io import HammerRecording, write_recording_uff

    forces, responses = hammer_hits([(16.5, 2e6, 0.04)], fs=1024.0, duration_s=1.0, n_hits=2,
                                    width_s=4e-3)  # fmt: skip
    rec = tmp_path / "hits.uff"
    write_recording_uff(rec, HammerRecording(forces, responses, 1024.0, "acceleration", "x"))
    digest = hashlib.sha256(rec.read_bytes()).hexdigest()
    refused = CliRunner().invoke(app, ["frf", "compute", str(rec), "-o", str(rec)])
    assert refused.exit_code == 1 and "is the input file" in refused.output
    assert hashlib.sha256(rec.read_bytes()).hexdigest() == digest
    # an .uff output next to a .uff input: --force replaces the recording by the FRF
    res = CliRunner().invoke(app, ["frf", "compute", str(rec), "-o", str(rec), "--force"])
    assert res.exit_code == 0, res.output
    (frf,) = read_frfs(rec)
    assert frf.quantity == "compliance" and frf.direction == "x"


def test_flagged_fit_fails_unless_kept(tmp_path):
    f = np.arange(2.0, 60.0, 0.25)
    path = tmp_path / "inverted.h5"
    write_frfs(path, [FRF(f, -MODE.compliance(f), direction="x")])
    res = CliRunner().invoke(app, ["modal", "fit", str(path), "--json"])
    assert res.exit_code == 1
    errors = [ln for ln in res.output.splitlines() if ln.startswith("error:")]
    assert len(errors) == 1 and "flagged" in errors[0] and "--keep-flagged" in errors[0]
    kept = CliRunner().invoke(app, ["modal", "fit", str(path), "--json", "--keep-flagged"])
    assert kept.exit_code == 0
    doc = _strict_json(kept.stdout)
    dom = doc["frfs"][0]["dominant_mode"]
    assert dom["flagged"] is True and any("inverted sign" in x for x in dom["flags"])
    # a clean FRF is not flagged and exits 0
    write_frfs(path, [FRF(f, MODE.compliance(f), direction="x")], force=True)
    ok = CliRunner().invoke(app, ["modal", "fit", str(path), "--json"])
    assert ok.exit_code == 0
    assert _strict_json(ok.stdout)["frfs"][0]["dominant_mode"]["flags"] == []


@pytest.mark.parametrize(
    "argv",
    [
        ["mill", "predict", "--x", "99999", "--y", "0", "--rz", "0", "--samples", "2", "--json"],
        ["mill", "lobes", "--x", "99999", "--y", "0", "--rz", "0", "--json"],
        ["control", "gains", "--x", "99999", "--y", "0", "--rz", "0", "--json"],
    ],
    ids=["mill-predict", "mill-lobes", "control-gains"],
)
def test_predictions_outside_the_workspace_are_flagged(argv):
    res = CliRunner().invoke(app, argv)
    assert res.exit_code == 0, res.output
    doc = _strict_json(res.stdout)
    assert doc["extrapolation"] == ["x_mm"]
    inside = CliRunner().invoke(app, [a if a != "99999" else "2400" for a in argv])
    assert _strict_json(inside.stdout)["extrapolation"] == []


def test_cli_json_never_writes_nan_or_infinity(capsys):
    """Every --json document goes through emit_json: non-finite numbers become null + reason."""
    from robovib.cli._common import emit_json

    emit_json({"depth_m": [0.002, float("inf")], "band_mm": (float("nan"), 1.0), "n": np.int64(2)})
    text = capsys.readouterr().out
    assert "Infinity" not in text and "NaN" not in text
    doc = _strict_json(text)
    assert doc["depth_m"] == [0.002, None] and doc["band_mm"] == [None, 1.0] and doc["n"] == 2
    assert set(doc["null_reasons"]) == {"depth_m[1]", "band_mm[0]"}
    assert "infinity" in doc["null_reasons"]["depth_m[1]"]
