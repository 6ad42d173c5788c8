"""Input files that cannot block or flood a reader: one check for every reader of robovib.

Every reader calls :func:`check_input_file` before it opens a file the user named. The file
must exist and be a regular file (a symbolic link to one is fine): a FIFO, a character or block
device (``/dev/zero``), a socket or a folder is refused with a message saying what it is, so a
reader never blocks on a pipe nobody writes to, nor reads an endless device until memory runs
out. The file must also be smaller than a size limit (:data:`MAX_TEXT_BYTES` for text tables and
recordings, :data:`MAX_BINARY_BYTES` for HDF5 and UFF files); the environment variable
``ROBOVIB_MAX_INPUT_MB`` raises or lowers every limit at once. :func:`read_bytes_checked` reads
a text file in one go, checks it and stops at the limit even if the file grows meanwhile.

Inside a command of the command line (:func:`recording_inputs`), every file checked is also
remembered as an input of the run, so :func:`robovib.io.check_output_path` refuses to write an
output over any file the command read (a manifest or poses file inside the output folder too).
"""

from __future__ import annotations

import contextlib
import os
import stat
from collections.abc import Iterator
from contextvars import ContextVar
from pathlib import Path

__all__ = [
    "MAX_BINARY_BYTES",
    "MAX_TEXT_BYTES",
    "InputFileError",
    "check_input_file",
    "inputs_read",
    "note_written",
    "read_bytes_checked",
    "recording_inputs",
]

#: Largest text input (CSV tables, recordings, cuts, manifests) [bytes]: 1 GiB.
MAX_TEXT_BYTES = 1 << 30
#: Largest binary input (HDF5 model and FRF files, UFF recordings) [bytes]: 16 GiB.
MAX_BINARY_BYTES = 16 << 30
_ENV = "ROBOVIB_MAX_INPUT_MB"


class InputFileError(ValueError):
    """An input that is not a readable regular file of acceptable size."""


#: Files read and written by the running command (None: none running, nothing recorded).
_RUN: ContextVar[dict[str, list[str]] | None] = ContextVar("robovib_run_files", default=None)


@contextlib.contextmanager
def recording_inputs() -> Iterator[dict[str, list[str]]]:
    """Record every file :func:`check_input_file` accepts while the block runs (the CLI does this).

    Yields
    ------
    dict
        ``{"read": [...], "written": [...]}``: resolved paths, growing while the block runs.
    """
    files: dict[str, list[str]] = {"read": [], "written": []}
    token = _RUN.set(files)
    try:
        yield files
    finally:
        _RUN.reset(token)


def _remember(kind: str, path: Path) -> None:
    files = _RUN.get()
    if files is None:
        return
    with contextlib.suppress(OSError):
        resolved = str(path.resolve())
        if resolved not in files[kind]:
            files[kind].append(resolved)


def note_written(path: str | os.PathLike) -> None:
    """Remember that the running command wrote ``path`` (reading it back makes no input of it).

    Parameters
    ----------
    path : path-like
        The output file.
    """
    _remember("written", Path(os.fspath(path)))


def inputs_read() -> tuple[str, ...]:
    """Resolved paths of the files the running command read and did not write itself
    (empty outside a command).

    Returns
    -------
    tuple of str
        The paths.
    """
    files = _RUN.get()
    if files is None:
        return ()
    return tuple(p for p in files["read"] if p not in files["written"])


def _kind(mode: int) -> str:
    if stat.S_ISDIR(mode):
        return "a folder"
    if stat.S_ISFIFO(mode):
        return "a FIFO (named pipe)"
    if stat.S_ISCHR(mode):
        return "a character device"
    if stat.S_ISBLK(mode):
        return "a block device"
    if stat.S_ISSOCK(mode):
        return "a socket"
    return "not a regular file"


def _limit(max_bytes: int | None) -> int | None:
    env = os.environ.get(_ENV, "").strip()
    if env:
        try:
            return int(float(env) * (1 << 20))
        except ValueError:
            raise InputFileError(f"{_ENV}={env!r} is not a number of megabytes") from None
    return max_bytes


def _size_words(n: int) -> str:
    return f"{n / (1 << 20):.3g} MB" if n >= 1 << 20 else f"{n} bytes"


def check_input_file(
    path: str | os.PathLike, what: str = "input file", max_bytes: int | None = MAX_TEXT_BYTES
) -> Path:
    """Check that ``path`` is an existing regular file below a size limit; return it as a Path.

    Parameters
    ----------
    path : path-like
        The input file.
    what : str
        What the file is, for messages (``"manifest file"``, ``"cuts file"``, ``"pose model"``...).
    max_bytes : int or None
        Largest size accepted [bytes] (None: no limit). ``ROBOVIB_MAX_INPUT_MB`` overrides it.

    Returns
    -------
    pathlib.Path
        ``path``.

    Raises
    ------
    InputFileError
        (a ``ValueError``) No such file, a folder, FIFO, device or socket, unreadable, or larger
        than the limit; the message names the file and what it is.
    """
    p = Path(os.fspath(path))
    try:
        st = os.stat(p)  # follows links: a link to a regular file is that file
    except FileNotFoundError:
        if p.is_symlink():
            raise InputFileError(f"{p}: the {what} is a broken symbolic link") from None
        raise InputFileError(f"{p}: no such {what}") from None
    except NotADirectoryError:
        raise InputFileError(f"{p}: no such {what} (a part of the path is a file)") from None
    except OSError as exc:
        raise InputFileError(f"{p}: cannot read the {what} ({exc.strerror or exc})") from None
    if not stat.S_ISREG(st.st_mode):
        raise InputFileError(f"{p}: the {what} is {_kind(st.st_mode)}, not a regular file")
    if not os.access(p, os.R_OK):
        raise InputFileError(f"{p}: the {what} is not readable (permission denied)")
    limit = _limit(max_bytes)
    if limit is not None and st.st_size > limit:
        raise InputFileError(
            f"{p}: the {what} is {_size_words(st.st_size)}, larger than the {_size_words(limit)} "
            f"a {what} may have (set {_ENV} to raise the limit)"
        )
    _remember("read", p)
    return p


def read_bytes_checked(
    path: str | os.PathLike, what: str = "input file", max_bytes: int | None = MAX_TEXT_BYTES
) -> bytes:
    """The bytes of a checked input file (:func:`check_input_file`), never more than the limit.

    Parameters
    ----------
    path : path-like
        The file.
    what : str
        What the file is, for messages.
    max_bytes : int or None
        Largest size accepted [bytes] (None: no limit).

    Returns
    -------
    bytes
        The content.

    Raises
    ------
    InputFileError
        See :func:`check_input_file`; also a file that grew past the limit while being read.
    """
    p = check_input_file(path, what, max_bytes)
    limit = _limit(max_bytes)
    try:
        # O_NONBLOCK: should the file have been swapped for a FIFO since the check, opening
        # it returns at once instead of waiting for a writer (regular files ignore the flag).
        fd = os.open(p, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
    except OSError as exc:
        raise InputFileError(f"{p}: cannot read the {what} ({exc.strerror or exc})") from None
    with os.fdopen(fd, "rb") as fh:
        if not stat.S_ISREG(os.fstat(fh.fileno()).st_mode):
            raise InputFileError(f"{p}: the {what} is not a regular file")
        data = fh.read() if limit is None else fh.read(limit + 1)
    if limit is not None and len(data) > limit:
        raise InputFileError(
            f"{p}: the {what} grew past the {_size_words(limit)} limit while being read"
        )
    return data
