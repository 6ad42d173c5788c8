"""Safe, atomic output files: one place for every writer of robovib.

Every file robovib writes goes through :func:`atomic_output`: the content is written to a
temporary file with a unique name in the target folder (so two writers never share one), and
only a complete write is moved over the target with :func:`os.replace` (atomic on POSIX and
Windows when source and target are on one file system). If the write fails — an exception,
``KeyboardInterrupt``, a full disk — the temporary file is removed and any previous file at the
target is left exactly as it was.

Before anything is written the target is checked: its folder must exist and be writable, it must
not be a folder, and it must not be one of the command's input files (compared by resolved path
and, when both exist, by :func:`os.path.samefile`, so links and ``./a/../a.h5`` are caught) unless
``force=True``. Those problems raise :class:`OutputPathError` (a ``ValueError``) naming the file
or folder.

One rule for every output (``docs/files.md``):

* an output is never a file the command reads: the ``inputs`` given, and inside a command of the
  command line every file read so far (:func:`robovib.files.safe_read.recording_inputs`), such as
  a manifest or poses file inside an output folder. Only ``force=True`` (``--force`` where a
  command offers it) lets the new file replace an input, after the input was read;
* an existing output that is not a regular file (a symbolic link, FIFO, device, socket or
  folder) is refused, ``force`` or not: robovib replaces only regular files;
* a command that writes a set of files into a folder owns their names and replaces the set as a
  whole: files of its set that the run does not write are removed (:func:`remove_stale_outputs`),
  every other file in the folder is left alone.
"""

from __future__ import annotations

import contextlib
import os
import secrets
import stat
from collections.abc import Iterable, Iterator
from pathlib import Path

__all__ = [
    "OutputPathError",
    "atomic_output",
    "check_output_path",
    "remove_stale_outputs",
    "save_figure",
]


class OutputPathError(ValueError):
    """An output path that cannot or must not be written (missing folder, input file, ...)."""


def _same_file(a: Path, b: Path) -> bool:
    try:
        if a.resolve() == b.resolve():
            return True
    except OSError:
        pass
    try:
        return a.exists() and b.exists() and os.path.samefile(a, b)
    except OSError:
        return False


def _writable(p: Path) -> bool:
    """Writable by us, and not marked read-only for everybody (root ignores permissions)."""
    try:
        mode = os.stat(p).st_mode
    except OSError:
        return False
    return os.access(p, os.W_OK) and bool(mode & 0o222)


def check_output_path(
    path: str | os.PathLike,
    *,
    inputs: Iterable[str | os.PathLike | None] = (),
    force: bool = False,
) -> Path:
    """Check that ``path`` may be written; return it as a :class:`~pathlib.Path`.

    Parameters
    ----------
    path : path-like
        The output file.
    inputs : iterable of path-like, optional
        The files the output is computed from (``None`` entries are ignored).
    force : bool, default False
        Allow the output to replace one of ``inputs`` (the input is then lost).

    Returns
    -------
    Path

    Raises
    ------
    OutputPathError
        Output is a folder, a symbolic link, a FIFO, a device or a socket; its folder is missing,
        not a folder or not writable; or the output is one of ``inputs`` (or, inside a command,
        a file the command read) and ``force`` is False.
    """
    from .safe_read import inputs_read

    path = Path(os.fspath(path))
    if str(path) == "" or path.name in ("", ".", ".."):
        raise OutputPathError(f"output {str(path)!r} is not a file name")
    if path.is_dir():
        raise OutputPathError(f"output {path} is a folder, not a file")
    folder = path.parent if str(path.parent) != "" else Path(".")
    if not folder.exists():
        raise OutputPathError(f"output folder {folder} does not exist (writing {path.name})")
    if not folder.is_dir():
        raise OutputPathError(f"output folder {folder} is not a folder (writing {path.name})")
    if not _writable(folder):
        raise OutputPathError(f"output folder {folder} is not writable (writing {path.name})")
    if path.exists() and not _writable(path):
        raise OutputPathError(f"output {path} exists and is read-only")
    if not force:
        for inp in [*inputs, *inputs_read()]:
            if inp is None:
                continue
            inp = Path(os.fspath(inp))
            if _same_file(path, inp):
                raise OutputPathError(
                    f"output {path} is the input file {inp}; writing it would destroy the "
                    "input (choose another output; --force / force=True, where offered, "
                    "replaces it)"
                )
    _check_regular(path)  # after the input check: a link to an input is named as such
    return path


def _check_regular(path: Path) -> None:
    """An existing output must be a regular file: never replace a link, FIFO or device."""
    try:
        st = os.lstat(path)
    except OSError:
        return  # absent (or unreachable: the folder checks report it)
    mode = st.st_mode
    if stat.S_ISLNK(mode):
        raise OutputPathError(
            f"output {path} is a symbolic link; robovib replaces only regular files "
            "(write to the link's target or another name)"
        )
    if not stat.S_ISREG(mode):
        kind = (
            "a FIFO (named pipe)" if stat.S_ISFIFO(mode)
            else "a character device" if stat.S_ISCHR(mode)
            else "a block device" if stat.S_ISBLK(mode)
            else "a socket" if stat.S_ISSOCK(mode)
            else "not a regular file"
        )  # fmt: skip
        raise OutputPathError(
            f"output {path} exists and is {kind}; robovib replaces only regular files"
        )


def remove_stale_outputs(folder: str | os.PathLike, owned, written) -> list[Path]:
    """Remove the files of a command's output set that this run did not write.

    A command writing several files into a folder owns their names; rerun with other options
    (fewer poses, no ``--modes-band``) it must not leave the earlier run's files beside its own.

    Parameters
    ----------
    folder : path-like
        The output folder.
    owned : iterable of str
        Names (glob patterns relative to ``folder``) of every file the command may write there.
    written : iterable of path-like
        The files this run wrote.

    Returns
    -------
    list of pathlib.Path
        The files removed. Links and anything but regular files are never removed.
    """
    folder = Path(os.fspath(folder))
    keep = {Path(os.fspath(w)).resolve() for w in written}
    removed = []
    for pattern in owned:
        for p in sorted(folder.glob(pattern)):
            if p.is_symlink() or not p.is_file() or p.resolve() in keep:
                continue
            with contextlib.suppress(FileNotFoundError):
                p.unlink()
                removed.append(p)
    return removed


def _create_unique(folder: Path, name: str) -> Path:
    """Create an empty, unique temporary file ``.<name>.<random>.tmp<suffix>`` in ``folder``."""
    suffix = Path(name).suffix
    for _ in range(100):
        tmp = folder / f".{name}.{secrets.token_hex(6)}.tmp{suffix}"
        try:
            fd = os.open(tmp, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o666)  # umask applies
        except FileExistsError:
            continue
        except PermissionError:
            raise OutputPathError(
                f"output folder {folder} is not writable (writing {name})"
            ) from None
        os.close(fd)
        return tmp
    raise OutputPathError(f"could not create a temporary file in {folder}")  # pragma: no cover


@contextlib.contextmanager
def atomic_output(
    path: str | os.PathLike,
    *,
    inputs: Iterable[str | os.PathLike | None] = (),
    force: bool = False,
) -> Iterator[Path]:
    """Context manager yielding a temporary path to write; renamed onto ``path`` on success.

    The temporary file exists (empty) when the block starts, in the same folder as ``path`` and
    with the same suffix (so format detection by extension works). On any exception, including
    ``KeyboardInterrupt``, the temporary file is deleted and ``path`` is left untouched.

    Parameters
    ----------
    path : path-like
        Final output file.
    inputs : iterable of path-like, optional
        Input files of the computation; ``path`` must not be one of them unless ``force``.
    force : bool, default False
        Allow replacing an input file.

    Yields
    ------
    Path
        The temporary file to write.

    Raises
    ------
    OutputPathError
        See :func:`check_output_path`.

    Examples
    --------
    >>> with atomic_output("out.h5", inputs=["in.uff"]) as tmp:  # doctest: +SKIP
    ...     write_something(tmp)
    """
    from .safe_read import note_written

    path = check_output_path(path, inputs=inputs, force=force)
    folder = path.parent if str(path.parent) != "" else Path(".")
    tmp = _create_unique(folder, path.name)
    try:
        yield tmp
        if path.exists():  # keep the permissions of the file being replaced
            with contextlib.suppress(OSError):
                os.chmod(tmp, os.stat(path).st_mode & 0o7777)
        os.replace(tmp, path)
        note_written(path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


def save_figure(
    fig,
    path: str | os.PathLike,
    *,
    dpi: int = 120,
    inputs: Iterable[str | os.PathLike | None] = (),
    force: bool = False,
) -> Path:
    """Save a matplotlib figure atomically; the format comes from the suffix of ``path``.

    Parameters
    ----------
    fig : matplotlib.figure.Figure
        The figure.
    path : str or os.PathLike
        The image file (``.png``, ``.svg``, ``.pdf`` ...).
    dpi : int
        Resolution of raster formats.
    inputs : sequence of path
        Files the output was made from (never overwritten unless ``force``).
    force : bool
        Allow ``path`` to be one of ``inputs``.

    Returns
    -------
    pathlib.Path
        The file written.

    Raises
    ------
    OutputPathError
        See :func:`check_output_path`; also no suffix, or one matplotlib cannot write (the
        output and the formats named).
    """
    fmt = Path(os.fspath(path)).suffix.lstrip(".").lower()
    supported = sorted(fig.canvas.get_supported_filetypes())
    if fmt not in supported:  # else matplotlib names the temporary file's suffix ("tmp")
        what = f"suffix .{fmt} is not an image format" if fmt else "no suffix names its format"
        raise OutputPathError(
            f"output {path}: {what} matplotlib writes (use one of "
            f"{', '.join('.' + f for f in supported)})"
        )
    with atomic_output(path, inputs=inputs, force=force) as tmp:
        fig.savefig(tmp, dpi=dpi, format=fmt)
    return Path(os.fspath(path))
