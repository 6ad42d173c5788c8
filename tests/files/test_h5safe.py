"""HDF5 files that touch only themselves (issue 38, item 1).

Every attack is built with h5py the way a sender could build it: data stored in another file
(a stand-in for /etc/passwd), an external link, a virtual dataset, soft and hard-link loops, a
lazily allocated 10⁹-element dataset, a flipped bit, a truncated file, and members of the
wrong type or shape with the checksum recomputed (so only the format checks can catch them).
Each must end in one error that names the file and the member, through every reader and
through the CLI.
"""

from __future__ import annotations

import shutil
import tracemalloc

import h5py
import numpy as np
import pytest
from typer.testing import CliRunner

from robovib.cli import app
from robovib.files.h5safe import (
    CHECKSUM_ATTR,
    USERBLOCK_SIZE,
    FileContentError,
    check_file_seal,
    content_sha256,
    seal,
    seal_file,
)
from robovib.files.provenance import read_provenance
from robovib.gp import PoseModalModel
from robovib.gp.chapter3_model import chapter3_model_path
from robovib.gp.saved_model import PosePredictor
from robovib.io import read_frfs, write_frfs

SECRET = b"root:x:0:0:root:/root:/bin/bash\n" * 200  # stands in for /etc/passwd


@pytest.fixture
def secret(tmp_path):
    path = tmp_path / "passwd"
    path.write_bytes(SECRET)
    return path


@pytest.fixture
def pose_file(tmp_path):
    path = tmp_path / "model.h5"
    shutil.copy(chapter3_model_path(), path)
    return path


@pytest.fixture
def frf_file(tmp_path):
    from robovib.frf import FRF

    f = np.linspace(1.0, 50.0, 64)
    frf = FRF(f, 1e-6 / (1 - (f / 20) ** 2 + 0.1j * f / 20), direction="x")
    path = tmp_path / "frfs.h5"
    write_frfs(path, [frf])
    return path


def _other_file(tmp_path, shape=(180, 3)):
    other = tmp_path / "other.h5"
    with h5py.File(other, "w") as h5:
        h5.create_dataset("X", data=np.full(shape, 7.0))
    return other


def _replace(path, member, build, *, reseal=True):
    """Replace ``member`` by what ``build(h5, member, old)`` makes; recompute the checksum (an
    attacker can) unless ``reseal`` is False, in which case the checksum is removed (the file
    then reads as one written before robovib sealed files: the structure checks alone must
    refuse it; robovib's own :func:`seal` refuses to hash a file that reaches outside)."""
    with h5py.File(path, "a") as h5:
        hard = isinstance(h5.get(member, getlink=True), h5py.HardLink)
        old = h5[member][()] if hard and isinstance(h5[member], h5py.Dataset) else None
        if h5.get(member, getlink=True) is not None:
            del h5[member]
        build(h5, member, old)
        if reseal:
            seal(h5)
        elif CHECKSUM_ATTR in h5.attrs:
            del h5.attrs[CHECKSUM_ATTR]
    if reseal:
        seal_file(path)
    else:
        _strip_file_seal(path)


def _strip_file_seal(path):
    """Blank the byte checksum in the user block: the file reads as an unsealed one."""
    data = bytearray(path.read_bytes())
    data[:USERBLOCK_SIZE] = bytes(USERBLOCK_SIZE)
    path.write_bytes(bytes(data))


def _external_storage(secret):
    def build(h5, member, old):
        h5.create_dataset(member, shape=old.shape, dtype=old.dtype,
                          external=[(str(secret), 0, old.nbytes)])  # fmt: skip

    return build


def _external_link(other):
    def build(h5, member, old):
        h5[member] = h5py.ExternalLink(str(other), "/X")

    return build


def _virtual(other):
    def build(h5, member, old):
        layout = h5py.VirtualLayout(shape=old.shape, dtype=old.dtype)
        layout[:] = h5py.VirtualSource(str(other), "X", shape=old.shape)
        h5.create_virtual_dataset(member, layout)

    return build


POSE_READERS = {
    "PosePredictor.load": PosePredictor.load,
    "PoseModalModel.load": PoseModalModel.load,
}


def _refused(reader, path, member, words):
    with pytest.raises(ValueError) as info:
        reader(path)
    msg = str(info.value)
    assert "\n" not in msg and str(path) in msg, msg
    if member is not None:
        assert member in msg, msg
    assert words in msg, msg
    return info.value


@pytest.mark.parametrize("reader", POSE_READERS)
def test_pose_model_with_data_stored_in_another_file_is_refused(pose_file, secret, reader):
    _replace(pose_file, "training/X", _external_storage(secret), reseal=False)
    with h5py.File(pose_file) as h5:  # the attack works on plain h5py: the bytes are the secret
        assert h5["training/X"][()].tobytes() == SECRET[: 180 * 3 * 8]
    err = _refused(POSE_READERS[reader], pose_file, "training/X", "external file")
    assert isinstance(err, FileContentError) and str(secret) in str(err)


@pytest.mark.parametrize("reader", POSE_READERS)
def test_pose_model_with_an_external_link_or_virtual_dataset_is_refused(
    tmp_path, pose_file, reader
):
    other = _other_file(tmp_path)
    original = pose_file.read_bytes()
    _replace(pose_file, "training/X", _external_link(other), reseal=False)
    _refused(POSE_READERS[reader], pose_file, "training/X", "external link")
    pose_file.write_bytes(original)
    _replace(pose_file, "training/X", _virtual(other), reseal=False)
    _refused(POSE_READERS[reader], pose_file, "training/X", "virtual dataset")


def test_seal_refuses_to_hash_a_file_that_reaches_outside(pose_file, secret):
    _replace(pose_file, "training/X", _external_storage(secret), reseal=False)
    with h5py.File(pose_file, "a") as h5, pytest.raises(FileContentError, match="external file"):
        seal(h5)


def test_soft_links_and_hard_link_loops_are_refused(pose_file):
    with h5py.File(pose_file) as h5:
        x = h5["training/X"][()]
    _replace(pose_file, "training/X", lambda h5, m, old: h5.__setitem__(m, h5py.SoftLink(m)),
             reseal=False)  # fmt: skip
    _refused(PosePredictor.load, pose_file, "training/X", "soft link")
    _replace(pose_file, "training/X", lambda h5, m, old: h5.create_dataset(m, data=x))
    PosePredictor.load(pose_file)  # restored: loads again
    _replace(pose_file, "training/again", lambda h5, m, old: h5.__setitem__(m, h5["training"]),
             reseal=False)  # fmt: skip
    _refused(PosePredictor.load, pose_file, "training/again", "second name")


@pytest.mark.parametrize("reader", POSE_READERS)
def test_lazily_allocated_giant_dataset_is_refused_before_any_allocation(pose_file, reader):
    """A 64 kB-scale file declaring 8 GB: refused from the metadata, nothing allocated."""

    def bomb(h5, member, old):
        h5.create_dataset(member, shape=(10**9,), dtype="f8")  # never written: not allocated

    _replace(pose_file, "training/junk", bomb, reseal=False)
    assert pose_file.stat().st_size < 200_000
    tracemalloc.start()
    try:
        _refused(POSE_READERS[reader], pose_file, "training/junk", "declares 8.0 GB")
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 50e6


def test_compressed_bomb_is_refused(pose_file):
    def bomb(h5, member, old):
        h5.create_dataset(member, data=np.zeros((4000, 3)), compression="gzip", chunks=True)

    _replace(pose_file, "training/X", bomb, reseal=False)
    _refused(PosePredictor.load, pose_file, "training/X", "chunked or compressed")


def _flip_in_training_x(path):
    with h5py.File(path) as h5:
        offset = h5["training/X"].id.get_offset()
    data = bytearray(path.read_bytes())
    data[offset + 8 * 10 + 3] ^= 0x10  # a low bit of one pose coordinate
    path.write_bytes(bytes(data))
    with h5py.File(path) as h5:  # still a valid HDF5 file with a plausible value
        assert np.all(np.isfinite(h5["training/X"][()]))


def test_a_flipped_bit_in_a_value_is_an_error_not_another_answer(pose_file):
    """Caught by the byte checksum before HDF5 parses the file, and by the content checksum
    where the byte one is gone."""
    _flip_in_training_x(pose_file)
    _refused(PosePredictor.load, pose_file, None, "bytes do not match the checksum")
    _refused(PoseModalModel.load, pose_file, None, "bytes do not match the checksum")
    _strip_file_seal(pose_file)
    _refused(PosePredictor.load, pose_file, None, "content does not match its checksum")
    _refused(PoseModalModel.load, pose_file, None, "content does not match its checksum")


def test_damaged_metadata_never_reaches_the_hdf5_library(tmp_path):
    """Two bit flips that make libhdf5 itself crash (segmentation fault in h5py's attribute
    reading, found by the corruption property) are refused from the byte checksum first."""
    from robovib.hybrid import FRFPoseModel

    f = np.linspace(2, 40, 12)
    h = np.array([(1 + s) * 1e-6 / (1 - (f / 15) ** 2 + 0.1j * f / 15) for s in (0.0, 1.2)])
    path = tmp_path / "m.h5"
    FRFPoseModel(f).fit(np.array([0.0, 1.2]), h).save(path)
    assert check_file_seal(path) == "verified"
    data = bytearray(path.read_bytes())
    for where in range(USERBLOCK_SIZE, len(data), 997):  # every region: header, heap, data
        damaged = bytearray(data)
        damaged[where] ^= 0x04
        path.write_bytes(bytes(damaged))
        _refused(FRFPoseModel.load, path, None, "bytes do not match the checksum")


def test_truncated_file_is_refused(pose_file):
    data = pose_file.read_bytes()
    pose_file.write_bytes(data[: len(data) // 2])
    _refused(PosePredictor.load, pose_file, None, "cut short")
    _strip_file_seal(pose_file)
    _refused(PosePredictor.load, pose_file, None, "not a readable HDF5 file (truncated")


@pytest.mark.parametrize(
    ("member", "build", "words"),
    [
        ("training/X", lambda h5, m, old: h5.create_dataset(m, data=old[:, :2]),
         "has shape (180, 2), expected (any, 3)"),
        ("training/X", lambda h5, m, old: h5.create_dataset(m, data=old.astype("S8")),
         "expected real numbers"),
        ("training/X", lambda h5, m, old: h5.create_dataset(m, data=np.where(old > 0, np.nan, old)),
         "NaN"),
        ("estimators/0/signal_std", lambda h5, m, old: h5.create_dataset(m, data=-old),
         "not positive"),
        ("estimators/0/Y", lambda h5, m, old: h5.create_dataset(m, data=old[:-1]),
         "has shape (179, 6), expected (180, 6)"),
        ("training/mask", lambda h5, m, old: None, "dataset is missing"),
    ],
)  # fmt: skip
@pytest.mark.parametrize("reader", POSE_READERS)
def test_pose_members_of_the_wrong_type_or_shape_are_named(pose_file, member, build, words, reader):
    _replace(pose_file, member, build)  # checksum recomputed: only the format checks see it
    _refused(POSE_READERS[reader], pose_file, member, words)


def test_frf_file_attacks_are_refused(tmp_path, frf_file, secret):
    member = "frf/000000/frequency_hz"
    original = frf_file.read_bytes()
    _replace(frf_file, member, _external_storage(secret), reseal=False)
    _refused(read_frfs, frf_file, member, "external file")
    _refused(read_provenance, frf_file, member, "external file")
    other = tmp_path / "other.h5"
    with h5py.File(other, "w") as h5:
        h5.create_dataset("X", data=np.linspace(1, 2, 64))
    for build, words in ((_external_link(other), "external link"), (_virtual(other), "virtual")):
        frf_file.write_bytes(original)
        _replace(frf_file, member, build, reseal=False)
        _refused(read_frfs, frf_file, member, words)
    frf_file.write_bytes(original)
    _replace(frf_file, "frf/000000/values", lambda h5, m, old: h5.create_dataset(m, data=old[:5]))
    _refused(read_frfs, frf_file, "frf/000000/values", "has 5 bins but frequency_hz has 64")
    frf_file.write_bytes(original)
    _replace(frf_file, member, lambda h5, m, old: h5.create_dataset(m, data=old[::-1]))
    _refused(read_frfs, frf_file, "frf/000000", "strictly increasing")


def test_hybrid_model_attacks_are_refused(tmp_path, secret):
    from robovib.hybrid import FRFPoseModel

    f = np.linspace(2, 40, 12)
    h = np.array([(1 + s) * 1e-6 / (1 - (f / 15) ** 2 + 0.1j * f / 15) for s in (0.0, 1.2)])
    path = tmp_path / "m.h5"
    FRFPoseModel(f).fit(np.array([0.0, 1.2]), h).save(path)
    original = path.read_bytes()
    _replace(path, "X_train", _external_storage(secret), reseal=False)
    _refused(FRFPoseModel.load, path, "X_train", "external file")
    path.write_bytes(original)
    _replace(path, "theta", lambda h5, m, old: h5.create_dataset(m, data=old[:, :2]))
    _refused(FRFPoseModel.load, path, "theta", "has shape")
    path.write_bytes(original)
    _replace(path, "y_scale", lambda h5, m, old: h5.create_dataset(m, data=np.zeros_like(old)))
    _refused(FRFPoseModel.load, path, "y_scale", "not positive")


def test_cli_names_the_file_in_one_line(pose_file, secret):
    _replace(pose_file, "training/X", _external_storage(secret), reseal=False)
    argv = ["gpr", "predict", "--model", str(pose_file), "--x", "2000", "--y", "0", "--rz", "0"]
    result = CliRunner().invoke(app, argv)
    assert result.exit_code == 1
    lines = result.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), result.output
    assert str(pose_file) in lines[0] and "training/X" in lines[0] and "unexpected" not in lines[0]
    assert "root:x" not in result.output


def test_writers_seal_and_the_seal_is_independent_of_layout(tmp_path, frf_file):
    with h5py.File(frf_file) as h5:
        stored = h5.attrs[CHECKSUM_ATTR]
        digest = content_sha256(h5)
        # an independent copy of the same content (h5py copies object by object): same digest
        with h5py.File(tmp_path / "copy.h5", "w") as out:
            for key, value in h5.attrs.items():
                out.attrs[key] = value
            for name in h5:
                h5.copy(h5[name], out, name)
            assert content_sha256(out) == digest
    assert stored == digest
    with h5py.File(chapter3_model_path()) as h5:  # the shipped model is sealed
        assert h5.attrs[CHECKSUM_ATTR] == content_sha256(h5)
    assert check_file_seal(chapter3_model_path()) == check_file_seal(frf_file) == "verified"


def test_files_without_a_checksum_still_load(pose_file):
    ref = PosePredictor.load(pose_file).predict([[2000.0, 0.0, 0.0]])
    with h5py.File(pose_file, "a") as h5:
        del h5.attrs[CHECKSUM_ATTR]
    _strip_file_seal(pose_file)
    from robovib.files.h5safe import UnverifiedFileWarning
    from robovib.gp.pose_file import read_pose_file

    with pytest.warns(UnverifiedFileWarning, match="no checksum stored"):  # loud, not silent
        assert read_pose_file(pose_file)[0].checksum == "none stored"
    with pytest.warns(UnverifiedFileWarning):
        assert PoseModalModel.load(pose_file).file_attrs_["content_sha256"] == "none stored"
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error", UnverifiedFileWarning)  # a sealed file does not warn
        loaded = PoseModalModel.load(chapter3_model_path())
    assert loaded.file_attrs_["content_sha256"] == "verified"
    with pytest.warns(UnverifiedFileWarning):
        again = PosePredictor.load(pose_file).predict([[2000.0, 0.0, 0.0]])
    np.testing.assert_array_equal(again, ref)


def test_input_files_record_every_hdf5_file_read_named_or_not(tmp_path):
    """The shipped default model is read without being named: input_files still lists it."""
    import hashlib
    import json

    argv = ["gpr", "predict", "--x", "2000", "--y", "0", "--rz", "0", "--json"]
    doc = json.loads(CliRunner().invoke(app, argv).stdout)
    (item,) = doc["input_files"]
    assert item["path"] == str(chapter3_model_path())
    assert item["sha256"] == hashlib.sha256(chapter3_model_path().read_bytes()).hexdigest()
    model = tmp_path / "mine.h5"
    shutil.copy(chapter3_model_path(), model)
    doc = json.loads(CliRunner().invoke(app, [*argv, "--model", str(model)]).stdout)
    assert [i["path"] for i in doc["input_files"]] == [str(model)]
