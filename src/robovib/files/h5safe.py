"""HDF5 files that touch only themselves: the checks every robovib HDF5 reader runs.

An HDF5 file can make its reader read *other* files (external raw storage, external links,
virtual datasets), loop (soft links, a group hard-linked below itself), or claim far more data
than it holds (a lazily allocated or compressed dataset of 10⁹ elements in a 64 KB file). A
robovib file does none of this: every member is a hard link, every dataset is stored in full,
contiguous and uncompressed, in the file itself. :func:`check_self_contained` refuses anything
else from the file's metadata alone, before any data is read, so the data a reader then reads
is bounded by the file's size on disk.

Every robovib writer seals its file twice. :func:`seal` stores the root attribute
``content_sha256``, the SHA-256 of every dataset and attribute (:func:`content_sha256`), which
:func:`verify_seal` recomputes on reading: a flipped bit in a value is an error rather than a
different answer. :func:`seal_file` then writes the SHA-256 of the file's bytes into its first
:data:`USERBLOCK_SIZE` bytes (HDF5's user block), which :func:`open_file` checks *before* the
HDF5 library parses anything: damaged HDF5 metadata can crash the library itself (a
segmentation fault, not an exception), so a damaged sealed file never reaches it. Files written
before the seals existed have neither and are read as before (``"none stored"``); a damaged
unsealed file is parsed, and the HDF5 library's robustness is then the limit.

Every error is a :class:`FileContentError`: one line that names the file, the member and the
problem in words.

Only h5py and NumPy are imported (h5py lazily): the fast prediction path uses this module.
"""

from __future__ import annotations

import hashlib
import json
import os
from collections.abc import Iterator
from pathlib import Path
from typing import NamedTuple

import numpy as np

__all__ = [
    "CHECKSUM_ATTR",
    "MAX_OBJECTS",
    "USERBLOCK_SIZE",
    "FileContentError",
    "Scan",
    "UnverifiedFileWarning",
    "check_file_seal",
    "check_self_contained",
    "content_sha256",
    "open_file",
    "read_array",
    "scan",
    "seal",
    "seal_file",
    "verify_seal",
]

#: Root attribute holding the SHA-256 of a file's content (:func:`content_sha256`).
CHECKSUM_ATTR = "content_sha256"
#: Bytes reserved at the start of every robovib HDF5 file (HDF5's user block, which the HDF5
#: library skips) for the SHA-256 of the rest of the file (:func:`seal_file`).
USERBLOCK_SIZE = 512


class UnverifiedFileWarning(UserWarning):
    """An HDF5 file without robovib's checksums: read, but damage cannot be detected."""


_FILE_SEAL_MAGIC = b"robovib file sha256 "
#: Most groups and datasets a robovib file may hold (a pose model holds about 100).
MAX_OBJECTS = 100_000
#: Deepest group nesting a robovib file may have (a pose model nests 4 deep).
MAX_DEPTH = 32
#: Dataset element types robovib writes: bool, integers, floats, complex, fixed strings.
_DATA_KINDS = "biufcS"


class FileContentError(ValueError):
    """A file that is not what it claims to be, or reaches outside itself.

    The message is one line: the file, the member (dataset or group path inside the file,
    when there is one) and the problem in words.

    Parameters
    ----------
    path : str or pathlib.Path
        The file.
    problem : str
        What is wrong, in words.
    member : str, optional
        The dataset or group inside the file.
    """

    def __init__(self, path, problem: str, member: str | None = None) -> None:
        self.path = str(path)
        self.member = member
        self.problem = problem
        where = f"{self.path}" if member is None else f"{self.path}: '{member}'"
        super().__init__(f"{where}: {problem}")


def _size_text(n: float) -> str:
    for unit in ("bytes", "kB", "MB", "GB", "TB"):
        if n < 1000 or unit == "TB":
            return f"{n:.0f} {unit}" if unit == "bytes" else f"{n:.1f} {unit}"
        n /= 1000
    raise AssertionError  # pragma: no cover


def _walk(h5, path) -> Iterator[tuple[str, object]]:
    """Every group and dataset below ``h5`` (name, object), hard links only, each once.

    Link classes are read before an object is touched, so an external link is never opened.
    """
    import h5py

    seen: set = set()
    count = 0
    stack = [("", h5, 0)]
    while stack:
        prefix, group, depth = stack.pop()
        if depth > MAX_DEPTH:
            raise FileContentError(
                path, f"groups nested more than {MAX_DEPTH} deep; not a robovib file", prefix
            )
        try:
            names = list(group.keys())
        except (KeyError, OSError, RuntimeError, ValueError, UnicodeDecodeError):
            raise FileContentError(
                path, "group members cannot be listed (damaged file)", prefix or "/"
            ) from None
        if not all(isinstance(n, str) for n in names):
            raise FileContentError(
                path, "a member name is not valid text (damaged file)", prefix or "/"
            )
        names.sort()
        for name in names:
            member = f"{prefix}/{name}" if prefix else name
            try:
                info = group.id.links.get_info(name.encode())
            except (KeyError, OSError, RuntimeError, ValueError):
                raise FileContentError(path, "link cannot be read (damaged file)", member) from None
            if info.type != h5py.h5l.TYPE_HARD:
                _refuse_link(group, name, member, path)
            if info.u in seen:
                raise FileContentError(
                    path,
                    "is a second name of an object already in the file (a hard link, possibly a "
                    "loop); robovib files name every object once",
                    member,
                )
            seen.add(info.u)
            count += 1
            if count > MAX_OBJECTS:
                raise FileContentError(
                    path, f"more than {MAX_OBJECTS} groups and datasets; not a robovib file"
                )
            try:
                obj = group[name]
            except (KeyError, OSError, RuntimeError, ValueError):
                raise FileContentError(
                    path, "object cannot be opened (damaged file)", member
                ) from None
            yield member, obj
            if isinstance(obj, h5py.Group):
                stack.append((member, obj, depth + 1))


def _refuse_link(group, name: str, member: str, path):
    import h5py

    try:
        link = group.get(name, getlink=True)
    except (KeyError, OSError, RuntimeError, ValueError):
        link = None
    if isinstance(link, h5py.ExternalLink):
        raise FileContentError(
            path,
            f"external link to '{link.path}' in file '{link.filename}'; robovib reads only the "
            "file it is given and never follows links to other files",
            member,
        )
    if isinstance(link, h5py.SoftLink):
        raise FileContentError(
            path,
            f"soft link to '{link.path}'; robovib files hold no links (a link can loop or lead "
            "out of the file), so it is refused",
            member,
        )
    raise FileContentError(path, "link of a kind robovib never writes (user-defined) is refused",
                           member)  # fmt: skip


def _check_dataset(ds, member: str, path, file_size: int | None) -> int:
    """Refuse a dataset stored outside the file, virtual, not stored in full, or of a type
    robovib never writes; return its size in bytes."""
    try:
        plist = ds.id.get_create_plist()
        external = plist.get_external_count()
        virtual = ds.is_virtual
        layout = plist.get_layout()
        n_filters = plist.get_nfilters()
        dtype = ds.dtype
        shape = ds.shape
    except (OSError, RuntimeError, ValueError, TypeError):
        raise FileContentError(
            path, "dataset header cannot be read (damaged file)", member
        ) from None
    if external:
        try:
            name = plist.get_external(0)[0].decode(errors="replace")
        except Exception:  # the name is only for the message
            name = "another file"
        raise FileContentError(
            path,
            f"data stored in the external file '{name}'; robovib reads only the file it is "
            "given and never reads external storage",
            member,
        )
    if virtual:
        raise FileContentError(
            path,
            "virtual dataset (its data is mapped from other datasets or files); robovib reads "
            "only data stored in the file itself",
            member,
        )
    if shape is None:  # an empty (null-dataspace) dataset
        return 0
    import h5py

    kind = dtype.kind
    text = kind == "O" and h5py.check_string_dtype(dtype) is not None
    if not text and (kind not in _DATA_KINDS or (kind == "c" and dtype.itemsize not in (8, 16))):
        raise FileContentError(
            path, f"data type {dtype} is not one robovib writes (numbers, booleans, text)", member
        )
    # variable-length text: the dataset stores a 16-byte reference per string
    logical = int(np.prod(shape, dtype=object)) * (16 if text else dtype.itemsize)
    if logical == 0:
        return 0
    if file_size is not None and logical > file_size:
        raise FileContentError(
            path,
            f"declares {_size_text(logical)} of data in a file of {_size_text(file_size)}; "
            "robovib files store every dataset in full",
            member,
        )
    if n_filters or layout != h5py.h5d.CONTIGUOUS:
        raise FileContentError(
            path,
            "dataset is chunked or compressed; robovib writes every dataset contiguous and "
            "uncompressed, so the file was not written by robovib",
            member,
        )
    try:
        stored = ds.id.get_storage_size()
    except (OSError, RuntimeError, ValueError):
        raise FileContentError(
            path, "dataset storage cannot be read (damaged file)", member
        ) from None
    if stored != logical:
        raise FileContentError(
            path,
            f"declares {_size_text(logical)} of data but the file stores {_size_text(stored)} "
            "(lazily allocated or truncated); robovib files store every dataset in full",
            member,
        )
    return logical


def open_file(path: Path):
    """``h5py.File(path, "r")``, or a one-line error naming the file.

    Parameters
    ----------
    path : pathlib.Path
        The file.

    Returns
    -------
    h5py.File
        The file, open for reading (close it: ``with``).

    Raises
    ------
    ValueError
        Missing, a folder, not readable, truncated, or not HDF5.
    FileContentError
        The file's bytes do not match the checksum in its user block (:func:`seal_file`).
    """
    import h5py

    from .safe_read import MAX_BINARY_BYTES, check_input_file

    # Every HDF5 file robovib reads is opened here (open_checked, file_format,
    # read_provenance): a regular file within the size limits, before any byte is read (a FIFO
    # would block the checksum's read).
    path = check_input_file(path, "HDF5 file", MAX_BINARY_BYTES)
    if check_file_seal(path) == "none stored":
        import warnings

        warnings.warn(
            f"{path}: no checksum stored (written by an older robovib or another program): "
            "damage to its content cannot be detected",
            UnverifiedFileWarning,
            stacklevel=3,
        )
    try:
        return h5py.File(path, "r")
    except FileNotFoundError:
        raise ValueError(f"{path}: no such file") from None
    except IsADirectoryError:
        raise ValueError(f"{path}: is a folder, not an HDF5 file") from None
    except PermissionError:
        raise ValueError(f"{path}: permission denied") from None
    except OSError as exc:
        if "truncated file" in str(exc):
            raise ValueError(
                f"{path}: not a readable HDF5 file (truncated: it ends before its own data)"
            ) from None
        raise ValueError(f"{path}: not a readable HDF5 file (damaged or another format)") from None


def _file_size(h5, path) -> int | None:
    """Size on disk of the file behind ``h5`` (None for an in-memory file)."""
    try:
        if h5.file.driver not in ("sec2", "stdio"):
            return None
        return os.stat(h5.file.filename).st_size
    except (OSError, TypeError, ValueError):
        return None


class Scan(NamedTuple):
    """What :func:`scan` found.

    Parameters
    ----------
    members : dict
        Member path -> array (datasets; None when not read) or None (groups).
    attrs : dict
        Member path -> attributes of every group (``""``: the scanned group).
    checksum : str
        ``"verified"``, ``"none stored"`` or ``"not checked"``.
    digest : str or None
        :func:`content_sha256` of what was read (None when nothing was read).
    """

    members: dict
    attrs: dict
    checksum: str
    digest: str | None


def scan(h5, path=None, *, read: bool = True, verify: bool = True) -> Scan:
    """Check every member of an open file (or group) and, with ``read``, read and hash it.

    One pass over the file: each link is checked before its object is opened and each
    dataset before its data is read (the rules of :func:`check_self_contained`), so nothing
    outside the file is touched and what is read is bounded by the file's size on disk.

    Parameters
    ----------
    h5 : h5py.Group
        An open file or group.
    path : str or pathlib.Path, optional
        The file (for messages; default ``h5.file.filename``).
    read : bool
        Read every dataset (otherwise only the metadata is checked).
    verify : bool
        With ``read`` and ``h5`` a file's root: check the content against the stored
        :data:`CHECKSUM_ATTR`, if there is one.

    Returns
    -------
    Scan
        ``members``: ``member path -> numpy.ndarray`` for every dataset (None without
        ``read``), ``member path -> None`` for every group, paths relative to ``h5``;
        ``attrs``: ``member path -> dict`` of attributes of every group (``""``: ``h5``
        itself); ``checksum``: ``"verified"``, ``"none stored"``, or ``"not checked"`` (not
        read, or not the root); ``digest``: :func:`content_sha256` (None without ``read``).

    Raises
    ------
    FileContentError
        The first member that breaks a rule, or content that does not match the checksum.
    """
    import h5py

    path = h5.file.filename if path is None else path
    file_size = _file_size(h5, path)
    digest = hashlib.sha256() if read else None
    members: dict = {}
    attrs: dict = {"": _read_attrs(h5, path, "")}
    root = h5.name == "/"
    _hash_attrs(digest, attrs[""], skip_checksum=root)
    total = 0
    for member, obj in _walk(h5, path):
        if isinstance(obj, h5py.Dataset):
            total += _check_dataset(obj, member, path, file_size)
            if file_size is not None and total > file_size:
                raise FileContentError(
                    path,
                    f"its datasets declare {_size_text(total)} in a file of "
                    f"{_size_text(file_size)}; the file is damaged",
                    member,
                )
            data = None
            if read:
                data = _read(obj, member, path)
                digest.update(f"\0dataset\0{member}\0{data.dtype.str}{data.shape}\0".encode())
                digest.update(_attr_bytes(data) if data.dtype.kind in "OSU" else data.tobytes())
                _hash_attrs(digest, _read_attrs(obj, path, member))
            members[member] = data
        elif isinstance(obj, h5py.Group):
            members[member] = None
            attrs[member] = _read_attrs(obj, path, member)
            if read:
                digest.update(f"\0group\0{member}\0".encode())
                _hash_attrs(digest, attrs[member])
        else:
            raise FileContentError(path, f"object of kind {type(obj).__name__} is not one "
                                   "robovib writes", member)  # fmt: skip
    checksum = "not checked"
    if read and root:
        stored = attrs[""].get(CHECKSUM_ATTR)
        if stored is None:
            checksum = "none stored"
        elif verify:
            stored = stored.decode(errors="replace") if isinstance(stored, bytes) else str(stored)
            if digest.hexdigest() != stored:
                raise FileContentError(
                    path,
                    f"content does not match its checksum ({CHECKSUM_ATTR}): the file was "
                    "changed or damaged after robovib wrote it",
                )
            checksum = "verified"
    return Scan(members, attrs, checksum, None if digest is None else digest.hexdigest())


def _hash_attrs(digest, attrs: dict, skip_checksum: bool = False) -> None:
    if digest is None:
        return
    for key in sorted(attrs):
        if skip_checksum and key == CHECKSUM_ATTR:
            continue
        digest.update(f"\0attr\0{key}\0".encode())
        digest.update(_attr_bytes(attrs[key]))


def _read(ds, member: str, path) -> np.ndarray:
    try:
        return np.asarray(ds[()])
    except (OSError, RuntimeError, ValueError, TypeError):
        raise FileContentError(path, "data cannot be read (damaged file)", member) from None


def _read_attrs(obj, path, member: str) -> dict:
    try:
        attrs = dict(obj.attrs.items())
    except (OSError, RuntimeError, KeyError, TypeError, ValueError, UnicodeDecodeError):
        raise FileContentError(
            path, "attributes cannot be read (damaged file)", member or "/"
        ) from None
    if not all(isinstance(k, str) for k in attrs):
        raise FileContentError(
            path, "an attribute name is not valid text (damaged file)", member or "/"
        )
    return attrs


def check_self_contained(h5, path) -> None:
    """Refuse an HDF5 file that reaches outside itself or claims more data than it holds.

    Walks every link of the open file (metadata only, no data read) and refuses: external
    links, soft links, objects reachable by two names (hard-link loops), datasets with
    external raw storage, virtual datasets, chunked or compressed datasets, datasets whose
    declared size exceeds the file or what it stores, data types robovib never writes, more
    than :data:`MAX_OBJECTS` objects or groups nested deeper than :data:`MAX_DEPTH`.

    Parameters
    ----------
    h5 : h5py.File
        The file, open for reading.
    path : str or pathlib.Path
        Its path (for the message; its size bounds the datasets).

    Raises
    ------
    FileContentError
        The first member that breaks a rule, named with the file.
    """
    scan(h5, path, read=False)


def read_array(group, name: str, path, *, member: str | None = None) -> np.ndarray:
    """Read one dataset, naming the file and the dataset if HDF5 cannot.

    Call after :func:`check_self_contained`, which bounds what may be read.

    Parameters
    ----------
    group : h5py.Group
        The group holding the dataset.
    name : str
        The dataset's name in ``group``.
    path : str or pathlib.Path
        The file (for the message).
    member : str, optional
        The dataset's full path in the file (for the message; default ``group.name/name``).

    Returns
    -------
    numpy.ndarray
        The data (0-d for a scalar).

    Raises
    ------
    FileContentError
        The dataset is missing, not a dataset, or cannot be read.
    """
    import h5py

    where = member or f"{group.name.rstrip('/')}/{name}".lstrip("/")
    if name not in group:
        raise FileContentError(path, "dataset is missing", where)
    ds = group[name]
    if not isinstance(ds, h5py.Dataset):
        raise FileContentError(path, "is a group where a dataset was expected", where)
    try:
        return np.asarray(ds[()])
    except (OSError, RuntimeError, ValueError, TypeError):
        raise FileContentError(path, "data cannot be read (damaged file)", where) from None


def _attr_bytes(value) -> bytes:
    """Canonical bytes of an attribute value, the same at writing and at reading."""
    arr = np.asarray(value)
    if arr.dtype.kind in "OSU":
        items = [v.decode("utf-8", "replace") if isinstance(v, bytes) else str(v)
                 for v in arr.ravel().tolist()]  # fmt: skip
        return json.dumps([list(arr.shape), items]).encode()
    return f"{arr.dtype.str}{arr.shape}".encode() + arr.tobytes()


def content_sha256(h5, path=None) -> str:
    """SHA-256 of an HDF5 file's content: every group's and dataset's name, attributes
    (except :data:`CHECKSUM_ATTR`), type, shape and data, in name order.

    Independent of HDF5's layout on disk (object addresses, free space, creation order), so
    the same content gives the same digest whichever h5py wrote it.

    Parameters
    ----------
    h5 : h5py.File
        An open file (reading or writing).
    path : str or pathlib.Path, optional
        The file, for messages (default: ``h5.filename``).

    Returns
    -------
    str
        The hex digest.
    """
    return scan(h5, path, read=True, verify=False).digest


def seal(h5) -> None:
    """Store :func:`content_sha256` as the root attribute :data:`CHECKSUM_ATTR` (last step of
    every robovib HDF5 writer; call it again after changing the file).

    Parameters
    ----------
    h5 : h5py.File
        The file, open for writing, with all its content written.
    """
    h5.flush()
    h5.attrs[CHECKSUM_ATTR] = content_sha256(h5)


def verify_seal(h5, path) -> str:
    """Check every member of a file (:func:`scan`) and its content against its stored
    :data:`CHECKSUM_ATTR`.

    Parameters
    ----------
    h5 : h5py.File
        The file, open for reading.
    path : str or pathlib.Path
        The file (for the message).

    Returns
    -------
    str
        ``"verified"``, or ``"none stored"`` for a file written before robovib sealed files.

    Raises
    ------
    FileContentError
        A member that breaks a rule of :func:`check_self_contained`, or content that differs
        from the checksum (the file was changed or damaged).
    """
    try:
        sealed = CHECKSUM_ATTR in h5.attrs
    except (OSError, RuntimeError, ValueError, TypeError):
        raise FileContentError(path, "root attributes cannot be read (damaged file)") from None
    if not sealed:
        check_self_contained(h5, path)
        return "none stored"
    return scan(h5, path, read=True).checksum


def seal_file(path) -> None:
    """Write the SHA-256 of a closed HDF5 file's bytes into its user block (the last step of
    every robovib HDF5 writer, after :func:`seal` and closing the file).

    The file must have been created with ``userblock_size=USERBLOCK_SIZE``.

    Parameters
    ----------
    path : str or pathlib.Path
        The closed file.

    Raises
    ------
    ValueError
        The file has no user block of :data:`USERBLOCK_SIZE` bytes.
    """
    with open(path, "r+b") as fh:
        head = fh.read(USERBLOCK_SIZE)
        if len(head) < USERBLOCK_SIZE or head.startswith(b"\x89HDF"):
            raise ValueError(f"{path}: no {USERBLOCK_SIZE}-byte user block to seal")
        digest = hashlib.sha256()
        while block := fh.read(1 << 20):
            digest.update(block)
        stamp = _FILE_SEAL_MAGIC + digest.hexdigest().encode() + b"\n"
        fh.seek(0)
        fh.write(stamp.ljust(USERBLOCK_SIZE, b"\0"))


def check_file_seal(path) -> str:
    """Check a file's bytes against the checksum in its user block, before HDF5 parses it.

    Parameters
    ----------
    path : str or pathlib.Path
        The file.

    Returns
    -------
    str
        ``"verified"``, or ``"none stored"`` (no robovib user block: an older or foreign file).

    Raises
    ------
    FileContentError
        The bytes after the user block do not match its checksum.
    """
    try:
        with open(path, "rb") as fh:
            head = fh.read(USERBLOCK_SIZE)
            if not head.startswith(_FILE_SEAL_MAGIC):
                return "none stored"
            digest = hashlib.sha256()
            while block := fh.read(1 << 20):
                digest.update(block)
    except OSError:
        return "none stored"  # h5py says why it cannot open the file
    stored = head[len(_FILE_SEAL_MAGIC) :].split(b"\n", 1)[0]
    if stored != digest.hexdigest().encode():
        raise FileContentError(
            path,
            "its bytes do not match the checksum robovib wrote at its start: the file was "
            "changed, damaged or cut short after robovib wrote it",
        )
    return "verified"
