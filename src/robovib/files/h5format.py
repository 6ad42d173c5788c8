"""The one header convention of every HDF5 file robovib writes, and its one reader.

Every file carries, as root attributes: ``format`` (what it holds, e.g.
``robovib.PoseModalModel``), ``format_version`` (an integer that grows when the layout
changes), ``robovib_version`` (the writer) and ``created_utc``, and the units of what it holds
(``units``, or a ``units`` attribute on each dataset). :func:`open_checked` opens a
file for reading and checks the tag and version in one place, so every reader refuses a foreign
or newer file with the same clear message. Files written before the convention named the
version ``version``; it is read as ``format_version``.

Only h5py is imported (lazily): the fast prediction path uses this module.
"""

from __future__ import annotations

from collections.abc import Mapping
from datetime import UTC, datetime
from pathlib import Path

import numpy as np

__all__ = [
    "FRF_FORMAT",
    "FRF_POSE_MODEL_FORMAT",
    "LOBE_MAP_FORMAT",
    "LOBE_MAP_FORMAT_VERSION",
    "POSE_MODEL_FORMAT",
    "POSE_MODEL_FORMAT_VERSION",
    "H5Tree",
    "as_text",
    "file_format",
    "open_checked",
    "open_verified",
    "read_tree",
    "write_header",
]

#: Format tag of FRF collections (:func:`robovib.io.write_frfs_hdf5`), layout version 1.
FRF_FORMAT = "robovib-frf"
#: Format tag of hybrid FRF pose models (:meth:`robovib.hybrid.FRFPoseModel.save`), versions 1-2.
FRF_POSE_MODEL_FORMAT = "robovib-frf-pose-model"
#: Format tag and layout version of pose models (:meth:`robovib.gp.PoseModalModel.save`).
POSE_MODEL_FORMAT = "robovib.PoseModalModel"
POSE_MODEL_FORMAT_VERSION = 1
#: Format tag and layout version of workspace stability maps (NetCDF-4, an HDF5 file:
#: :func:`robovib.milling.maps.save_lobe_map`).
LOBE_MAP_FORMAT = "robovib-lobe-map"
LOBE_MAP_FORMAT_VERSION = 1


def write_header(h5, format_name: str, format_version: int, **attrs) -> None:
    """Write the root attributes of the convention (and any extra ``attrs``).

    Parameters
    ----------
    h5
        An ``h5py.File`` open for writing.
    format_name, format_version
        What the file holds and its layout version.
    **attrs
        Further root attributes (strings, numbers, lists of strings).
    """
    from .. import __version__

    h5.attrs["format"] = format_name
    h5.attrs["format_version"] = int(format_version)
    h5.attrs["robovib_version"] = __version__
    h5.attrs["created_utc"] = datetime.now(UTC).isoformat(timespec="seconds")
    for key, value in attrs.items():
        h5.attrs[key] = value


def as_text(v) -> str:
    """An HDF5 attribute as text (h5py returns bytes or str depending on how it was written).

    Parameters
    ----------
    v
        The attribute value.

    Returns
    -------
    str
        The text.

    Examples
    --------
    >>> as_text(b"robovib-frf"), as_text("x_mm")
    ('robovib-frf', 'x_mm')
    """
    return v.decode() if isinstance(v, bytes) else str(v)


def file_format(path) -> tuple[str, int]:
    """``(format, format_version)`` of an HDF5 file (``("", -1)`` when untagged).

    Parameters
    ----------
    path : str or pathlib.Path
        The HDF5 file.

    Returns
    -------
    tuple of (str, int)
        The format tag and its version.

    Raises
    ------
    ValueError
        Not a readable HDF5 file.
    """
    path = Path(path)
    with _open(path) as h5:
        return _tag(h5, path)


def _open(path: Path):
    from .h5safe import open_file

    return open_file(path)


def _tag(h5, path=None) -> tuple[str, int]:
    from .h5safe import FileContentError

    try:
        a = h5.attrs
        version = a.get("format_version", a.get("version", -1))
        fmt = a.get("format", "")
    except (OSError, RuntimeError, KeyError, TypeError, ValueError):
        raise FileContentError(
            path or h5.filename, "root attributes cannot be read (damaged file)"
        ) from None
    if not isinstance(fmt, str | bytes) or np.ndim(version) != 0:
        raise FileContentError(path or h5.filename, "format tag or version is not a single value")
    try:
        return as_text(fmt), int(version)
    except (TypeError, ValueError, UnicodeDecodeError):
        raise FileContentError(
            path or h5.filename, f"format version {version!r} is not an integer"
        ) from None


def open_checked(path, formats: Mapping[str, int], what: str | None = None):
    """Open an HDF5 file for reading after checking its format tag and version.

    Parameters
    ----------
    path
        The file.
    formats
        Accepted format tags -> the newest version this robovib reads of each.
    what
        Words for the error message (default: the accepted tags).

    Returns
    -------
    h5py.File, str, int
        The open file (close it: ``with``), its format tag and version.

    Raises
    ------
    ValueError
        Not a readable HDF5 file, another format, or a version newer than supported.
    robovib.files.h5safe.FileContentError
        The file reaches outside itself (external storage or links, virtual datasets, soft
        links), declares more data than it stores, or its content does not match its checksum
        (see :mod:`robovib.files.h5safe`).
    """
    h5, fmt, version, _ = open_verified(path, formats, what)
    return h5, fmt, version


def open_verified(
    path, formats: Mapping[str, int], what: str | None = None, *, read_whole: bool = False
):
    """:func:`open_checked` that also says whether the file's checksum was verified.

    Before any data is read the file is checked to touch only itself
    (:func:`robovib.files.h5safe.check_self_contained`), then its content is checked against the
    checksum robovib's writers store (:func:`robovib.files.h5safe.verify_seal`).

    Parameters
    ----------
    path, formats, what
        As :func:`open_checked`.
    read_whole
        The caller reads the whole file with :func:`read_tree`, which makes the same checks
        in the same pass: they are not made here (the checksum is returned as
        ``"not checked"``).

    Returns
    -------
    h5py.File, str, int, str
        The open file (close it: ``with``), its format tag and version, and ``"verified"`` or
        ``"none stored"`` (a file written before robovib stored checksums).

    Raises
    ------
    ValueError
        As :func:`open_checked`.
    """
    from .h5safe import verify_seal
    from .safe_read import MAX_BINARY_BYTES, check_input_file

    path = check_input_file(path, what or "HDF5 file", MAX_BINARY_BYTES)  # no FIFO, no device
    h5 = _open(path)
    try:
        fmt, version = _tag(h5, path)
        if fmt not in formats:
            expected = what or " or ".join(formats)
            raise ValueError(f"{path}: not a {expected} file (format tag {fmt!r})")
        if version < 1 or version > formats[fmt]:
            raise ValueError(
                f"{path}: {fmt} format version {version}; this robovib reads versions 1 to "
                f"{formats[fmt]}"
            )
        seal = "not checked" if read_whole else verify_seal(h5, path)
    except BaseException:
        h5.close()
        raise
    from .provenance import note_input_file

    note_input_file(path)  # the run's input_files record every file read, named or not
    return h5, fmt, version, seal


class H5Tree(dict):
    """An HDF5 group read into memory: a dict of its members plus ``attrs`` (a dict).

    Members are :class:`H5Tree` (subgroups) or NumPy arrays (datasets; scalars as 0-d arrays),
    so code written for an open ``h5py.Group`` reads it unchanged: ``tree.attrs[name]``,
    ``tree[name][()]``, ``name in tree``, ``tree.items()``, ``len(tree)``.

    Parameters
    ----------
    members : mapping or iterable of (str, object), optional
        Subgroups and datasets by name.
    attrs : mapping or iterable of (str, object), optional
        The group's attributes.
    """

    def __init__(self, members=(), attrs=None) -> None:
        super().__init__(members)
        self.attrs = dict(attrs or {})
        #: ``"verified"``, ``"none stored"`` or None (not checked): the file's checksum.
        self.checksum: str | None = None


def read_tree(group, path=None) -> H5Tree:
    """Read an ``h5py`` group (or file) and everything below it into an :class:`H5Tree`.

    Only what the file itself stores is read: links, external storage, virtual datasets and
    datasets not stored in full are refused first (:func:`robovib.files.h5safe.scan`),
    so what is read is bounded by the file's size on disk.

    Parameters
    ----------
    group : h5py.Group
        An open group or file.
    path : str or pathlib.Path, optional
        The file, for messages (default: the file's name).

    Returns
    -------
    H5Tree
        Attributes as h5py gives them; datasets as arrays (``tree[name][()]`` returns what
        ``group[name][()]`` does).

    Raises
    ------
    robovib.files.h5safe.FileContentError
        A member that reaches outside the file or cannot be read, or (``group`` a file's root)
        content that does not match the file's checksum; named with the file.

    Examples
    --------
    >>> import io, h5py, numpy as np
    >>> from robovib.files.h5format import read_tree
    >>> with h5py.File(io.BytesIO(), "w") as h5:
    ...     h5.attrs["kind"] = "demo"
    ...     _ = h5.create_group("g").create_dataset("x", data=np.arange(3.0))
    ...     tree = read_tree(h5)
    >>> tree.attrs["kind"], tree["g"]["x"][()].tolist()
    ('demo', [0.0, 1.0, 2.0])
    """
    from .h5safe import scan

    members, attrs, checksum, _ = scan(group, path, read=True, verify=True)
    root = H5Tree(attrs=attrs[""])
    root.checksum = checksum
    groups = {"": root}
    for member in sorted(members, key=lambda m: m.count("/")):
        parent, _, name = member.rpartition("/")
        value = members[member]
        if value is None:
            groups[member] = H5Tree(attrs=attrs[member])
            value = groups[member]
        groups[parent][name] = value
    return root
