"""HDF5 outputs carry units on every dataset and a provenance group (version, command,
settings, SHA-256 of the inputs), from the CLI and from library use."""

from __future__ import annotations

import hashlib

import h5py
import numpy as np
from typer.testing import CliRunner

from robovib import __version__
from robovib.cli import app
from robovib.datasets import example_path
from robovib.files.provenance import read_provenance, unit_of_key
from robovib.frf import FRF
from robovib.io import read_frfs, write_frfs


def _datasets(h5):
    out = []
    h5.visititems(
        lambda name, obj: out.append((name, obj)) if isinstance(obj, h5py.Dataset) else None
    )
    return out


def test_frf_compute_writes_units_and_provenance(tmp_path):
    rec = example_path("hammer.uff")
    out = tmp_path / "f.h5"
    argv = ["frf", "compute", str(rec), "--fmax", "80", "-o", str(out)]
    result = CliRunner().invoke(app, argv)
    assert result.exit_code == 0, result.output
    prov = read_provenance(out)
    assert prov["robovib_version"] == __version__
    assert prov["command"] == ["robovib", *argv]
    assert prov["settings"]["f_max_hz"] == 80.0 and prov["units"]["f_max_hz"] == "Hz"
    (item,) = prov["input_files"]
    assert item["path"] == str(rec)
    assert item["sha256"] == hashlib.sha256(rec.read_bytes()).hexdigest()
    with h5py.File(out) as h5:
        units = {name.split("/")[-1]: obj.attrs.get("units") for name, obj in _datasets(h5)}
    assert units["frequency_hz"] == "Hz" and units["values"] == "m/N" and units["coherence"] == "1"
    assert all(units.values()), units
    assert read_frfs(out)[0].direction == "x"  # the reader ignores the provenance group


def test_library_writer_records_argv_and_given_inputs(tmp_path):
    f = np.linspace(1, 10, 10)
    write_frfs(tmp_path / "a.h5", [FRF(f, 1e-6 / (1 + 1j * f), meta={"path_s_m": 0.5})])
    prov = read_provenance(tmp_path / "a.h5")
    assert prov["command"] and prov["input_files"] == [] and prov["settings"] == {}


def test_hybrid_model_file_has_units_and_provenance(tmp_path):
    from robovib.hybrid import FRFPoseModel

    f = np.linspace(2, 40, 12)
    h = np.array([(1 + s) * 1e-6 / (1 - (f / 15) ** 2 + 0.1j * f / 15) for s in (0.0, 1.2)])
    FRFPoseModel(f).fit(np.array([0.0, 1.2]), h).save(tmp_path / "m.h5")
    with h5py.File(tmp_path / "m.h5") as h5:
        missing = [n for n, d in _datasets(h5) if not d.attrs.get("units")]
        assert "provenance" in h5
    assert missing == []
    FRFPoseModel.load(tmp_path / "m.h5")  # loads past the provenance group


def test_unit_suffixes():
    assert unit_of_key("stiffness_n_per_m") == "N/m"
    assert unit_of_key("damping_ns_per_m") == "N s/m"
    assert unit_of_key("peak_compliance_um_per_n") == "um/N"
    assert unit_of_key("s_m") == "m" and unit_of_key("x_mm") == "mm"
    assert unit_of_key("w1") is None and unit_of_key("hits") is None
