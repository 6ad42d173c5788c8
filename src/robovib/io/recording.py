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

import decimal
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..files.units import si_factor

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
    "write_recording_uff",
]

_SPEC_TO_QUANTITY = {8: "displacement", 11: "velocity", 12: "acceleration"}
_QUANTITY_TO_SPEC = {v: k for k, v in _SPEC_TO_QUANTITY.items()}
_SI_LABEL = {"acceleration": "m/s^2", "velocity": "m/s", "displacement": "m"}
_DIR_CODE = {"x": 1, "y": 2, "z": 3}
_CODE_DIR = {1: "x", 2: "y", 3: "z"}
_SEGMENT = ("auto", "always", "never")


@dataclass(frozen=True)
class ReadReport:
    """What a reader did with a file.

    Attributes
    ----------
    path
        The file read.
    layout
        ``"paired"`` (one record per hit and channel) or ``"continuous"`` (cut at the impacts).
    records_read
        Data records (UFF datasets 58 or CSV hit blocks / channels) read.
    hits_formed
        Hits returned.
    hits_rejected
        ``(hit label, reason)`` of hits that were found but not formed.
    channels
        Response channels found, e.g. ``("acceleration x node 1", ...)``.
    notes
        Anything else changed on the way (negated records, truncations).
    """

    path: str
    layout: str
    records_read: int
    hits_formed: int
    hits_rejected: tuple[tuple[str, str], ...] = ()
    channels: tuple[str, ...] = ()
    notes: tuple[str, ...] = ()

    def to_dict(self) -> dict:
        return {
            "path": self.path,
            "layout": self.layout,
            "records_read": self.records_read,
            "hits_formed": self.hits_formed,
            "hits_rejected": [{"hit": h, "reason": r} for h, r in self.hits_rejected],
            "channels": list(self.channels),
            "notes": list(self.notes),
        }


@dataclass(frozen=True)
class HammerRecording:
    """Hits of one hammer test, SI units: forces [N], responses [m, m/s or m/s²].

    ``direction`` is the response direction, ``reference_direction`` the force direction
    (None where the file does not say); a recording with both set and different is a cross
    measurement. ``report`` says how the reader formed the hits.

    Attributes
    ----------
    forces
        (n_hits, n) forces [N].
    responses
        (n_hits, n) responses in SI of ``response_quantity``.
    sample_rate_hz
        Sample rate [Hz].
    response_quantity
        ``"acceleration"``, ``"velocity"`` or ``"displacement"``.
    direction, reference_direction
        Response and force directions (None: not in the file).
    pose
        (X, Y, Z [m], Rx, Ry, Rz [deg]) when the file gives it.
    response_node
        Response node of a multi-channel file.
    report
        How the reader formed the hits.
    """

    forces: np.ndarray  #: (n_hits, n_samples)
    responses: np.ndarray  #: (n_hits, n_samples)
    sample_rate_hz: float
    response_quantity: str
    direction: str | None = None
    pose: tuple[float, ...] | None = None
    reference_direction: str | None = None
    response_node: int | None = None
    report: ReadReport | None = field(default=None, compare=False)

    def __post_init__(self) -> None:
        f = np.atleast_2d(np.asarray(self.forces, float))
        r = np.atleast_2d(np.asarray(self.responses, float))
        if f.shape != r.shape:
            raise ValueError(f"forces {f.shape} and responses {r.shape} must have the same shape")
        if not (np.all(np.isfinite(f)) and np.all(np.isfinite(r))):
            raise ValueError("recording contains NaN or inf samples")
        if not self.sample_rate_hz > 0:
            raise ValueError(f"sample_rate_hz must be positive, got {self.sample_rate_hz!r}")
        if self.response_quantity not in _QUANTITY_TO_SPEC:
            raise ValueError(f"unknown response quantity {self.response_quantity!r}")
        for name in ("direction", "reference_direction"):
            v = getattr(self, name)
            if v is not None and v not in _DIR_CODE:
                raise ValueError(f"unknown {name} {v!r}; expected x, y or z")
        object.__setattr__(self, "forces", f)
        object.__setattr__(self, "responses", r)

    @property
    def n_hits(self) -> int:
        return self.forces.shape[0]

    @property
    def is_cross(self) -> bool:
        """True when the response and force directions are both known and differ."""
        return (
            self.direction is not None
            and self.reference_direction is not None
            and self.direction != self.reference_direction
        )


@dataclass(frozen=True)
class Sensitivity:
    """A sensor sensitivity for voltage channels: ``mv_per_unit`` millivolts per ``unit``.

    E.g. ``Sensitivity(2.25, "N")`` for a PCB 086D05 hammer, ``Sensitivity(10.0, "g")`` for an
    accelerometer.

    Attributes
    ----------
    mv_per_unit
        Millivolts per ``unit``.
    unit
        The physical unit (``"N"``, ``"g"``, ``"m/s^2"``, ``"m/s"``, ``"m"``).
    """

    mv_per_unit: float
    unit: str


def _channel_factor(
    label: str, expected: str, sensitivity: Sensitivity | None, where: str
) -> float:
    """SI factor of a channel; voltage labels (V, mV) need a sensitivity of the right quantity."""
    key = label.strip().lower()
    if key in ("v", "mv"):
        if sensitivity is None:
            raise ValueError(
                f"{where}: the {expected} channel is in {label}; give its sensitivity (mV per unit)"
            )
        quantity, per_unit = si_factor(sensitivity.unit)
        if quantity != expected:
            raise ValueError(
                f"{where}: sensitivity is per {sensitivity.unit} ({quantity}), the channel is {expected}"
            )
        if not sensitivity.mv_per_unit > 0:
            raise ValueError(
                f"{where}: sensitivity must be positive, got {sensitivity.mv_per_unit}"
            )
        return (1e3 if key == "v" else 1.0) / sensitivity.mv_per_unit * per_unit
    return si_factor(label, expected)[1]


def sample_rate_from_time(time_s: np.ndarray, resolution_s, where: str) -> float:
    """Sample rate [Hz] of a printed time column, tolerating rounding up to its resolution.

    The sample interval is the least-squares slope of time against sample index; each step must
    match it within the printed resolution ``resolution_s`` (a rounded value is off by at most
    half of it, a step by at most all of it). A larger deviation is a gap, named by sample and
    time.

    Parameters
    ----------
    time_s
        (n,) sample times [s].
    resolution_s
        Printed resolution [s]: one value, or one per sample (a step is allowed the coarser
        of its two ends).
    where
        The file (and hit) for messages.

    Returns
    -------
    float
        The sample rate [Hz].

    Raises
    ------
    ValueError
        Fewer than 2 samples, non-increasing time, or a gap.
    """
    t = np.asarray(time_s, float)
    if t.size < 2:
        raise ValueError(f"{where}: fewer than 2 samples")
    dt = np.diff(t)
    if np.any(dt <= 0):
        i = int(np.argmax(dt <= 0)) + 1
        raise ValueError(
            f"{where}: time column is not uniformly sampled: time does not increase at sample {i} "
            f"(t = {t[i]:.9g} s)"
        )
    # A gap (a missing sample, a jump) is found against the median step first, so that it is
    # named where it is, not where it tilts the least-squares slope.
    step = float(np.median(dt))
    gap = np.abs(dt - step) > 0.25 * step
    if np.any(gap):
        i = int(np.argmax(gap)) + 1
        raise ValueError(
            f"{where}: time column is not uniformly sampled: step of {dt[i - 1]:.9g} s before "
            f"sample {i} (t = {t[i]:.9g} s), expected {step:.9g} s; a gap or a changed rate"
        )
    idx = np.arange(t.size, dtype=float)
    slope, _ = np.polyfit(idx, t, 1)
    # A step off by a quarter interval or more is never rounding (a missing sample is a whole one).
    res = np.broadcast_to(np.asarray(resolution_s, float), t.shape)
    res_step = np.maximum(res[:-1], res[1:])  # each step: the coarser of its two printed times
    tol = np.minimum(1.001 * res_step + 1e-9 * slope + 1e-15, 0.25 * slope)
    bad = np.abs(dt - slope) > tol
    if np.any(bad):
        i = int(np.argmax(bad)) + 1
        raise ValueError(
            f"{where}: time column is not uniformly sampled: step of {dt[i - 1]:.9g} s before "
            f"sample {i} (t = {t[i]:.9g} s), expected {slope:.9g} s ± {res_step[i - 1]:.3g} s "
            "(the printed resolution); a gap or a changed rate"
        )
    return float(1.0 / slope)


def _printed_resolution(cells) -> np.ndarray:
    """The last printed digit of each numeric string (e.g. '0.000195' -> 1e-6); a DAQ printing
    ``%.10g`` gives fewer decimals once the time passes 1 s."""
    out = []
    for c in cells:
        try:
            e = decimal.Decimal(c.strip()).as_tuple().exponent
        except (decimal.InvalidOperation, AttributeError):
            e = None
        out.append(10.0**e if isinstance(e, int) else 0.0)
    return np.asarray(out, float)


def _unit_from_column(name: str) -> str:
    unit = name.split("_", 1)[1]
    return unit.replace("_per_", "/").replace("s2", "s^2")


def _split_column(name: str) -> tuple[str, str | None, str]:
    """``acceleration_x_m_per_s2`` -> ("acceleration", "x", "m/s^2")."""
    quantity, rest = name.split("_", 1)
    direction = None
    head, _, tail = rest.partition("_")
    if head in _DIR_CODE and tail:
        direction, rest = head, tail
    return quantity, direction, rest.replace("_per_", "/").replace("s2", "s^2")


@dataclass
class _Channels:
    """Raw hits as read: force and each response channel, lists of 1-D arrays per hit."""

    forces: list
    responses: dict  # key -> list of arrays (same hit order as forces)
    quantity: dict  # key -> quantity
    direction: dict  # key -> direction or None
    node: dict  # key -> node or None
    force_direction: str | None
    sample_rate_hz: float
    labels: list  # hit labels
    records_read: int
    rejected: list = field(default_factory=list)
    notes: list = field(default_factory=list)
    cut_short: bool = False  # the file ends without a line end (or inside a record)
    hit_rates: list | None = None  # per-hit sample rates (CSV), averaged over the kept hits


def _channel_name(key, ch: _Channels) -> str:
    d = ch.direction[key]
    node = ch.node[key]
    return f"{ch.quantity[key]}{' ' + d if d else ''}{f' node {node}' if node is not None else ''}"


def _cut_continuous(ch: _Channels, where: str, segment: str, seg_kw: dict) -> str:
    """Cut single-record channels into hits at the impacts; returns the layout."""
    from ..frf.segment import segment_hits

    if segment == "never" or (segment == "auto" and len(ch.forces) != 1):
        return "paired"
    if len(ch.forces) != 1:
        raise ValueError(
            f"{where}: segment='always' needs one continuous record per channel, "
            f"found {len(ch.forces)} hits"
        )
    seg = segment_hits(ch.forces[0], ch.sample_rate_hz, **seg_kw)
    if seg.n_hits <= 1 and not seg.rejected:
        return "paired" if segment == "auto" else "continuous"
    fs = ch.sample_rate_hz
    for onset, reason in seg.rejected:
        ch.rejected.append((f"impact at {onset / fs:.4g} s", reason))
    f0 = ch.forces[0]
    ch.forces = [f0[s : s + seg.length] for s in seg.starts]
    for key, rs in ch.responses.items():
        ch.responses[key] = [rs[0][s : s + seg.length] for s in seg.starts]
    ch.labels = [f"impact at {o / fs:.4g} s" for o in seg.onsets]
    ch.notes.append(
        f"continuous record of {f0.size / fs:.4g} s cut into {seg.n_hits} hits of "
        f"{seg.length / fs:.4g} s"
    )
    return "continuous"


def _equal_lengths(ch: _Channels, where: str) -> None:
    """Give every hit the common length; a hit shorter than it is rejected, never the others cut.

    The common length is the upper median of the hit lengths (at least half the hits are that
    long). Shorter hits are rejected by name and length (averaging them would cut every hit
    and coarsen the FRF resolution); longer ones lose only their tail beyond it (noted). A
    short last hit in a file that ends without a line end is a file cut short: an error.
    """
    lengths = [len(f) for f in ch.forces]
    if ch.cut_short:
        ch.notes.append("the file ends without a line end: its last value may be cut short")
    if len(set(lengths)) <= 1:
        return
    n = int(np.sort(lengths)[len(lengths) // 2])
    if ch.cut_short and lengths[-1] < n:
        raise ValueError(
            f"{where}: the file ends inside {ch.labels[-1]} ({lengths[-1]} samples, the other "
            f"hits {n}) without a line end: a truncated or damaged file"
        )
    keep = []
    for i, m in enumerate(lengths):
        if m < n:
            ch.rejected.append(
                (ch.labels[i], f"short hit: {m} samples ({m / ch.sample_rate_hz:.4g} s), the "
                 f"others {n} ({n / ch.sample_rate_hz:.4g} s)")
            )  # fmt: skip
        else:
            keep.append(i)
    longer = sorted({lengths[i] for i in keep if lengths[i] > n})
    if longer:
        ch.notes.append(f"hits of {longer} samples cut to the common length {n}")
    ch.forces = [ch.forces[i][:n] for i in keep]
    ch.responses = {k: [v[i][:n] for i in keep] for k, v in ch.responses.items()}
    ch.labels = [ch.labels[i] for i in keep]
    if ch.hit_rates is not None:  # a rejected short hit's (less precise) rate does not count
        ch.hit_rates = [ch.hit_rates[i] for i in keep]
        ch.sample_rate_hz = float(np.mean(ch.hit_rates))


def _finish(ch: _Channels, path: Path, segment: str, seg_kw: dict) -> list[HammerRecording]:
    if segment not in _SEGMENT:
        raise ValueError(f"unknown segment mode {segment!r}; expected one of {_SEGMENT}")
    if not ch.forces:
        detail = "; ".join(f"{h}: {r}" for h, r in ch.rejected)
        raise ValueError(f"{path}: no complete hit (force + response) found ({detail})")
    layout = _cut_continuous(ch, str(path), segment, seg_kw)
    _equal_lengths(ch, str(path))
    names = tuple(_channel_name(k, ch) for k in ch.responses)
    report = ReadReport(
        str(path), layout, ch.records_read, len(ch.forces),
        tuple(ch.rejected), names, tuple(ch.notes),
    )  # fmt: skip
    out = []
    forces = np.array(ch.forces)
    for key, rs in ch.responses.items():
        out.append(
            HammerRecording(
                forces,
                np.array(rs),
                ch.sample_rate_hz,
                ch.quantity[key],
                direction=ch.direction[key],
                reference_direction=ch.force_direction,
                response_node=ch.node[key],
                report=report,
            )
        )
    return out


def _csv_channels(
    path: Path,
    force_sensitivity: Sensitivity | None,
    response_sensitivity: Sensitivity | None,
) -> _Channels:
    from ..files.csv_table import read_table

    table = read_table(path, what="recording")
    header = list(table.header)
    rows = table.rows
    try:
        data = np.array(rows, dtype=float)
    except ValueError:
        for name in header:
            table.numbers(name)  # names the line and the cell
        raise
    renamed = [
        f"column {raw!r} read as {name}"
        for raw, name in zip(table.raw_header, header, strict=True)
        if raw.strip().lower() != name
    ]
    col = {h: i for i, h in enumerate(header)}
    time_cols = [h for h in header if h.startswith("time_")]
    force_cols = [h for h in header if h.startswith("force_")]
    resp_cols = [h for h in header if h.split("_", 1)[0] in _QUANTITY_TO_SPEC]
    if len(time_cols) != 1 or len(force_cols) != 1 or not resp_cols:
        raise ValueError(
            f"{path}: need exactly one time_*, one force_* and at least one "
            f"acceleration_*/velocity_*/displacement_* column, got {header}"
        )
    if not np.all(np.isfinite(data)):
        r, c = np.argwhere(~np.isfinite(data))[0]
        raise ValueError(f"{path} line {table.lines[r]}: NaN or inf in column {header[c]!r}")
    _, t_factor = si_factor(_unit_from_column(time_cols[0]), "time")
    _, f_dir, f_unit = _split_column(force_cols[0])
    f_factor = _channel_factor(f_unit, "force", force_sensitivity, str(path))
    hits = data[:, col["hit"]].astype(int) if "hit" in col else np.zeros(len(data), int)
    order = list(dict.fromkeys(hits.tolist()))  # hit numbers in file order
    ti = col[time_cols[0]]
    rates = []
    for h in order:
        sel = np.flatnonzero(hits == h)
        res = _printed_resolution(rows[i][ti] for i in sel) * t_factor
        where = f"{path} hit {h}" if "hit" in col else str(path)
        rates.append(sample_rate_from_time(data[sel, ti] * t_factor, res, where))
    if np.ptp(rates) > 1e-4 * rates[0]:
        raise ValueError(
            f"{path}: hits have mismatched sampling rates {sorted(set(np.round(rates, 3)))} Hz"
        )
    responses, quantity, direction, node = {}, {}, {}, {}
    for c in resp_cols:
        q, d, unit = _split_column(c)
        factor = _channel_factor(unit, q, response_sensitivity, str(path))
        responses[c] = [data[hits == h, col[c]] * factor for h in order]
        quantity[c], direction[c], node[c] = q, d, None
    return _Channels(
        forces=[data[hits == h, col[force_cols[0]]] * f_factor for h in order],
        responses=responses, quantity=quantity, direction=direction, node=node,
        force_direction=f_dir, sample_rate_hz=float(np.mean(rates)),
        labels=[f"hit {h}" for h in order], records_read=len(order) * (1 + len(resp_cols)),
        notes=[f"CSV read with {table.dialect}", *renamed], cut_short=not table.ends_with_newline,
        hit_rates=rates,
    )  # fmt: skip


def _uff_fs(s: dict, where: str) -> float:
    if int(s.get("abscissa_spacing", 0)) == 1 and float(s.get("abscissa_inc", 0)) > 0:
        # Even spacing is stored as min + increment (E13.5: 6 significant digits).
        return 1.0 / float(s["abscissa_inc"])
    x = np.asarray(s["x"], float)
    # Uneven abscissae printed in E13.5 carry 6 significant digits.
    top = float(np.max(np.abs(x))) if x.size else 0.0
    res = 10.0 ** (np.floor(np.log10(top)) - 5) if top > 0 else 0.0
    return sample_rate_from_time(x, res, where)


def _check_uff_complete(path: Path, n_read: int) -> None:
    """A UFF file cut short or damaged is an error, never a partial read.

    Datasets are delimited by lines ``    -1``; the file must close every dataset it opens, and
    the reader must have returned every dataset 58 the file holds.
    """
    raw = path.read_bytes()
    lines = raw.decode("latin-1").splitlines()
    inside, start, kind, n58 = False, 0, "", 0
    for i, line in enumerate(lines):
        if line.strip() == "-1":
            if inside:
                inside = False
            else:
                inside, start = True, i
                kind = (
                    lines[i + 1].strip().split()[0]
                    if i + 1 < len(lines) and lines[i + 1].strip()
                    else ""
                )
                if kind.lower().endswith("b"):
                    return  # binary dataset: the text structure cannot be checked here
                n58 += kind == "58"
    if inside:
        raise ValueError(
            f"{path}: the file ends inside dataset {kind or '?'} opened at line {start + 1} "
            "(no closing -1): a truncated or damaged file"
        )
    if n58 != n_read:
        raise ValueError(
            f"{path}: holds {n58} datasets 58 but only {n_read} could be read: a damaged file"
        )


def _uff_channels(
    path: Path,
    force_sensitivity: Sensitivity | None,
    response_sensitivity: Sensitivity | None,
) -> _Channels:
    import pyuff

    try:
        sets = pyuff.UFF(str(path)).read_sets()
    except Exception as exc:  # pyuff raises bare Exceptions on corrupt files
        raise ValueError(f"{path}: not a readable UFF file ({exc})") from None
    sets = [sets] if isinstance(sets, dict) else list(sets)
    _check_uff_complete(path, sum(s.get("type") == 58 for s in sets))
    for k, s in enumerate(s for s in sets if s.get("type") == 58):
        declared, held = int(s.get("num_pts", -1)), len(s.get("data", ()))
        if declared >= 0 and declared != held:
            raise ValueError(
                f"{path}: dataset 58 number {k} declares {declared} values but holds {held}: "
                "a truncated or damaged file"
            )
    records = [s for s in sets if s.get("type") == 58 and s.get("func_type") == 1]
    if not records:
        raise ValueError(f"{path}: no dataset 58 time records (function type 1)")
    notes: list[str] = []
    parsed = []  # (record index, channel key, load case, values, fs)
    force_dirs = set()
    ref_dirs = set()
    for i, s in enumerate(records):
        spec = int(s.get("ordinate_spec_data_type", 0))
        label = str(s.get("ordinate_axis_units_lab", "")).strip()
        code = int(s.get("rsp_dir", 0))
        node = int(s.get("rsp_node", 0))
        where = f"{path} record {i}"
        if spec == 13:
            factor = _channel_factor(label, "force", force_sensitivity, where)
            key = ("force", node, abs(code))
            if code:
                force_dirs.add(abs(code))
        elif spec in _SPEC_TO_QUANTITY:
            q = _SPEC_TO_QUANTITY[spec]
            factor = _channel_factor(label, q, response_sensitivity, where)
            key = (q, node, abs(code))
            if int(s.get("ref_dir", 0)):
                ref_dirs.add(abs(int(s["ref_dir"])))
        else:
            raise ValueError(f"{where}: unsupported ordinate specific data type {spec}")
        if abs(code) > 3:
            raise ValueError(
                f"{where}: direction code {code} is a rotation; only translations (±1-3) are supported"
            )
        values = np.asarray(s["data"], float) * factor
        if code < 0:
            values = -values
            notes.append(
                f"record {i} ({key[0]}, node {node}) points along -{_CODE_DIR[-code].upper()}: negated"
            )
        parsed.append((i, key, int(s.get("load_case_id", 0)), values, _uff_fs(s, where)))
    force_keys = {k for _, k, *_ in parsed if k[0] == "force"}
    if not force_keys:
        raise ValueError(f"{path}: no force record (specific data type 13)")
    if len(force_keys) > 1:
        raise ValueError(
            f"{path}: {len(force_keys)} force channels {sorted(force_keys)}; one excitation per file"
        )
    if len(force_dirs) > 1:
        raise ValueError(f"{path}: force records in several directions {sorted(force_dirs)}")
    fdir = next(iter(force_dirs), None) or (next(iter(ref_dirs)) if len(ref_dirs) == 1 else None)
    rates = [p[4] for p in parsed]
    if np.ptp(rates) > 1e-5 * max(rates):
        by = sorted({round(r, 3) for r in rates})
        raise ValueError(f"{path}: records have mismatched sampling rates {by} Hz")
    keys = list(dict.fromkeys(k for _, k, *_ in parsed))
    per_key: dict = {k: [p for p in parsed if p[1] == k] for k in keys}
    load_cases = {p[2] for p in parsed}
    by_case = len(load_cases) > 1 and all(
        len({p[2] for p in v}) == len(v) for v in per_key.values()
    )
    # hit label -> {key: values}
    hits: dict = {}
    if by_case:
        for p in parsed:
            hits.setdefault(p[2], {})[p[1]] = p[3]
        labels = {lc: f"load case {lc}" for lc in hits}
    else:
        for v in per_key.values():
            for j, p in enumerate(v):
                hits.setdefault(j, {})[p[1]] = p[3]
        labels = {j: f"hit {j}" for j in hits}
    (fkey,) = force_keys
    rkeys = [k for k in keys if k != fkey]
    if not rkeys:
        raise ValueError(f"{path}: no response record (specific data type 8, 11 or 12)")
    forces, responses, kept_labels, rejected = [], {k: [] for k in rkeys}, [], []
    # The hit the file's last record belongs to: a hit from there on that lacks a record means
    # the file was cut (between datasets), not that a record was left out.
    final = parsed[-1]
    last = final[2] if by_case else len(per_key[final[1]]) - 1
    for h in sorted(hits):
        rec = hits[h]
        missing = [k for k in [fkey, *rkeys] if k not in rec]
        if missing and h >= last:
            names = ", ".join(f"{k[0]} node {k[1]} dir {k[2]}" for k in missing)
            raise ValueError(
                f"{path}: the last hit ({labels[h]}) lacks its {names} record and the file ends "
                "there: a truncated file (a file cut between datasets)"
            )
        if missing:
            names = ", ".join(f"{k[0]} node {k[1]} dir {k[2]}" for k in missing)
            rejected.append((labels[h], f"no {names} record"))
            continue
        sizes = {rec[k].size for k in [fkey, *rkeys]}
        if len(sizes) > 1:
            rejected.append(
                (labels[h], f"force and response records differ in length {sorted(sizes)}")
            )
            continue
        forces.append(rec[fkey])
        for k in rkeys:
            responses[k].append(rec[k])
        kept_labels.append(labels[h])
    return _Channels(
        forces=forces, responses=responses,
        quantity={k: k[0] for k in rkeys},
        direction={k: _CODE_DIR.get(k[2]) for k in rkeys},
        node={k: k[1] for k in rkeys},
        force_direction=_CODE_DIR.get(fdir) if fdir else None,
        sample_rate_hz=float(np.mean(rates)), labels=kept_labels,
        records_read=len(records), rejected=rejected, notes=notes,
    )  # fmt: skip


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
    from ..files.safe_read import check_input_file

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


def _time_records(recording: HammerRecording) -> list:
    from .uff58 import Record58

    dcode = _DIR_CODE.get(recording.direction or "", 0)
    fcode = _DIR_CODE.get(recording.reference_direction or recording.direction or "", 0)
    spec = _QUANTITY_TO_SPEC[recording.response_quantity]
    dt = 1.0 / recording.sample_rate_hz
    out = []
    for hit in range(recording.n_hits):
        for name, data, sp, label, code in (
            ("force", recording.forces[hit], 13, "N", fcode),
            (recording.response_quantity, recording.responses[hit], spec, _SI_LABEL[recording.response_quantity], dcode),
        ):  # fmt: skip
            out.append(
                Record58(
                    data=np.asarray(data, float),
                    x0=0.0,
                    dx=dt,
                    func_type=1,
                    ordinate_spec=sp,
                    ordinate_label=label,
                    abscissa_spec=17,
                    abscissa_label="s",
                    load_case_id=hit,
                    rsp_node=1,
                    rsp_dir=code,
                    ref_node=1,
                    ref_dir=fcode,
                    ids=(f"robovib hammer {name}", f"hit {hit}", "NONE", "NONE", "NONE"),
                )
            )
    return out


def write_recording_uff(
    path: str | Path, recording: HammerRecording, *, inputs=(), force: bool = False
) -> None:
    """Write a recording as UFF datasets 58 (per hit one force, one response record).

    One pass over the hits (linear in their number), atomic (:func:`robovib.io.atomic_output`):
    a failed or interrupted write leaves any previous file untouched; ``path`` must not be one
    of ``inputs`` unless ``force``.

    Parameters
    ----------
    path : str or pathlib.Path
        The ``.uff`` file to write.
    recording : HammerRecording
        The hits.
    inputs : sequence of path
        Files the output was made from (never overwritten unless ``force``).
    force : bool
        Allow ``path`` to be one of ``inputs``.
    """
    from .uff58 import write_uff58

    write_uff58(path, _time_records(recording), inputs=inputs, force=force)
