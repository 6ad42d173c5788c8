"""Atomic outputs: a failed or interrupted write never destroys the previous file or an input."""

import hashlib
import os
import stat

import numpy as np
import pytest

from robovib.frf import FRF
from robovib.io import (
    OutputPathError,
    atomic_output,
    read_frfs,
    write_frfs,
    write_frfs_hdf5,
    write_frfs_uff,
)


def _digest(path):
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _frf(n=16):
    f = np.arange(1, n + 1, dtype=float)
    return FRF(f, 1e-6 / (1 - (f / 8) ** 2 + 0.1j * f / 8), direction="x")


def _leftovers(folder):
    return [p.name for p in folder.iterdir() if ".tmp" in p.name]


def test_success_replaces_and_leaves_no_temporary(tmp_path):
    out = tmp_path / "a.txt"
    out.write_text("old")
    with atomic_output(out) as tmp:
        assert tmp.parent == tmp_path and tmp.suffix == ".txt" and tmp != out
        tmp.write_text("new")
        assert out.read_text() == "old"  # nothing visible before the block ends
    assert out.read_text() == "new"
    assert _leftovers(tmp_path) == []


@pytest.mark.parametrize("exc", [RuntimeError("boom"), KeyboardInterrupt()])
def test_failure_or_interrupt_keeps_previous_file(tmp_path, exc):
    out = tmp_path / "a.txt"
    out.write_text("good")
    with pytest.raises(type(exc)), atomic_output(out) as tmp:
        tmp.write_text("half")
        raise exc
    assert out.read_text() == "good"
    assert _leftovers(tmp_path) == []


def test_two_writers_get_distinct_temporaries(tmp_path):
    out = tmp_path / "a.h5"
    with atomic_output(out) as t1, atomic_output(out) as t2:
        assert t1 != t2
        t1.write_text("1")
        t2.write_text("2")
    assert out.read_text() == "1"  # last rename wins, whole content of one writer, never mixed


def test_new_file_gets_normal_permissions(tmp_path):
    old = os.umask(0o022)
    try:
        with atomic_output(tmp_path / "p.txt") as tmp:
            tmp.write_text("x")
    finally:
        os.umask(old)
    assert stat.S_IMODE(os.stat(tmp_path / "p.txt").st_mode) == 0o644


def test_output_equal_to_input_refused_unless_forced(tmp_path):
    inp = tmp_path / "in.h5"
    inp.write_text("raw recording")
    digest = _digest(inp)
    sub = tmp_path / "sub"
    sub.mkdir()
    link = tmp_path / "link.h5"
    link.symlink_to(inp)
    for alias in (inp, sub / ".." / "in.h5", link):
        with pytest.raises(OutputPathError, match="is the input file"):
            with atomic_output(alias, inputs=[inp]) as tmp:
                tmp.write_text("FRF")
    assert _digest(inp) == digest
    with atomic_output(inp, inputs=[inp], force=True) as tmp:
        tmp.write_text("FRF")
    assert inp.read_text() == "FRF"


def test_missing_or_readonly_folder_named(tmp_path):
    with pytest.raises(OutputPathError, match=r"output folder .*nope does not exist"):
        with atomic_output(tmp_path / "nope" / "a.h5"):
            pass
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o555)
    try:
        with pytest.raises(OutputPathError, match=r"output folder .*ro is not writable"):
            with atomic_output(ro / "a.h5"):
                pass
    finally:
        ro.chmod(0o755)
    with pytest.raises(OutputPathError, match="is a folder"):
        with atomic_output(tmp_path):
            pass
    assert list(ro.iterdir()) == []


@pytest.mark.parametrize("suffix", [".h5", ".uff"])
def test_frf_writer_failure_keeps_previous_file(tmp_path, suffix, monkeypatch):
    out = tmp_path / f"frfs{suffix}"
    write_frfs(out, [_frf()])
    digest = _digest(out)
    # an unstorable FRF (uneven axis for UFF, unstorable meta for HDF5) fails mid-way
    bad = FRF(np.array([1.0, 2.0, 4.0]), np.ones(3, complex), meta={"obj": object()})
    with pytest.raises(ValueError):
        write_frfs(out, [_frf(), bad])
    assert _digest(out) == digest
    # Ctrl-C in the middle of the write
    import pathlib

    import h5py

    def interrupted(*a, **k):
        raise KeyboardInterrupt

    def half_then_interrupted(self, text, *a, **k):
        with open(self, "w") as fh:
            fh.write(text[: len(text) // 2])
        raise KeyboardInterrupt

    if suffix == ".uff":
        monkeypatch.setattr(pathlib.Path, "write_text", half_then_interrupted)
    else:
        monkeypatch.setattr(h5py.Group, "create_group", interrupted)
    with pytest.raises(KeyboardInterrupt):
        write_frfs(out, [_frf(), _frf()])
    monkeypatch.undo()
    assert _digest(out) == digest
    assert len(read_frfs(out)) == 1
    assert _leftovers(tmp_path) == []


@pytest.mark.parametrize("writer", [write_frfs_hdf5, write_frfs_uff])
def test_frf_writer_refuses_input_as_output(tmp_path, writer):
    inp = tmp_path / "hits.uff"
    inp.write_text("8 MB of raw hits")
    digest = _digest(inp)
    with pytest.raises(OutputPathError, match="input file"):
        writer(inp, [_frf()], inputs=[inp])
    assert _digest(inp) == digest
