"""Provenance of robovib outputs: version, command, settings and input-file hashes.

Every HDF5 file robovib writes gets a ``provenance`` group (:func:`write_provenance`) and a
``units`` attribute on each dataset (:func:`set_units`); every ``--json`` document of the
command line carries the same record (:func:`run_provenance`).

The command and its settings are known to the front end (the CLI), not to the writers: the front
end registers a provider with :func:`set_run_info_provider`; without one (library use), the
command is ``sys.argv`` and the settings are empty.
"""

from __future__ import annotations

import hashlib
import json
import os
import sys
from collections.abc import Callable, Iterable, Mapping
from contextvars import ContextVar
from pathlib import Path
from typing import Any

import numpy as np

__all__ = [
    "command_settings",
    "file_sha256",
    "forget_files_read",
    "note_input_file",
    "read_provenance",
    "run_provenance",
    "set_run_info_provider",
    "set_units",
    "unit_of_key",
    "write_provenance",
]

#: Key-name suffix -> unit (longest first). A key such as ``stiffness_n_per_m`` says its unit.
UNIT_SUFFIXES: tuple[tuple[str, str], ...] = (
    ("_m_per_s2_per_n", "m/s^2/N"),
    ("_m_per_s_per_n", "m/s/N"),
    ("_n_m_per_rad", "N m/rad"),
    ("_ns_per_m", "N s/m"),
    ("_n_per_m2", "N/m^2"),
    ("_n_per_m", "N/m"),
    ("_um_per_n", "um/N"),
    ("_mm_per_n", "mm/N"),
    ("_m_per_n", "m/N"),
    ("_m_per_s2", "m/s^2"),
    ("_mm_per_s", "mm/s"),
    ("_m_per_s", "m/s"),
    ("_mm_deg", "mm (positions), deg (angles)"),
    ("_hz", "Hz"),
    ("_rpm", "rpm"),
    ("_mm", "mm"),
    ("_um", "um"),
    ("_ms", "ms"),
    ("_m", "m"),
    ("_s", "s"),
    ("_deg", "deg"),
    ("_rad", "rad"),
    ("_nm", "N m"),
    ("_n", "N"),
    ("_kg", "kg"),
    ("_pct", "%"),
    ("_db", "dB"),
    ("_rel_error", "1"),
    ("_ratio", "1"),
    ("_fraction", "1"),
    ("_probability", "1"),
)


def unit_of_key(key: str) -> str | None:
    """The unit a key name carries in its suffix (``"natural_frequency_hz"`` -> ``"Hz"``), or
    None when the name carries none.

    Parameters
    ----------
    key : str
        The key name.

    Returns
    -------
    str or None
        The unit.
    """
    k = str(key).lower()
    for suffix, unit in UNIT_SUFFIXES:
        if k.endswith(suffix) or k == suffix[1:]:
            return unit
    return None


_PROVIDER: ContextVar[Callable[[], dict] | None] = ContextVar("robovib_run_info", default=None)
#: Files the readers opened during the run in progress (HDF5 models and data, e.g. the shipped
#: default model), recorded in its ``input_files`` beside the files named on the command line.
#: None: no run in progress, nothing recorded.
_FILES_READ: ContextVar[tuple[str, ...] | None] = ContextVar("robovib_files_read", default=None)


def command_settings(params, output_names=("output", "plot", "output_dir")) -> dict:
    """Settings, their units and the input files of a command from its parsed parameters.

    A setting's unit is the bracketed unit in its help text (``"Tool-tip X [mm]"`` -> ``mm``);
    numbers without one are dimensionless (``"1"``); a file path never gets a unit (its help may
    name its content's). Existing files among the values are inputs, except for the outputs.

    Parameters
    ----------
    params
        Iterable of ``(name, value, help)``: every parameter after parsing, defaults included
        (help may be None).
    output_names
        Parameters whose files are outputs, not inputs.

    Returns
    -------
    dict
        ``settings`` (name -> JSON-ready value), ``units`` (name -> unit) and ``inputs``
        (paths of the input files, as strings).

    Examples
    --------
    >>> command_settings([("x", 1200.0, "Tool-tip X [mm]"), ("k", 3, "Poses.")])["units"]
    {'x': 'mm', 'k': '1'}
    """
    import re

    settings: dict[str, Any] = {}
    units: dict[str, str] = {}
    inputs: list[str] = []
    for name, value, help_text in params:
        settings[name] = plain_json(list(value) if isinstance(value, tuple) else value)
        found = re.search(r"\[([^\]]+)\]", help_text or "")
        vals = value if isinstance(value, list | tuple) else [value]
        if found and not any(isinstance(v, Path) for v in vals):
            units[name] = found.group(1)
        elif any(isinstance(v, int | float) and not isinstance(v, bool) for v in vals):
            units[name] = "1"
        if name not in output_names:
            inputs += [str(v) for v in vals if isinstance(v, Path) and v.is_file()]
    return {"settings": settings, "units": units, "inputs": inputs}


def set_run_info_provider(provider: Callable[[], dict] | None):
    """Register a callable returning ``{"command": [...], "settings": {...}, "units": {...},
    "inputs": [paths]}`` for the run in progress (the CLI does this); returns a reset token.

    Parameters
    ----------
    provider : callable or None
        The callable (None: no run in progress).

    Returns
    -------
    object
        Token that restores the previous provider.
    """
    _FILES_READ.set(())
    return _PROVIDER.set(provider)


def forget_files_read() -> None:
    """End of a run: forget the files :func:`note_input_file` recorded, and stop recording."""
    _FILES_READ.set(None)


def note_input_file(path: str | os.PathLike) -> None:
    """Record a file a reader opened, for the ``input_files`` of the run in progress.

    Only while a run is in progress (from :func:`set_run_info_provider` to
    :func:`forget_files_read`, the CLI command): a library call records nothing.

    Parameters
    ----------
    path : str or os.PathLike
        The file read.
    """
    read = _FILES_READ.get()
    if read is not None and str(path) not in read:
        _FILES_READ.set((*read, str(path)))


def file_sha256(path: str | os.PathLike, chunk: int = 1 << 20) -> str:
    """SHA-256 hex digest of a file's bytes.

    Parameters
    ----------
    path : str or os.PathLike
        The file.
    chunk : int
        Bytes read at a time.

    Returns
    -------
    str
        Hex digest.

    Raises
    ------
    OSError
        The file cannot be read.
    """
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        while block := fh.read(chunk):
            h.update(block)
    return h.hexdigest()


def plain_json(value: Any) -> Any:
    """JSON-ready copy: arrays to lists, NumPy scalars to Python, paths to str, NaN/inf to None."""
    if isinstance(value, Mapping):
        return {str(k): plain_json(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [plain_json(v) for v in value]
    if isinstance(value, np.ndarray):
        return plain_json(value.tolist())
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, Path):
        return str(value)
    if isinstance(value, float) and not np.isfinite(value):
        return None
    return value


def run_provenance(
    *, inputs: Iterable[str | os.PathLike | None] = (), settings: Mapping | None = None
) -> dict:
    """Provenance record of the run in progress.

    Parameters
    ----------
    inputs
        Input files of the output (hashed); merged with the provider's inputs.
    settings
        Settings of the library call, merged over the provider's (CLI) settings.

    Returns
    -------
    dict
        ``robovib_version``, ``command`` (list of str, argv as run), ``settings`` (dict),
        ``units`` (setting name -> unit), ``input_files`` (list of ``{"path", "sha256"}``).
    """
    from .. import __version__

    provider = _PROVIDER.get()
    info = provider() if provider is not None else {}
    command = info.get("command")
    if not command:
        argv = sys.argv or ["python"]
        command = [Path(argv[0]).name or "python", *argv[1:]]
    merged = {**info.get("settings", {}), **(dict(settings) if settings else {})}
    paths: list[str] = []
    for p in [*info.get("inputs", ()), *(_FILES_READ.get() or ()), *inputs]:
        if p is None:
            continue
        s = str(p)
        if s not in paths and Path(s).is_file():
            paths.append(s)
    return {
        "robovib_version": __version__,
        "command": [str(a) for a in command],
        "settings": plain_json(merged),
        "units": dict(info.get("units", {})),
        "input_files": [{"path": p, "sha256": file_sha256(p)} for p in paths],
    }


def write_provenance(h5, provenance: Mapping | None = None, **kwargs) -> None:
    """Write a ``provenance`` group into an open h5py file or group.

    Attributes: ``robovib_version``, ``command`` (JSON list), ``settings`` (JSON object),
    ``units`` (JSON object: setting -> unit); one subgroup ``inputs/<i>`` per input file with
    attributes ``path`` and ``sha256``. ``provenance`` defaults to :func:`run_provenance`
    (``kwargs`` go to it).

    Parameters
    ----------
    h5 : h5py.Group
        Open file or group to write into.
    provenance : mapping, optional
        The provenance (default: :func:`run_provenance`).
    **kwargs
        Passed to :func:`run_provenance`.
    """
    prov = dict(provenance) if provenance is not None else run_provenance(**kwargs)
    if "provenance" in h5:
        del h5["provenance"]
    g = h5.create_group("provenance")
    g.attrs["robovib_version"] = prov["robovib_version"]
    g.attrs["command"] = json.dumps(prov["command"])
    g.attrs["settings"] = json.dumps(plain_json(prov.get("settings", {})), allow_nan=False)
    g.attrs["units"] = json.dumps(prov.get("units", {}))
    ins = g.create_group("inputs")
    for i, item in enumerate(prov.get("input_files", [])):
        gi = ins.create_group(str(i))
        gi.attrs["path"] = item["path"]
        gi.attrs["sha256"] = item["sha256"]


def read_provenance(path_or_h5) -> dict:
    """The ``provenance`` group of an HDF5 file (path or open h5py object) as a dict.

    Parameters
    ----------
    path_or_h5 : str, pathlib.Path or h5py.Group
        The file, or an open h5py file or group.

    Returns
    -------
    dict
        ``robovib_version``, ``command``, ``settings``, ``units`` and ``inputs`` (path, sha256).

    Raises
    ------
    KeyError
        The file has no provenance group (written by an older robovib or another tool).
    """
    if isinstance(path_or_h5, str | os.PathLike):
        from .h5safe import check_self_contained, open_file

        with open_file(Path(path_or_h5)) as h5:
            check_self_contained(h5, path_or_h5)  # links and external storage refused
            return read_provenance(h5)
    h5 = path_or_h5
    if "provenance" not in h5:
        raise KeyError(f"{getattr(h5, 'filename', 'file')}: no provenance group")
    g = h5["provenance"]
    return {
        "robovib_version": str(g.attrs["robovib_version"]),
        "command": json.loads(g.attrs["command"]),
        "settings": json.loads(g.attrs["settings"]),
        "units": json.loads(g.attrs["units"]),
        "input_files": [
            {
                "path": str(g["inputs"][k].attrs["path"]),
                "sha256": str(g["inputs"][k].attrs["sha256"]),
            }
            for k in sorted(g["inputs"], key=int)
        ],
    }


def set_units(dataset, unit: str) -> None:
    """Set the ``units`` attribute of an h5py dataset (``"1"`` for dimensionless).

    Parameters
    ----------
    dataset : h5py.Dataset
        The dataset.
    unit : str
        Its unit.
    """
    if not unit:
        raise ValueError(f"empty unit for dataset {dataset.name}")
    dataset.attrs["units"] = unit
