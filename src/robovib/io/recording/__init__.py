"""Impact-hammer recordings: force and response time series of several hits, read from CSV or UFF.

The readers never lose or invent a hit: every record is paired by its channel, hits are formed
from paired records or cut out of continuous records, and what happened is reported in a
:class:`ReadReport` (records read, hits formed, hits rejected and why) attached to the result.

CSV layout (one header row, comma separated)::

    hit,time_s,force_n,acceleration_m_per_s2
    0,0.0,0.12,-0.003
    ...

* ``hit`` (optional): hit number; without it the file is one continuous record, cut into hits
  at the impacts (:func:`robovib.frf.segment_hits`).
* time: ``time_s`` or ``time_ms``; the sample rate is the least-squares slope of time against
  sample index; deviations up to the printed resolution of the time column (6 decimals: 1 µs)
  are rounding, larger ones are gaps and rejected with the sample and time named.
* force: ``force_n``, ``force_kn`` or ``force_lbf`` (optionally with a direction:
  ``force_x_n``).
* voltage channels: unit ``v`` or ``mv`` (``force_mv``, ``acceleration_v``) with a
  :class:`Sensitivity` passed to the reader;
* one or more response columns ``<quantity>[_<dir>]_<unit>`` with quantity ``acceleration``,
  ``velocity`` or ``displacement``, optional direction ``x``/``y``/``z`` and unit written with
  ``_per_`` for ``/`` and ``2`` for squares: ``acceleration_g``, ``acceleration_x_m_per_s2``,
  ``velocity_mm_per_s``, ``displacement_um``...

UFF: datasets 58 with function type 1 (time response). The force record has specific data type
13 (excitation force), responses 8, 11 or 12 (displacement, velocity, acceleration). A record's
channel is (function type, specific data type, node, |direction|); a negative direction code
(``rsp_dir = -1``: the sensor points along -X) is honoured by negating the record. Records are
paired into hits by load-case id when every channel numbers its records uniquely with
several ids, otherwise by order within each channel (the i-th force record and the i-th record
of every response channel form hit i), so files that give every record load-case 0 keep all
hits. A file with one record per channel is continuous and is cut into hits at the impacts.
Units come from the ordinate unit labels (see :mod:`robovib.files.units`).
"""

from __future__ import annotations

from pathlib import Path

from .csv_layout import _csv_channels, write_recording_csv
from .hammer import _DIR_CODE, HammerRecording, ReadReport, Sensitivity
from .hits import _finish, sample_rate_from_time
from .uff_layout import _uff_channels, write_recording_uff

__all__ = [
    "HammerRecording",
    "ReadReport",
    "Sensitivity",
    "read_recording",
    "read_recording_channels",
    "read_recording_csv",
    "read_recording_uff",
    "sample_rate_from_time",
    "select_channel",
    "write_recording",
    "write_recording_csv",
    "write_recording_uff",
]


def read_recording_channels(
    path: str | Path,
    force_sensitivity: Sensitivity | None = None,
    response_sensitivity: Sensitivity | None = None,
    *,
    segment: str = "auto",
    threshold: float = 0.1,
    pretrigger_s: float = 0.01,
    hold_off_s: float = 0.5,
    window_s: float | None = None,
) -> list[HammerRecording]:
    """Every response channel of a hammer recording (.csv, .uff/.unv), one recording each.

    Parameters
    ----------
    path
        Recording file (layouts in the module docstring).
    force_sensitivity, response_sensitivity
        Sensitivities of voltage channels (unit V or mV).
    segment
        ``"auto"``: cut a file holding one record per channel into hits at its impacts;
        ``"always"``: require and cut such a record; ``"never"``: keep records as hits.
    threshold, pretrigger_s, hold_off_s, window_s
        Impact detection settings of :func:`robovib.frf.segment_hits` [fraction, s, s, s].

    Returns
    -------
    list of HammerRecording
        One per response channel, all with the same hits and the same ``report``.

    Raises
    ------
    ValueError
        Unreadable file, unknown units, mismatched sampling rates, time gaps, no complete hit.
    """
    from ...files.safe_read import check_input_file

    path = check_input_file(path, "file")  # a regular file below the size limit ("no such file")
    suffix = path.suffix.lower()
    if suffix == ".csv":
        ch = _csv_channels(path, force_sensitivity, response_sensitivity)
    elif suffix in (".uff", ".unv"):
        ch = _uff_channels(path, force_sensitivity, response_sensitivity)
    else:
        raise ValueError(
            f"{path}: unknown recording format {suffix!r}; expected .csv, .uff or .unv"
        )
    seg_kw = dict(threshold=threshold, pretrigger_s=pretrigger_s, hold_off_s=hold_off_s,
                  window_s=window_s)  # fmt: skip
    return _finish(ch, path, segment, seg_kw)


def select_channel(
    channels: list[HammerRecording], direction: str | None, where: str = "recording"
) -> HammerRecording:
    """The response channel for ``direction``; a direction that contradicts the file is an error.

    With ``direction=None`` the only channel, or the direct one (response along the force),
    is returned. A channel without a direction in the file takes ``direction``.

    Parameters
    ----------
    channels : list of HammerRecording
        The channels of one file.
    direction : {"x", "y", "z"} or None
        The direction asked for.
    where : str
        The file, named in errors.

    Returns
    -------
    HammerRecording
        The channel.

    Raises
    ------
    ValueError
        Unknown direction, a force along another direction, no such channel, or ambiguity.
    """
    from dataclasses import replace

    if direction is not None and direction not in _DIR_CODE:
        raise ValueError(f"unknown direction {direction!r}; expected x, y or z")
    ref = channels[0].reference_direction
    if direction is not None and ref is not None and ref != direction:
        raise ValueError(
            f"{where}: direction {direction!r} contradicts the file: the force is along {ref!r}"
        )
    known = [c for c in channels if c.direction is not None]
    if direction is None:
        if len(channels) == 1:
            return channels[0]
        direct = [c for c in known if c.direction == ref] if ref else []
        if len(direct) == 1:
            return direct[0]
        dirs = ", ".join(c.direction or "?" for c in channels)
        raise ValueError(f"{where}: {len(channels)} response channels ({dirs}); give the direction")
    match = [c for c in channels if c.direction == direction]
    if not match and len(channels) == 1 and channels[0].direction is None:
        return replace(channels[0], direction=direction)
    if not match:
        dirs = ", ".join(sorted({c.direction or "none" for c in channels}))
        raise ValueError(
            f"{where}: direction {direction!r} contradicts the file: its responses are along {dirs}"
        )
    if len(match) > 1:
        nodes = ", ".join(str(c.response_node) for c in match)
        raise ValueError(f"{where}: several {direction} responses (nodes {nodes}); ambiguous")
    return match[0]


def read_recording_csv(
    path: str | Path,
    direction: str | None = None,
    force_sensitivity: Sensitivity | None = None,
    response_sensitivity: Sensitivity | None = None,
    **segment_kw,
) -> HammerRecording:
    """Read a hammer recording of one or more hits from CSV (layout in the module docstring).

    Parameters
    ----------
    path : str or os.PathLike
        The file.
    direction : {"x", "y", "z"}, optional
        Response channel to return; needed when the file holds several.
    force_sensitivity, response_sensitivity : Sensitivity, optional
        Sensor sensitivities converting voltage channels (V or mV) to N and m/s² (SI).
    **segment_kw
        Passed to :func:`read_recording_channels` (how a continuous record is cut into hits).

    Returns
    -------
    HammerRecording
        ``forces`` and ``responses`` (n_hits, n_samples) in SI, ``sample_rate_hz``,
        ``response_quantity``, direction, pose and a ``report`` of how hits were formed.

    Raises
    ------
    ValueError
        Unreadable or inconsistent file, voltage channels without a sensitivity, mismatched
        sample rates, or ``direction`` missing from / contradicting the file.

    See ``docs/methods.md`` section 1.

    Examples
    --------
    >>> import pathlib, tempfile
    >>> from robovib.io import read_recording_csv, write_recording_csv
    >>> from robovib.sim import VirtualRobot, simulate_hammer_test
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "hammer.csv"
    >>> write_recording_csv(path, simulate_hammer_test(VirtualRobot(), (2.4, 0.0, 45.0), "x", n_hits=2, rng=0))
    >>> read_recording_csv(path).forces.shape[0]
    2
    """
    if Path(path).suffix.lower() != ".csv":
        raise ValueError(f"{path}: expected a .csv file")
    return read_recording(path, direction, force_sensitivity, response_sensitivity, **segment_kw)


def read_recording_uff(
    path: str | Path,
    direction: str | None = None,
    force_sensitivity: Sensitivity | None = None,
    response_sensitivity: Sensitivity | None = None,
    **segment_kw,
) -> HammerRecording:
    """Read a hammer recording of one or more hits from UFF dataset 58 (function type 1) time records.

    Parameters
    ----------
    path : str or os.PathLike
        The file.
    direction : {"x", "y", "z"}, optional
        Response channel to return; needed when the file holds several.
    force_sensitivity, response_sensitivity : Sensitivity, optional
        Sensor sensitivities converting voltage channels (V or mV) to N and m/s² (SI).
    **segment_kw
        Passed to :func:`read_recording_channels` (how a continuous record is cut into hits).

    Returns
    -------
    HammerRecording
        ``forces`` and ``responses`` (n_hits, n_samples) in SI, ``sample_rate_hz``,
        ``response_quantity``, direction, pose and a ``report`` of how hits were formed.

    Raises
    ------
    ValueError
        Unreadable or inconsistent file, voltage channels without a sensitivity, mismatched
        sample rates, or ``direction`` missing from / contradicting the file.

    See ``docs/methods.md`` section 1.

    Examples
    --------
    >>> import pathlib, tempfile
    >>> from robovib.io import read_recording_uff, write_recording_uff
    >>> from robovib.sim import VirtualRobot, simulate_hammer_test
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "hammer.uff"
    >>> write_recording_uff(path, simulate_hammer_test(VirtualRobot(), (2.4, 0.0, 45.0), "x", n_hits=2, rng=0))
    >>> read_recording_uff(path).forces.shape[0]
    2
    """
    if Path(path).suffix.lower() not in (".uff", ".unv"):
        raise ValueError(f"{path}: expected a .uff or .unv file")
    return read_recording(path, direction, force_sensitivity, response_sensitivity, **segment_kw)


def read_recording(
    path: str | Path,
    direction: str | None = None,
    force_sensitivity: Sensitivity | None = None,
    response_sensitivity: Sensitivity | None = None,
    **segment_kw,
) -> HammerRecording:
    """Read a hammer recording by file extension (.csv, .uff/.unv): the channel of ``direction``.

    Voltage channels (unit V or mV) are converted with the given sensitivities; ``segment_kw``
    go to :func:`read_recording_channels`. The result's ``report`` says how hits were formed.

    Parameters
    ----------
    path : str or pathlib.Path
        The recording.
    direction : {"x", "y", "z"}, optional
        Response channel to read (default: the only or the direct one).
    force_sensitivity, response_sensitivity : Sensitivity, optional
        For channels in V or mV.
    **segment_kw
        Hit segmentation of continuous records (:func:`read_recording_channels`).

    Returns
    -------
    HammerRecording
        The hits of that channel, in SI.

    Raises
    ------
    ValueError
        As :func:`read_recording_channels`, or when ``direction`` contradicts the file.
    """
    channels = read_recording_channels(path, force_sensitivity, response_sensitivity, **segment_kw)
    return select_channel(channels, direction, str(path))


def write_recording(
    path: str | Path, recording: HammerRecording, *, inputs=(), force: bool = False
) -> None:
    """Write a hammer recording as UFF 58 (``.uff``/``.unv``) or CSV (``.csv``).

    Parameters
    ----------
    path : str or pathlib.Path
        The file to write; its suffix picks the format.
    recording : HammerRecording
        The hits.
    inputs : sequence of path
        Files the output was made from (never overwritten unless ``force``).
    force : bool
        Allow ``path`` to be one of ``inputs``.

    Raises
    ------
    ValueError
        Unknown file suffix.
    """
    suffix = Path(path).suffix.lower()
    if suffix in (".uff", ".unv"):
        write_recording_uff(path, recording, inputs=inputs, force=force)
    elif suffix == ".csv":
        write_recording_csv(path, recording, inputs=inputs, force=force)
    else:
        raise ValueError(f"{path}: unknown output format {suffix!r}; use .uff or .csv")
