"""File formats: UFF 58 (pyuff), CSV and HDF5, round trips and independently written files."""

import json

import numpy as np
import pytest
import pyuff
from synthetic import hammer_hits
from typer.testing import CliRunner

from robovib.cli import app
from robovib.frf import FRF
from robovib.io import (
    HammerRecording,
    read_frfs,
    read_recording,
    read_recording_csv,
    si_factor,
    write_frfs,
    write_recording_uff,
)

MODE = (18.0, 1.5e6, 0.04)


@pytest.fixture
def recording():
    forces, responses = hammer_hits([MODE], n_hits=3, duration_s=4.0)
    return HammerRecording(forces, responses, 2048.0, "acceleration", "y")


def test_recording_uff_round_trip(tmp_path, recording):
    path = tmp_path / "hits.uff"
    write_recording_uff(path, recording)
    back = read_recording(path)
    assert back.n_hits == 3 and back.direction == "y"
    assert back.sample_rate_hz == pytest.approx(2048.0, rel=1e-5)  # UFF ASCII: 6-digit increment
    np.testing.assert_allclose(back.forces, recording.forces, rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(back.responses, recording.responses, rtol=1e-6, atol=1e-12)


@pytest.mark.oracle
def test_reads_uff_written_by_pyuff_with_other_units(tmp_path):
    """A file prepared with pyuff directly (accelerations in g, force in kN) is converted to SI."""
    fs, n = 1000.0, 512
    x = np.arange(n) / fs
    force_kn = np.exp(-(((x - 0.05) / 0.001) ** 2))
    acc_g = np.sin(2 * np.pi * 20 * x) * np.exp(-x)
    sets = [
        pyuff.prepare_58(binary=0, func_type=1, load_case_id=7, rsp_node=3, rsp_dir=3, ref_node=3, ref_dir=3,
                         ordinate_spec_data_type=13, ordinate_axis_units_lab="kN", orddenom_spec_data_type=0, data=force_kn, x=x),
        pyuff.prepare_58(binary=0, func_type=1, load_case_id=7, rsp_node=3, rsp_dir=3, ref_node=3, ref_dir=3,
                         ordinate_spec_data_type=12, ordinate_axis_units_lab="g", orddenom_spec_data_type=0, data=acc_g, x=x),
    ]  # fmt: skip
    path = tmp_path / "ext.uff"
    pyuff.UFF(str(path)).write_sets(sets, mode="add")
    rec = read_recording(path)
    assert rec.direction == "z" and rec.response_quantity == "acceleration"
    np.testing.assert_allclose(rec.forces[0], force_kn * 1e3, rtol=1e-6, atol=1e-6)
    np.testing.assert_allclose(rec.responses[0], acc_g * 9.80665, rtol=1e-6, atol=1e-9)


def test_uff_mismatched_sampling_rates_rejected(tmp_path):
    x1, x2 = np.arange(100) / 1000.0, np.arange(100) / 2000.0
    sets = [
        pyuff.prepare_58(binary=0, func_type=1, load_case_id=0, rsp_node=1, rsp_dir=1, ref_node=1, ref_dir=1,
                         ordinate_spec_data_type=13, ordinate_axis_units_lab="N", orddenom_spec_data_type=0, data=np.ones(100), x=x1),
        pyuff.prepare_58(binary=0, func_type=1, load_case_id=0, rsp_node=1, rsp_dir=1, ref_node=1, ref_dir=1,
                         ordinate_spec_data_type=12, ordinate_axis_units_lab="m/s^2", orddenom_spec_data_type=0, data=np.ones(100), x=x2),
    ]  # fmt: skip
    path = tmp_path / "bad.uff"
    pyuff.UFF(str(path)).write_sets(sets, mode="add")
    with pytest.raises(ValueError, match="mismatched sampling rates"):
        read_recording(path)


def test_corrupt_files_rejected(tmp_path):
    bad = tmp_path / "junk.uff"
    bad.write_text("    -1\n    58\nthis is not a dataset\n")
    with pytest.raises(ValueError, match=r"UFF|dataset 58"):
        read_recording(bad)
    h5 = tmp_path / "junk.h5"
    h5.write_bytes(b"not hdf5 at all")
    with pytest.raises(ValueError, match="HDF5"):
        read_frfs(h5)
    with pytest.raises(ValueError, match="unknown FRF file format"):
        read_frfs(tmp_path / "a.mat")


def test_csv_recording(tmp_path):
    fs = 1000.0
    t = np.arange(200) / fs
    lines = ["hit,time_ms,force_n,acceleration_g"]
    for hit in (0, 1):
        lines += [f"{hit},{ti * 1e3},{np.sin(ti)},{np.cos(ti)}" for ti in t]
    path = tmp_path / "rec.csv"
    path.write_text("\n".join(lines))
    rec = read_recording_csv(path, "x")
    assert rec.n_hits == 2 and rec.sample_rate_hz == pytest.approx(fs)
    np.testing.assert_allclose(rec.responses[1], np.cos(t) * 9.80665, rtol=1e-9)
    path.write_text("time_s,force_n,acceleration_furlongs\n0,1,1\n0.001,1,1\n")
    with pytest.raises(ValueError, match="unknown unit"):
        read_recording_csv(path)
    path.write_text("time_s,force_n,acceleration_g\n0,1,1\n0.001,1,1\n0.0035,1,1\n")
    with pytest.raises(ValueError, match="not uniformly sampled"):
        read_recording_csv(path)
    path.write_text("time_s,force_n,acceleration_g\n0,1,nan\n0.001,1,1\n")
    with pytest.raises(ValueError, match="NaN"):
        read_recording_csv(path)


def test_units():
    assert si_factor("mm/s^2") == ("acceleration", 1e-3)
    with pytest.raises(ValueError, match="is a force unit"):
        si_factor("N", "acceleration")
    with pytest.raises(ValueError, match="unknown unit"):
        si_factor("mV")


def test_frf_collection_round_trip(tmp_path):
    f = np.arange(1.0, 60.0, 0.25)
    frfs = [
        FRF(
            f,
            1e-6 / (1 + 1j * f),
            coherence=np.full(f.size, 0.95),
            direction="x",
            pose=(2.4, 0.0, 0.325, 0, 0, 45),
        ),
        FRF(
            f, 2e-6 / (1 + 1j * f), direction="z", source="OMA", n_averages=12, exp_window_tau_s=0.3
        ),
    ]
    for ext in ("h5", "uff"):
        path = tmp_path / f"c.{ext}"
        write_frfs(path, frfs)
        back = read_frfs(path)
        assert [b.direction for b in back] == ["x", "z"]
        assert back[0].pose == pytest.approx(frfs[0].pose)
        for a, b in zip(frfs, back, strict=True):
            np.testing.assert_allclose(b.values, a.values, rtol=1e-9)
    back = read_frfs(tmp_path / "c.h5")
    assert back[1].source == "OMA" and back[1].n_averages == 12 and back[1].exp_window_tau_s == 0.3
    import h5py

    import robovib

    with h5py.File(tmp_path / "c.h5") as h5:  # every HDF5 output says its units and version
        assert h5.attrs["robovib_version"] == robovib.__version__ and "m/N" in h5.attrs["units"]


def test_cli_frf_compute_and_modal_fit(tmp_path, recording):
    runner = CliRunner()
    rec_path = tmp_path / "hits.uff"
    write_recording_uff(rec_path, recording)
    out = tmp_path / "frf.h5"
    res = runner.invoke(
        app, ["frf", "compute", str(rec_path), "--direction", "y", "-o", str(out), "--json"]
    )
    assert res.exit_code == 0, res.output
    doc = json.loads(res.output)
    assert doc["n_averaged"] == 3 and doc["direction"] == "y"
    png = tmp_path / "fit.png"
    res = runner.invoke(app, ["modal", "fit", str(out), "--json", "--plot", str(png)])
    assert res.exit_code == 0, res.output
    mode = json.loads(res.output)["frfs"][0]["dominant_mode"]
    assert mode["natural_frequency_hz"] == pytest.approx(MODE[0], rel=0.005)
    assert mode["stiffness_n_per_m"] == pytest.approx(MODE[1], rel=0.03)
    assert png.stat().st_size > 1000
    res = runner.invoke(app, ["modal", "fit", str(tmp_path / "missing.h5")])
    assert res.exit_code == 1 and "error" in res.output


def test_voltage_channels_need_and_use_sensitivities(tmp_path):
    from robovib.io import Sensitivity

    fs = 1000.0
    t = np.arange(100) / fs
    path = tmp_path / "volts.csv"
    lines = ["time_s,force_mv,acceleration_v"] + [
        f"{ti},{225.0 * np.sin(ti)},{0.1 * np.cos(ti)}" for ti in t
    ]
    path.write_text("\n".join(lines))
    with pytest.raises(ValueError, match="sensitivity"):
        read_recording_csv(path)
    rec = read_recording_csv(path, force_sensitivity=Sensitivity(2.25, "N"),
                             response_sensitivity=Sensitivity(10.0, "g"))  # fmt: skip
    np.testing.assert_allclose(rec.forces[0], 100.0 * np.sin(t), rtol=1e-9)  # 225 mV / 2.25 mV/N
    np.testing.assert_allclose(
        rec.responses[0], 10.0 * np.cos(t) * 9.80665, rtol=1e-9
    )  # 100 mV / 10 mV/g
    with pytest.raises(ValueError, match="is force"):
        read_recording_csv(
            path,
            force_sensitivity=Sensitivity(2.25, "g"),
            response_sensitivity=Sensitivity(10.0, "g"),
        )


# --- CSV tables moved out of the CLI (robovib.io.tables) ---


def test_recording_csv_round_trip(tmp_path, recording):
    from robovib.io import write_recording

    write_recording(tmp_path / "hits.csv", recording)
    back = read_recording_csv(tmp_path / "hits.csv")
    assert back.n_hits == 3 and back.response_quantity == "acceleration"
    assert back.sample_rate_hz == pytest.approx(2048.0, rel=1e-9)
    np.testing.assert_allclose(back.forces, recording.forces, rtol=1e-8, atol=1e-12)
    np.testing.assert_allclose(back.responses, recording.responses, rtol=1e-8, atol=1e-15)
    with pytest.raises(ValueError, match="unknown output format"):
        write_recording(tmp_path / "hits.txt", recording)


def test_path_modes_csv_round_trip_and_missing_column(tmp_path):
    from robovib.io import read_path_modes_csv, write_path_modes_csv
    from robovib.modal import ModalParameters

    s = np.array([0.3, 0.7, 1.2])
    modes = [ModalParameters(15.0 + i, 2e6 * (i + 1), 0.03) for i in range(3)]
    write_path_modes_csv(tmp_path / "m.csv", s, modes)
    s2, modes2 = read_path_modes_csv(tmp_path / "m.csv")
    np.testing.assert_allclose(s2, s)
    assert modes2 == modes
    (tmp_path / "bad.csv").write_text("s_m,fn_hz\n0.1,15\n")
    with pytest.raises(ValueError, match="missing columns"):
        read_path_modes_csv(tmp_path / "bad.csv")


def test_force_and_milling_record_csv_read_pandas_written_files(tmp_path):
    import pandas as pd

    from robovib.io import read_force_csv, read_milling_record_csv

    rng = np.random.default_rng(0)
    t = np.arange(50) / 1000.0
    f, d = rng.normal(size=(50, 3)), rng.normal(size=(50, 3)) * 1e-5
    cols = {"time_s": t} | {f"force_{a}_n": f[:, i] for i, a in enumerate("xyz")}
    pd.DataFrame(cols).to_csv(tmp_path / "f.csv", index=False)
    t2, f2 = read_force_csv(tmp_path / "f.csv")
    np.testing.assert_allclose(t2, t)
    np.testing.assert_allclose(f2, f)
    cols |= {f"displacement_{a}_m": d[:, i] for i, a in enumerate("xyz")}
    cols["path_s_m"] = np.linspace(0.6, 0.7, 50)
    pd.DataFrame(cols).to_csv(tmp_path / "r.csv", index=False)
    rec = read_milling_record_csv(tmp_path / "r.csv")
    np.testing.assert_allclose(rec["displacement_m"], d)
    np.testing.assert_allclose(rec["path_s_m"], cols["path_s_m"])
    cols["force_x_n"] = np.where(t > 0.01, np.nan, f[:, 0])
    pd.DataFrame(cols).to_csv(tmp_path / "nan.csv", index=False)
    with pytest.raises(ValueError, match="NaN"):
        read_force_csv(tmp_path / "nan.csv")


def test_compliance_tests_csv_with_and_without_rotations(tmp_path):
    from robovib.io import read_compliance_tests_csv

    names = [f"a{i}_deg" for i in range(1, 7)] + ["fx_n", "fy_n", "fz_n", "mx_nm", "my_nm", "mz_nm"]
    names += ["dx_m", "dy_m", "dz_m"]
    data = np.arange(2 * 15, dtype=float).reshape(2, 15)
    np.savetxt(tmp_path / "t.csv", data, delimiter=",", header=",".join(names), comments="")
    q, _w, d = read_compliance_tests_csv(tmp_path / "t.csv")
    np.testing.assert_array_equal(q, data[:, :6])
    assert d.shape == (2, 3)
    data6 = np.arange(2 * 18, dtype=float).reshape(2, 18)
    np.savetxt(tmp_path / "r.csv", data6, delimiter=",", comments="",
               header=",".join([*names, "rx_rad", "ry_rad", "rz_rad"]))  # fmt: skip
    assert read_compliance_tests_csv(tmp_path / "r.csv")[2].shape == (2, 6)


def test_frf_interpolate_is_exact_on_linear_frf_and_checks_range():
    f = np.linspace(1.0, 10.0, 10)
    frf = FRF(f, (2 + 3j) * f - 1j, coherence=np.full(10, 0.9))
    grid = np.array([1.5, 4.25, 9.9])
    out = frf.interpolate(grid)
    np.testing.assert_allclose(out.values, (2 + 3j) * grid - 1j)
    np.testing.assert_allclose(out.coherence, 0.9)
    with pytest.raises(ValueError, match="covers 1-10 Hz"):
        frf.interpolate([0.5, 5.0])
    held = frf.interpolate([0.5, 12.0], outside="hold")
    np.testing.assert_allclose(held.values, frf.values[[0, -1]])


def test_frf_interpolate_zero_outside_and_per_side():
    f = np.linspace(1.0, 10.0, 10)
    frf = FRF(f, (2 + 3j) * f - 1j, coherence=np.full(10, 0.9))
    grid = np.array([0.0, 0.5, 1.0, 5.5, 10.0, 10.5, 20.0])
    inside = (grid >= 1.0) & (grid <= 10.0)
    zero = frf.interpolate(grid, outside="zero")
    np.testing.assert_allclose(zero.values[inside], (2 + 3j) * grid[inside] - 1j)
    np.testing.assert_array_equal(zero.values[~inside], 0)
    np.testing.assert_array_equal(zero.coherence, np.where(inside, 0.9, 0.0))
    mixed = frf.interpolate(grid, outside=("hold", "zero"))
    np.testing.assert_allclose(mixed.values[grid < 1.0], frf.values[0])
    np.testing.assert_array_equal(mixed.values[grid > 10.0], 0)
    for bad in ("clip", ("zero",), ("raise", "zero")):
        with pytest.raises(ValueError, match="unknown outside"):
            frf.interpolate(grid, outside=bad)
    with pytest.raises(ValueError, match="strictly increasing"):
        frf.interpolate([2.0, 1.0], outside="zero")


def test_tool_displacement_from_frf_matches_modes_within_the_band():
    """FRF path of milling.prediction (interpolated, zero above the band) vs the exact modal path."""
    from robovib.milling.prediction import convolve_force
    from robovib.modal import ModalParameters

    mode = ModalParameters(30.0, 2e6, 0.05)
    fs = 1000.0
    t = np.arange(2000) / fs
    force = 100 * np.sin(2 * np.pi * 12.0 * t) * (t < 1.0)
    f_dense = np.linspace(0.0, fs / 2, 20001)
    frf = FRF(f_dense, mode.compliance(f_dense))
    x_modes = convolve_force(force, fs, modes=[mode])
    x_frf = convolve_force(force, fs, frf=frf)
    assert np.max(np.abs(x_frf - x_modes)) < 0.02 * np.max(np.abs(x_modes))


def test_to_si_and_from_si_are_the_division_by_the_prefix():
    """The CLI's option conversions (mm, ms, mm/s -> SI and back for display) go through
    io.units; they equal the hand-written x / 1e3 and 1e3 * x bit for bit."""
    from robovib.io import from_si, to_si

    x = np.random.default_rng(0).uniform(-5e3, 5e3, 10_000)
    np.testing.assert_array_equal(to_si(x, "mm"), x / 1e3)
    np.testing.assert_array_equal(to_si(x, "ms"), x / 1e3)
    np.testing.assert_array_equal(to_si(x, "mm/s"), x / 1e3)
    np.testing.assert_array_equal(to_si(x, "um"), x / 1e6)
    np.testing.assert_array_equal(from_si(x, "mm"), 1e3 * x)
    assert to_si(2.0, "kN") == 2000.0 and to_si(1.0, "g") == 9.80665
    assert from_si(9.80665, "g") == 1.0 and to_si(25.4, "mm") == 0.0254
    with pytest.raises(ValueError, match="unknown unit 'furlong'"):
        to_si(1.0, "furlong")


def test_read_tree_returns_what_h5py_returns(tmp_path):
    """The in-memory tree of a file answers ``[()]``, ``attrs``, ``in`` and ``len`` as h5py."""
    import h5py

    from robovib.files.h5format import read_tree

    path = tmp_path / "t.h5"
    with h5py.File(path, "w") as h5:
        h5.attrs["names"] = ["a", "b"]
        h5.attrs["n"] = 3
        g = h5.create_group("g")
        g.create_dataset("x", data=np.arange(6.0).reshape(2, 3))
        g.create_dataset("s", data=2.5)
        g.create_dataset("t", data="text")
        g.create_group("h").attrs["kind"] = "k"
    with h5py.File(path, "r") as h5:
        tree = read_tree(h5)
        assert list(tree.attrs["names"]) == list(h5.attrs["names"]) and tree.attrs["n"] == 3
        assert set(tree) == {"g"} and len(tree["g"]) == len(h5["g"]) == 4 and "h" in tree["g"]
        for name in ("x", "s", "t"):
            ref, got = h5["g"][name][()], tree["g"][name][()]
            assert type(got) is type(ref) or isinstance(got, type(ref))
            np.testing.assert_array_equal(got, ref)
        assert tree["g"]["h"].attrs["kind"] == "k" and len(tree["g"]["h"]) == 0
