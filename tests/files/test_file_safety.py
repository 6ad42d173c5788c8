"""Files robovib reads and writes (issue 38 items 2 and 3): inputs are regular files below a
size limit, no output replaces an input or a link/FIFO/device, output folders keep no stale
files, and a Dask scheduler address that never answers costs seconds, not forever.

Every reader is run on a FIFO in a daemon thread that must finish within seconds: a reader that
opened the FIFO would block there (nobody writes to it) and the test fails instead of hanging.
"""

from __future__ import annotations

import hashlib
import os
import socket
import threading
import time
from pathlib import Path

import pytest
from typer.testing import CliRunner

from robovib.cli import app
from robovib.files.safe_read import (
    InputFileError,
    check_input_file,
    inputs_read,
    read_bytes_checked,
    recording_inputs,
)
from robovib.files.safe_write import (
    OutputPathError,
    atomic_output,
    check_output_path,
    remove_stale_outputs,
)

fifo_only = pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="needs POSIX FIFOs")
dev_zero = pytest.mark.skipif(not os.path.exists("/dev/zero"), reason="needs /dev/zero")


def _within(fn, seconds: float = 10.0):
    """Run ``fn`` in a daemon thread; fail if it has not returned within ``seconds``."""
    box: dict = {}

    def target():
        try:
            box["value"] = fn()
        except BaseException as exc:
            box["error"] = exc

    th = threading.Thread(target=target, daemon=True)
    th.start()
    th.join(seconds)
    assert not th.is_alive(), f"blocked for more than {seconds} s"
    if "error" in box:
        raise box["error"]
    return box.get("value")


def _digest(p: Path) -> str:
    return hashlib.sha256(p.read_bytes()).hexdigest()


def _error_line(res) -> str:
    lines = [ln for ln in res.output.splitlines() if ln.startswith("error:")]
    assert res.exit_code == 1 and len(lines) == 1, res.output
    assert "Traceback" not in res.output and "unexpected" not in res.output, res.output
    return lines[0]


# ----------------------------------------------------------------------------- inputs
@fifo_only
def test_fifo_device_folder_and_missing_named_for_what_they_are(tmp_path):
    fifo = tmp_path / "pipe.csv"
    os.mkfifo(fifo)
    with pytest.raises(InputFileError, match=r"pipe\.csv: the cuts file is a FIFO"):
        _within(lambda: check_input_file(fifo, "cuts file"))
    with pytest.raises(InputFileError, match="/dev/zero: the input file is a character device"):
        check_input_file("/dev/zero")
    with pytest.raises(InputFileError, match="is a folder, not a regular file"):
        check_input_file(tmp_path, "manifest file")
    with pytest.raises(InputFileError, match=r"nope\.csv: no such pose table$"):
        check_input_file(tmp_path / "nope.csv", "pose table")
    link = tmp_path / "dangling.csv"
    link.symlink_to(tmp_path / "gone.csv")
    with pytest.raises(InputFileError, match="broken symbolic link"):
        check_input_file(link)
    good = tmp_path / "ok.csv"
    good.write_text("a\n1\n")
    alias = tmp_path / "alias.csv"
    alias.symlink_to(good)  # a link to a regular file is that file
    assert check_input_file(alias) == alias


def test_size_limit_from_the_caller_and_the_environment(tmp_path, monkeypatch):
    big = tmp_path / "big.csv"
    big.write_bytes(b"x" * 5000)
    with pytest.raises(InputFileError, match=r"big\.csv: the table is 5000 bytes, larger than"):
        check_input_file(big, "table", max_bytes=4096)
    assert read_bytes_checked(big, "table", max_bytes=5000) == b"x" * 5000
    monkeypatch.setenv("ROBOVIB_MAX_INPUT_MB", "0.001")  # 1048 bytes, whatever the caller says
    with pytest.raises(InputFileError, match="ROBOVIB_MAX_INPUT_MB"):
        check_input_file(big, "table", max_bytes=None)
    monkeypatch.setenv("ROBOVIB_MAX_INPUT_MB", "lots")
    with pytest.raises(InputFileError, match="not a number of megabytes"):
        check_input_file(big)


def test_readers_stop_at_the_size_limit(tmp_path, monkeypatch):
    from robovib.io import read_cuts_csv, read_table

    cuts = tmp_path / "cuts.csv"
    cuts.write_text("spindle_rpm,depth_mm,result\n" + "1500,2,stable\n" * 200)  # 2.8 kB
    assert read_cuts_csv(cuts).spindle_rpm.size == 200
    monkeypatch.setenv("ROBOVIB_MAX_INPUT_MB", "0.002")  # 2097 bytes
    for read in (read_cuts_csv, read_table):
        with pytest.raises(InputFileError, match=r"cuts\.csv: the .* is 2\d{3} bytes, larger"):
            read(cuts)


def _readers():
    """(name, suffix, call) of every file reader of robovib."""
    from robovib.campaign.manifest import read_manifest
    from robovib.files.h5format import open_checked
    from robovib.gp.pose_file import read_pose_file
    from robovib.io import (
        read_compliance_tests_csv,
        read_cuts_csv,
        read_force_csv,
        read_frf_csv,
        read_frfs,
        read_frfs_hdf5,
        read_frfs_uff,
        read_milling_record_csv,
        read_path_modes_csv,
        read_pose_array,
        read_recording,
        read_recording_channels,
        read_table,
    )

    return [
        ("read_table", ".csv", read_table),
        ("cuts", ".csv", read_cuts_csv),
        ("force csv", ".csv", read_force_csv),
        ("milling record", ".csv", read_milling_record_csv),
        ("path modes", ".csv", read_path_modes_csv),
        ("compliance tests", ".csv", read_compliance_tests_csv),
        ("poses", ".csv", lambda p: read_pose_array(p, ("x_mm",))),
        ("manifest", ".csv", read_manifest),
        ("recording csv", ".csv", read_recording),
        ("recording uff", ".uff", read_recording_channels),
        ("frf csv", ".csv", read_frf_csv),
        ("frfs h5", ".h5", read_frfs),
        ("frfs hdf5", ".h5", read_frfs_hdf5),
        ("frfs uff", ".uff", read_frfs_uff),
        ("open_checked", ".h5", lambda p: open_checked(p, {"robovib-pose-model": 1})),
        ("pose model", ".h5", read_pose_file),
    ]


@fifo_only
@pytest.mark.parametrize("name, suffix, read", _readers(), ids=[r[0] for r in _readers()])
def test_every_reader_refuses_a_fifo_without_blocking(tmp_path, name, suffix, read):
    fifo = tmp_path / f"pipe{suffix}"
    os.mkfifo(fifo)
    with pytest.raises(ValueError, match=r"pipe\.\w+: .*is a FIFO \(named pipe\), not a regular"):
        _within(lambda: read(fifo))


@dev_zero
@pytest.mark.parametrize("name, suffix, read", _readers(), ids=[r[0] for r in _readers()])
def test_every_reader_refuses_an_endless_device(name, suffix, read):
    # /dev/zero never ends: a reader that reads it grows until memory runs out
    with pytest.raises(ValueError, match=r"/dev/zero: .*character device"):
        _within(lambda: read("/dev/zero"))


@fifo_only
def test_cli_fifo_and_dev_zero_inputs_end_in_one_error(tmp_path):
    fifo = tmp_path / "model.h5"
    os.mkfifo(fifo)
    run = CliRunner().invoke
    line = _within(lambda: _error_line(run(app, ["gpr", "predict", "--model", str(fifo),
                                                 "--x", "2400", "--y", "0", "--rz", "45"])))  # fmt: skip
    assert "model.h5" in line and "FIFO" in line
    report = ["report", "model", str(fifo), "-o", str(tmp_path / "r.html")]
    line = _within(lambda: _error_line(run(app, report)))
    assert "model.h5: the model file is a FIFO" in line
    cuts = ["mill", "lobes", "--mode", "x:30,1e7,0.05", "--rpm-range", "1000:2000:500",
            "--cuts", "/dev/zero"]  # fmt: skip
    line = _within(lambda: _error_line(run(app, cuts)))
    assert "/dev/zero: the cuts file is a character device" in line


# ----------------------------------------------------------------------------- outputs
@fifo_only
def test_output_that_is_a_fifo_device_or_link_is_refused_even_forced(tmp_path):
    fifo = tmp_path / "out.h5"
    os.mkfifo(fifo)
    target = tmp_path / "target.h5"
    target.write_text("keep me")
    link = tmp_path / "link.h5"
    link.symlink_to(target)
    for out, words in ((fifo, "is a FIFO"), (link, "is a symbolic link")):
        for force in (False, True):
            with pytest.raises(OutputPathError, match=words):
                with atomic_output(out, force=force) as tmp:
                    tmp.write_text("new")
    assert fifo.is_fifo() and link.is_symlink() and target.read_text() == "keep me"
    with pytest.raises(OutputPathError, match="/dev/null"):
        check_output_path("/dev/null")


def test_examples_never_write_through_a_link(tmp_path):
    victim = tmp_path / "victim.txt"
    victim.write_text("keep me")
    (tmp_path / "ex").mkdir()
    (tmp_path / "ex" / "cuts.csv").symlink_to(victim)
    res = CliRunner().invoke(app, ["examples", "--to", str(tmp_path / "ex")])
    assert "cuts.csv is a symbolic link" in _error_line(res)
    assert victim.read_text() == "keep me"


def test_output_onto_a_file_read_in_the_same_command_is_refused(tmp_path):
    from robovib.io import read_table

    table = tmp_path / "t.csv"
    table.write_text("a,b\n1,2\n")
    digest = _digest(table)
    with recording_inputs():
        read_table(table)
        assert inputs_read() == (str(table.resolve()),)
        with pytest.raises(OutputPathError, match="is the input file"):
            with atomic_output(tmp_path / "." / "t.csv") as tmp:
                tmp.write_text("replaced")
        with atomic_output(table, force=True) as tmp:  # --force: replace it knowingly
            tmp.write_text("a,b\n3,4\n")
        # the command's own output, read back and written again, is no input of the command
        read_table(table)
        with atomic_output(table) as tmp:
            tmp.write_text("a,b\n5,6\n")
    assert _digest(table) != digest
    read_table(table)  # library use (no command running): nothing is recorded
    assert inputs_read() == ()
    with atomic_output(table) as tmp:
        tmp.write_text("a,b\n7,8\n")


def test_model_fit_onto_its_table_refused_before_the_fit(tmp_path):
    t = tmp_path / "t.csv"
    t.write_text("x_mm,y_mm,rz_deg,direction,fn_hz\n1,2,3,x,4\n")
    digest = _digest(t)
    start = time.perf_counter()
    line = _error_line(CliRunner().invoke(app, ["model", "fit", str(t), "-o", str(t)]))
    assert "is the input file" in line and time.perf_counter() - start < 10
    assert _digest(t) == digest


def test_sim_campaign_onto_its_poses_refused_before_writing(tmp_path):
    out = tmp_path / "d"
    (out / "recordings").mkdir(parents=True)
    poses = out / "truth.csv"
    poses.write_text("x_mm,y_mm,rz_deg\n2400,0,45\n")
    digest = _digest(poses)
    res = CliRunner().invoke(app, ["sim", "campaign", "--poses", str(poses), "-o", str(out),
                                   "--hits", "1", "--duration-s", "0.5"])  # fmt: skip
    assert "truth.csv is the input file" in _error_line(res)
    assert _digest(poses) == digest
    assert sorted(p.name for p in out.rglob("*")) == ["recordings", "truth.csv"]  # nothing new


def test_campaign_process_onto_its_manifest_refused_before_processing(tmp_path):
    from robovib.campaign import process_campaign
    from robovib.sim import simulate_campaign

    sim = simulate_campaign([[2400, 0, 45]], tmp_path, rng=0, n_hits=1, duration_s=1.0,
                            directions=("x",), n_truth=0, layouts=("uff-pairs",))  # fmt: skip
    manifest = tmp_path / "modal.csv"  # a manifest named like an output, in the output folder
    sim.manifest.rename(manifest)
    digest = _digest(manifest)
    with pytest.raises(OutputPathError, match=r"modal\.csv is the input file"):
        process_campaign(manifest, tmp_path, n_workers=1)
    assert _digest(manifest) == digest
    assert not (tmp_path / "frfs.h5").exists()
    res = CliRunner().invoke(app, ["campaign", "process", str(manifest), "-o", str(tmp_path)])
    assert "modal.csv is the input file" in _error_line(res)
    assert _digest(manifest) == digest


def test_rerun_of_campaign_process_leaves_no_stale_modes_table(tmp_path):
    from robovib.campaign import ProcessingSettings, process_campaign
    from robovib.sim import simulate_campaign

    sim = simulate_campaign([[2400, 0, 45], [2200, 100, 90], [2600, -100, 20]], tmp_path,
                            rng=0, n_hits=2, directions=("x",), n_truth=0,
                            layouts=("uff-pairs",))  # fmt: skip
    out = tmp_path / "out"
    out.mkdir()
    (out / "notes.txt").write_text("mine")
    process_campaign(sim.manifest, out, n_workers=1,
                     settings=ProcessingSettings(modes_band_hz=(5.0, 100.0)))  # fmt: skip
    assert (out / "modes.csv").is_file()
    process_campaign(sim.manifest, out, n_workers=1)
    names = sorted(p.name for p in out.iterdir())
    assert names == ["campaign.json", "frfs.h5", "modal.csv", "notes.txt"]


def test_rerun_of_sim_campaign_removes_its_own_stale_recordings_only(tmp_path):
    from robovib.sim import simulate_campaign

    kw = dict(rng=0, n_hits=1, duration_s=0.5, directions=("x",), n_truth=0)
    simulate_campaign([[2400, 0, 45], [2200, 100, 90], [2600, -100, 20]], tmp_path, **kw)
    (tmp_path / "recordings" / "mine.uff").write_text("not robovib's")
    second = simulate_campaign([[2400, 0, 45]], tmp_path, **kw)
    left = sorted(p.name for p in (tmp_path / "recordings").iterdir())
    assert left == ["mine.uff", second.recordings[0].name]


def test_remove_stale_outputs_keeps_links_and_what_was_written(tmp_path):
    for name in ("a.csv", "b.csv", "c.txt"):
        (tmp_path / name).write_text(name)
    (tmp_path / "l.csv").symlink_to(tmp_path / "c.txt")
    removed = remove_stale_outputs(tmp_path, ["*.csv"], [tmp_path / "a.csv"])
    assert removed == [tmp_path / "b.csv"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.csv", "c.txt", "l.csv"]


# ----------------------------------------------------------------------------- scheduler
def _silent_listener():
    """A TCP listener on 127.0.0.1 that accepts and never speaks; returns (socket, port)."""
    srv = socket.socket()
    srv.bind(("127.0.0.1", 0))
    srv.listen(8)
    accepted = []

    def loop():
        while True:
            try:
                accepted.append(srv.accept()[0])
            except OSError:
                return

    threading.Thread(target=loop, daemon=True).start()
    return srv, srv.getsockname()[1]


def test_silent_listener_as_scheduler_fails_within_seconds_naming_it():
    from robovib.milling.maps import check_scheduler_address

    srv, port = _silent_listener()
    address = f"tcp://127.0.0.1:{port}"
    try:
        start = time.perf_counter()
        with pytest.raises(ValueError, match=f"{address}: .*no Dask handshake within 1 s"):
            _within(lambda: check_scheduler_address(address, timeout_s=1.0))
        assert time.perf_counter() - start < 5
    finally:
        srv.close()


def test_refused_port_and_bad_address_fail_at_once():
    from robovib.milling.maps import check_scheduler_address

    probe = socket.socket()
    probe.bind(("127.0.0.1", 0))
    port = probe.getsockname()[1]
    probe.close()  # nothing listens there now
    start = time.perf_counter()
    with pytest.raises(ValueError, match=f"tcp://127.0.0.1:{port}: connection refused"):
        check_scheduler_address(f"tcp://127.0.0.1:{port}")
    assert time.perf_counter() - start < 3
    for bad in ("tcp://127.0.0.1", "tcp://127.0.0.1:port", "udp://127.0.0.1:1"):
        with pytest.raises(ValueError, match="expected tcp://host:port"):
            check_scheduler_address(bad)


def test_mill_map_with_a_silent_scheduler_is_one_error_naming_the_address():
    srv, port = _silent_listener()
    try:
        res = _within(lambda: CliRunner().invoke(app, [
            "mill", "map", "--nx", "2", "--ny", "2", "--scheduler", f"tcp://127.0.0.1:{port}"]),
            60)  # fmt: skip
    finally:
        srv.close()
    assert f"Dask scheduler tcp://127.0.0.1:{port}" in _error_line(res)


def test_dask_scheduler_that_answers_passes_the_probe():
    from distributed import LocalCluster

    from robovib.milling.maps import check_scheduler_address

    with LocalCluster(n_workers=0, processes=False, protocol="tcp://", host="127.0.0.1",
                      scheduler_port=0, dashboard_address=None) as cluster:  # fmt: skip
        check_scheduler_address(cluster.scheduler_address, timeout_s=5.0)
