"""Corruption property over every file reader (issue 38, item 6).

Each reader gets a good file damaged at random — bit flips, truncation, and for HDF5 files
members of the wrong shape or type, dropped members, links, external storage, virtual
datasets and lazily allocated giants (checksum recomputed or removed, as a sender could). The
reader must either raise a ``ValueError`` (robovib's errors are ``ValueError`` subclasses: the
CLI prints them as one line and exits 1) whose message is one line naming the file, or return:

- for HDF5 files, which robovib seals with a checksum: the same answer as the good file;
- for text exchange formats (CSV, UFF), which carry no checksum: any answer (a flipped digit
  is a different number no reader can tell from the real one, and a UFF file cut exactly at a
  dataset boundary is a shorter valid file), but never another exception.

Hypothesis runs derandomized with no example database and bounded examples, so the test is
deterministic and costs a few seconds per reader. A CLI check runs one damaged file per
format through ``robovib`` itself.
"""

from __future__ import annotations

import dataclasses
import shutil
from pathlib import Path

import h5py
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

from robovib.files.h5safe import CHECKSUM_ATTR, USERBLOCK_SIZE, seal, seal_file

QUERY = np.array([[2000.0, -300.0, 30.0], [2600.0, 400.0, -60.0]])


def _settings(n):
    return settings(
        max_examples=n,
        derandomize=True,
        database=None,
        deadline=None,
        suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
    )


# ------------------------------------------------------------------------------ good files
def _frfs():
    from robovib.frf import FRF

    f = 1.0 + 1.25 * np.arange(40)  # a step UFF's abscissa fields hold exactly
    return [
        FRF(f, 1e-6 / (1 - (f / fn) ** 2 + 0.1j * f / fn), coherence=np.full(f.size, 0.95),
            direction=d, pose=(1.0, 0.2, 0.5, 0.0, 0.0, 30.0))
        for fn, d in ((20.0, "x"), (25.0, "y"))
    ]  # fmt: skip


def _recording():
    from robovib.io import HammerRecording

    t = np.arange(256) / 1024.0
    force = np.exp(-(((t - 0.01) / 0.002) ** 2)) * 100.0
    resp = np.exp(-3 * t) * np.sin(2 * np.pi * 30 * t) * (t > 0.01)
    return HammerRecording(np.vstack([force, force]), np.vstack([resp, resp]), 1024.0,
                           "acceleration", direction="x")  # fmt: skip


def _build(kind: str, path: Path) -> Path:
    from robovib import io

    if kind == "pose_model":
        from robovib.gp.chapter3_model import chapter3_model_path

        shutil.copy(chapter3_model_path(), path)
    elif kind == "frf_h5":
        io.write_frfs(path, _frfs())
    elif kind == "hybrid":
        from robovib.hybrid import FRFPoseModel

        f = np.linspace(2, 40, 12)
        h = np.array([(1 + s) * 1e-6 / (1 - (f / 15) ** 2 + 0.1j * f / 15) for s in (0.0, 1.2)])
        FRFPoseModel(f).fit(np.array([0.0, 1.2]), h).save(path)
    elif kind == "frf_csv":
        io.write_frf_csv(path, _frfs())
    elif kind == "frf_uff":
        io.write_frfs_uff(path, _frfs())
    elif kind == "recording_csv":
        io.write_recording_csv(path, _recording())
    elif kind == "recording_uff":
        io.write_recording_uff(path, _recording())
    elif kind == "path_modes_csv":
        from robovib.modal import ModalParameters

        modes = [ModalParameters(20.0 + i, 1e6 * (1 + 0.1 * i), 0.03) for i in range(4)]
        io.write_path_modes_csv(path, np.linspace(0.0, 0.6, 4), modes)
    elif kind == "cuts_csv":
        path.write_text("spindle_rpm,depth_mm,result\n2700,1.5,stable\n3000,2.5,chatter\n"
                        "3300,0.8,stable\n")  # fmt: skip
    elif kind == "modes_table":
        path.write_text("row,x_mm,y_mm,rz_deg,mode_id,fn_hz,stiffness_n_per_m,damping_ratio\n"
                        "1,2000,0,0,x1,40.5,2.1e6,0.031\n2,2400,100,30,x1,38.2,1.9e6,0.028\n"
                        "3,2000,0,0,x2,95.0,8.0e6,0.02\n")  # fmt: skip
    else:  # pragma: no cover
        raise AssertionError(kind)
    return path


def _read(kind: str, path: Path):
    """The reader's answer, as plain data to compare."""
    from robovib import io

    if kind == "pose_model":
        from robovib.gp.saved_model import PosePredictor

        return PosePredictor.load(path).predict(QUERY, return_std=True)
    if kind == "pose_model_full":
        from robovib.gp import PoseModalModel

        return PoseModalModel.load(path).predict(QUERY, return_std=True)
    if kind == "hybrid":
        from robovib.hybrid import FRFPoseModel

        return FRFPoseModel.load(path).predict([0.3, 0.9], return_std=True)
    if kind in ("frf_h5", "frf_uff"):
        return io.read_frfs(path)
    if kind == "frf_csv":
        return io.read_frf_csv(path)
    if kind == "recording_csv":
        return io.read_recording_csv(path)
    if kind == "recording_uff":
        return io.read_recording_uff(path)
    if kind == "path_modes_csv":
        return io.read_path_modes_csv(path)
    if kind == "cuts_csv":
        return io.read_cuts_csv(path)
    if kind == "modes_table":
        return io.read_table(path, what="mode table").to_frame()
    raise AssertionError(kind)  # pragma: no cover


def _plain(value):
    """Comparable plain form of an answer (arrays by bytes, dataclasses by fields)."""
    if isinstance(value, np.ndarray):
        return ("array", value.dtype.str, value.shape, value.tobytes())
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return (type(value).__name__,
                tuple((f.name, _plain(getattr(value, f.name)))
                      for f in dataclasses.fields(value) if f.compare))  # fmt: skip
    if isinstance(value, dict):
        return tuple(sorted((str(k), _plain(v)) for k, v in value.items()))
    if isinstance(value, list | tuple):
        return tuple(_plain(v) for v in value)
    if hasattr(value, "to_dict") and hasattr(value, "columns"):  # a DataFrame
        return _plain({c: value[c].to_numpy() for c in value.columns})
    if isinstance(value, float | np.floating):
        return ("float", float(value).hex())
    return value


@pytest.fixture(scope="module")
def good(tmp_path_factory):
    """Good file and its answer, per kind."""
    folder = tmp_path_factory.mktemp("good")
    out = {}
    for kind, suffix in KINDS.items():
        path = _build(kind, folder / f"{kind}{suffix}")
        out[kind] = (path, _plain(_read(kind, path)))
    out["pose_model_full"] = (out["pose_model"][0], _plain(_read("pose_model_full",
                                                                  out["pose_model"][0])))  # fmt: skip
    return out


KINDS = {
    "pose_model": ".h5",
    "frf_h5": ".h5",
    "hybrid": ".h5",
    "frf_csv": ".csv",
    "frf_uff": ".uff",
    "recording_csv": ".csv",
    "recording_uff": ".uff",
    "path_modes_csv": ".csv",
    "cuts_csv": ".csv",
    "modes_table": ".csv",
}
H5_KINDS = ("pose_model", "frf_h5", "hybrid")


# ------------------------------------------------------------------------------ damage
def _flip(data: bytes, flips) -> bytes:
    b = bytearray(data)
    for where, bit in flips:
        b[int(where * len(b))] ^= 1 << bit
    return bytes(b)


def _datasets(h5) -> list[str]:
    names = []
    h5.visititems(lambda n, o: names.append(n) if isinstance(o, h5py.Dataset) else None)
    return sorted(names)


def _restructure(path: Path, how: str, pick: int, other: Path) -> None:
    """Damage one dataset's structure. The checksum is recomputed where the result is still
    self-contained and breaks the format (as an editing sender would), removed where it
    reaches outside the file, and kept (now stale) where a member is lost."""
    with h5py.File(path, "a") as h5:
        names = _datasets(h5)
        name = names[pick % len(names)]
        old = h5[name][()]
        reseal = True
        del h5[name]
        if how == "shape":
            h5.create_dataset(name, data=old.reshape(-1)[:-1] if old.size > 1 else np.zeros((2, 2)))
        elif how == "dtype":
            h5.create_dataset(name, data=np.asarray(old).astype("S12"))
        elif how == "drop":  # a member lost: the stored checksum no longer matches
            reseal = None
        elif how == "soft_link":
            h5[name] = h5py.SoftLink("/" + names[(pick + 1) % len(names)])
            reseal = False
        elif how == "external_link":
            h5[name] = h5py.ExternalLink(str(other), "/X")
            reseal = False
        elif how == "external_storage":
            h5.create_dataset(name, shape=old.shape, dtype="f8",
                              external=[(str(other), 0, 8 * max(old.size, 1))])  # fmt: skip
            reseal = False
        elif how == "virtual":
            layout = h5py.VirtualLayout(shape=(40,), dtype="f8")
            layout[:] = h5py.VirtualSource(str(other), "X", shape=(40,))
            h5.create_virtual_dataset(name, layout)
            reseal = False
        elif how == "giant":
            h5.create_dataset(name, shape=(10**9,), dtype="f8")
            reseal = False
        else:  # pragma: no cover
            raise AssertionError(how)
        if reseal:
            seal(h5)
        elif reseal is not None and CHECKSUM_ATTR in h5.attrs:
            del h5.attrs[CHECKSUM_ATTR]
    if reseal:
        seal_file(path)
    elif reseal is not None:  # blank the byte checksum too: an unsealed file
        data = bytearray(path.read_bytes())
        data[:USERBLOCK_SIZE] = bytes(USERBLOCK_SIZE)
        path.write_bytes(bytes(data))


FLIPS = st.lists(
    st.tuples(st.floats(0.0, 1.0, exclude_max=True), st.integers(0, 7)), min_size=1, max_size=3
)
BYTE_DAMAGE = st.one_of(
    st.tuples(st.just("flip"), FLIPS),
    st.tuples(st.just("truncate"), st.floats(0.0, 1.0, exclude_max=True)),
)
HOW = ["shape", "dtype", "drop", "soft_link", "external_link", "external_storage", "virtual",
       "giant"]  # fmt: skip
RESTRUCTURE = st.tuples(
    st.just("restructure"), st.tuples(st.sampled_from(HOW), st.integers(0, 10**6))
)
H5_DAMAGE = st.one_of(BYTE_DAMAGE, RESTRUCTURE)


def _damage(good_path: Path, bad: Path, damage, other: Path) -> None:
    what, arg = damage
    data = good_path.read_bytes()
    if what == "flip":
        bad.write_bytes(_flip(data, arg))
    elif what == "truncate":
        bad.write_bytes(data[: int(arg * len(data))])
    else:
        bad.write_bytes(data)
        _restructure(bad, *arg, other)


def _check(kind: str, bad: Path, reference, *, checksummed: bool) -> None:
    try:
        answer = _read(kind, bad)
    except ValueError as exc:
        msg = str(exc)
        assert "\n" not in msg.strip(), f"{kind}: message on several lines: {msg!r}"
        assert str(bad) in msg or bad.name in msg, f"{kind}: message does not name the file: {msg}"
        return
    if checksummed:
        assert _plain(answer) == reference, f"{kind}: damaged file read with a different answer"


@pytest.fixture(scope="module")
def other(tmp_path_factory):
    path = tmp_path_factory.mktemp("other") / "other.h5"
    with h5py.File(path, "w") as h5:
        h5.create_dataset("X", data=np.linspace(1.0, 2.0, 40))
    return path


@pytest.mark.parametrize(
    ("kind", "n"), [("pose_model", 60), ("pose_model_full", 12), ("frf_h5", 60), ("hybrid", 40)]
)
def test_damaged_hdf5_file_is_refused_or_reads_the_same(kind, n, good, other, tmp_path):
    good_path, reference = good[kind]
    bad = tmp_path / f"damaged{good_path.suffix}"

    @_settings(n)
    @given(damage=H5_DAMAGE)
    def run(damage):
        _damage(good_path, bad, damage, other)
        _check(kind, bad, reference, checksummed=True)

    run()


@pytest.mark.parametrize("kind", [k for k in KINDS if k not in H5_KINDS])
def test_damaged_text_file_is_refused_in_one_line_naming_it(kind, good, other, tmp_path):
    good_path, reference = good[kind]
    bad = tmp_path / f"damaged{good_path.suffix}"

    @_settings(40)
    @given(damage=BYTE_DAMAGE)
    def run(damage):
        _damage(good_path, bad, damage, other)
        _check(kind, bad, reference, checksummed=False)

    run()


CLI = {
    "pose_model": ["gpr", "predict", "--x", "2000", "--y", "0", "--rz", "0", "--model"],
    "frf_h5": ["modal", "fit"],
    "hybrid": ["hybrid", "predict", "--path-s", "0.5"],
    "frf_uff": ["modal", "fit"],
    "cuts_csv": ["mill", "lobes", "--x", "2000", "--y", "0", "--rz", "0", "--cuts"],
}


@pytest.mark.parametrize("kind", list(CLI))
def test_cli_reports_a_damaged_file_in_one_line(kind, good, tmp_path):
    from robovib.cli import app

    good_path, _ = good[kind]
    bad = tmp_path / f"damaged{good_path.suffix}"
    data = good_path.read_bytes()
    cut = data.rstrip(b"\n").rfind(b"\n") + 4  # inside the last line: never a valid file
    bad.write_bytes(data[:cut])
    result = CliRunner().invoke(app, [*CLI[kind], str(bad)])
    lines = result.output.strip().splitlines()
    assert result.exit_code != 0 and len(lines) == 1, result.output
    assert lines[0].startswith("error: ") and str(bad) in lines[0], result.output
    assert "unexpected" not in lines[0] and "Traceback" not in result.output
