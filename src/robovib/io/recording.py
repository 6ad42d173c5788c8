"""Impact-hammer recordings: force and response time series of several hits, read from CSV or UFF.

CSV layout (one header row, comma separated)::

    hit,time_s,force_n,acceleration_m_per_s2
    0,0.0,0.12,-0.003
    ...

* ``hit`` (optional): hit number; without it the file holds one hit.
* time: ``time_s`` or ``time_ms``; uniform sampling is required (checked).
* force: ``force_n``, ``force_kn`` or ``force_lbf``.
* voltage channels: unit ``v`` or ``mv`` (``force_mv``, ``acceleration_v``) with a
  :class:`Sensitivity` passed to the reader;
* exactly one response column ``<quantity>_<unit>`` with quantity ``acceleration``,
  ``velocity`` or ``displacement`` and unit written with ``_per_`` for ``/`` and ``2`` for
  squares: ``acceleration_g``, ``acceleration_m_per_s2``, ``velocity_mm_per_s``,
  ``displacement_um``...

UFF: datasets 58 with function type 1 (time response). The force record has specific data type
13 (excitation force), the response 8, 11 or 12 (displacement, velocity, acceleration); the
hit number is the load-case id; units come from the ordinate unit labels (see
:mod:`robovib.io.units`).
"""

from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .safe_write import atomic_output
from .units import si_factor

__all__ = [
    "HammerRecording",
    "Sensitivity",
    "read_recording",
    "read_recording_csv",
    "read_recording_uff",
    "write_recording_csv",
    "write_recording_uff",
]

_SPEC_TO_QUANTITY = {8: "displacement", 11: "velocity", 12: "acceleration"}
_QUANTITY_TO_SPEC = {v: k for k, v in _SPEC_TO_QUANTITY.items()}
_SI_LABEL = {"acceleration": "m/s^2", "velocity": "m/s", "displacement": "m"}
_DIR_CODE = {"x": 1, "y": 2, "z": 3}


@dataclass(frozen=True)
class HammerRecording:
    """Hits of one hammer test, SI units: forces [N], responses [m, m/s or m/s²]."""

    forces: np.ndarray  #: (n_hits, n_samples)
    responses: np.ndarray  #: (n_hits, n_samples)
    sample_rate_hz: float
    response_quantity: str
    direction: str | None = None
    pose: tuple[float, ...] | None = None

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
        object.__setattr__(self, "forces", f)
        object.__setattr__(self, "responses", r)

    @property
    def n_hits(self) -> int:
        return self.forces.shape[0]


@dataclass(frozen=True)
class Sensitivity:
    """A sensor sensitivity for voltage channels: ``mv_per_unit`` millivolts per ``unit``.

    E.g. ``Sensitivity(2.25, "N")`` for a PCB 086D05 hammer, ``Sensitivity(10.0, "g")`` for an
    accelerometer.
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


def _sample_rate(time_s: np.ndarray, where: str) -> float:
    if time_s.size < 2:
        raise ValueError(f"{where}: fewer than 2 samples")
    dt = np.diff(time_s)
    if np.any(dt <= 0) or np.ptp(dt) > 1e-6 * np.mean(dt) + 1e-12:
        raise ValueError(f"{where}: time column is not uniformly sampled")
    return float(1.0 / np.mean(dt))


def _unit_from_column(name: str) -> str:
    unit = name.split("_", 1)[1]
    return unit.replace("_per_", "/").replace("s2", "s^2")


def read_recording_csv(
    path: str | Path,
    direction: str | None = None,
    force_sensitivity: Sensitivity | None = None,
    response_sensitivity: Sensitivity | None = None,
) -> HammerRecording:
    """Read a hammer recording from CSV (layout in the module docstring)."""
    path = Path(path)
    with path.open(newline="") as fh:
        reader = csv.reader(fh)
        try:
            header = [h.strip().lower() for h in next(reader)]
        except StopIteration:
            raise ValueError(f"{path}: empty file") from None
        rows = [r for r in reader if r]
    try:
        data = np.array(rows, dtype=float)
    except ValueError as exc:
        raise ValueError(f"{path}: non-numeric cell ({exc})") from None
    if data.ndim != 2 or data.shape[1] != len(header):
        raise ValueError(f"{path}: rows do not all have {len(header)} cells")
    col = {h: i for i, h in enumerate(header)}
    time_cols = [h for h in header if h.startswith("time_")]
    force_cols = [h for h in header if h.startswith("force_")]
    resp_cols = [h for h in header if h.split("_", 1)[0] in _QUANTITY_TO_SPEC]
    if len(time_cols) != 1 or len(force_cols) != 1 or len(resp_cols) != 1:
        raise ValueError(
            f"{path}: need exactly one time_*, one force_* and one acceleration_*/velocity_*/displacement_* "
            f"column, got {header}"
        )
    _, t_factor = si_factor(_unit_from_column(time_cols[0]), "time")
    f_factor = _channel_factor(
        _unit_from_column(force_cols[0]), "force", force_sensitivity, str(path)
    )
    quantity = resp_cols[0].split("_", 1)[0]
    r_factor = _channel_factor(
        _unit_from_column(resp_cols[0]), quantity, response_sensitivity, str(path)
    )
    hits = data[:, col["hit"]].astype(int) if "hit" in col else np.zeros(len(data), int)
    forces, responses, rates = [], [], []
    for h in np.unique(hits):
        sel = hits == h
        rates.append(_sample_rate(data[sel, col[time_cols[0]]] * t_factor, f"{path} hit {h}"))
        forces.append(data[sel, col[force_cols[0]]] * f_factor)
        responses.append(data[sel, col[resp_cols[0]]] * r_factor)
    if len({len(f) for f in forces}) != 1:
        raise ValueError(f"{path}: hits have different lengths")
    if np.ptp(rates) > 1e-6 * rates[0]:
        raise ValueError(
            f"{path}: hits have mismatched sampling rates {sorted(set(np.round(rates, 6)))}"
        )
    return HammerRecording(np.array(forces), np.array(responses), rates[0], quantity, direction)


def read_recording_uff(
    path: str | Path,
    direction: str | None = None,
    force_sensitivity: Sensitivity | None = None,
    response_sensitivity: Sensitivity | None = None,
) -> HammerRecording:
    """Read force/response time records (UFF dataset 58, function type 1) of one or more hits."""
    import pyuff

    path = Path(path)
    try:
        sets = pyuff.UFF(str(path)).read_sets()
    except Exception as exc:  # pyuff raises bare Exceptions on corrupt files
        raise ValueError(f"{path}: not a readable UFF file ({exc})") from None
    sets = [sets] if isinstance(sets, dict) else list(sets)
    records = [s for s in sets if s.get("type") == 58 and s.get("func_type") == 1]
    if not records:
        raise ValueError(f"{path}: no dataset 58 time records (function type 1)")
    by_hit: dict[int, dict[str, tuple]] = {}
    quantity = None
    found_dir = None
    for s in records:
        spec = int(s.get("ordinate_spec_data_type", 0))
        label = str(s.get("ordinate_axis_units_lab", "")).strip()
        hit = int(s.get("load_case_id", 0))
        if int(s.get("abscissa_spacing", 0)) == 1 and float(s.get("abscissa_inc", 0)) > 0:
            # Even spacing is stored as min + increment; x rebuilt from an ASCII increment
            # carries rounding that a diff-based check would take for jitter.
            fs = 1.0 / float(s["abscissa_inc"])
        else:
            fs = _sample_rate(np.asarray(s["x"], float), f"{path} hit {hit}")
        values = np.asarray(s["data"], float)
        if spec == 13:
            factor = _channel_factor(label, "force", force_sensitivity, str(path))
            by_hit.setdefault(hit, {})["force"] = (values * factor, fs)
        elif spec in _SPEC_TO_QUANTITY:
            q = _SPEC_TO_QUANTITY[spec]
            factor = _channel_factor(label, q, response_sensitivity, str(path))
            if quantity not in (None, q):
                raise ValueError(f"{path}: mixed response quantities {quantity} and {q}")
            quantity = q
            by_hit.setdefault(hit, {})["response"] = (values * factor, fs)
            code = int(s.get("rsp_dir", 0))
            found_dir = {1: "x", 2: "y", 3: "z"}.get(abs(code), found_dir)
        else:
            raise ValueError(f"{path}: record with unsupported ordinate specific data type {spec}")
    forces, responses, rates = [], [], []
    for hit in sorted(by_hit):
        pair = by_hit[hit]
        if set(pair) != {"force", "response"}:
            raise ValueError(
                f"{path}: hit {hit} lacks a {'force' if 'force' not in pair else 'response'} record"
            )
        (f, fs_f), (r, fs_r) = pair["force"], pair["response"]
        if abs(fs_f - fs_r) > 1e-6 * fs_f:
            raise ValueError(
                f"{path}: hit {hit} has mismatched sampling rates: force {fs_f:g} Hz, response {fs_r:g} Hz"
            )
        if f.size != r.size:
            raise ValueError(f"{path}: hit {hit} force and response lengths differ")
        forces.append(f)
        responses.append(r)
        rates.append(fs_f)
    if np.ptp(rates) > 1e-6 * rates[0]:
        raise ValueError(f"{path}: hits have mismatched sampling rates")
    return HammerRecording(
        np.array(forces), np.array(responses), rates[0], quantity, direction or found_dir
    )


def write_recording_uff(
    path: str | Path, recording: HammerRecording, *, inputs=(), force: bool = False
) -> None:
    """Write a recording as UFF datasets 58 (time responses): per hit one force, one response record.

    Atomic (see :func:`robovib.io.atomic_output`): a failed or interrupted write leaves any
    previous file untouched; ``path`` must not be one of ``inputs`` unless ``force``.
    """
    import pyuff

    n = recording.forces.shape[1]
    x = np.arange(n) / recording.sample_rate_hz
    dcode = _DIR_CODE.get(recording.direction or "x", 1)
    sets = []
    for hit in range(recording.n_hits):
        for name, data, spec, label, node in (
            ("force", recording.forces[hit], 13, "N", 1),
            (recording.response_quantity, recording.responses[hit], _QUANTITY_TO_SPEC[recording.response_quantity], _SI_LABEL[recording.response_quantity], 1),
        ):  # fmt: skip
            sets.append(
                pyuff.prepare_58(
                    binary=0,
                    id1=f"robovib hammer {name}",
                    id2=f"hit {hit}",
                    func_type=1,
                    load_case_id=hit,
                    rsp_node=node,
                    rsp_dir=dcode,
                    ref_node=1,
                    ref_dir=dcode,
                    abscissa_spec_data_type=17,
                    abscissa_axis_units_lab="s",
                    ordinate_spec_data_type=spec,
                    ordinate_axis_units_lab=label,
                    orddenom_spec_data_type=0,
                    abscissa_spacing=1,
                    data=np.asarray(data, float),
                    x=x,
                )
            )
    with atomic_output(path, inputs=inputs, force=force) as tmp:
        pyuff.UFF(str(tmp)).write_sets(sets, mode="add")


def write_recording_csv(
    path: str | Path, recording: HammerRecording, *, inputs=(), force: bool = False
) -> None:
    """Write a recording as CSV ``hit,time_s,force_n,<quantity>_<SI unit>`` (atomic).

    The layout is the one :func:`read_recording_csv` reads (long format, one row per sample).
    """
    unit = {"acceleration": "m_per_s2", "velocity": "m_per_s", "displacement": "m"}[
        recording.response_quantity
    ]
    n = recording.forces.shape[1]
    t = np.arange(n) / recording.sample_rate_hz
    with atomic_output(path, inputs=inputs, force=force) as tmp, open(tmp, "w") as fh:
        fh.write(f"hit,time_s,force_n,{recording.response_quantity}_{unit}\n")
        for h in range(recording.n_hits):
            for i in range(n):
                fh.write(
                    f"{h},{t[i]:.9g},{recording.forces[h, i]:.9g},{recording.responses[h, i]:.9g}\n"
                )


def read_recording(
    path: str | Path,
    direction: str | None = None,
    force_sensitivity: Sensitivity | None = None,
    response_sensitivity: Sensitivity | None = None,
) -> HammerRecording:
    """Read a hammer recording by file extension (.csv, .uff/.unv).

    Voltage channels (unit V or mV) are converted with the given sensitivities.
    """
    suffix = Path(path).suffix.lower()
    if suffix == ".csv":
        return read_recording_csv(path, direction, force_sensitivity, response_sensitivity)
    if suffix in (".uff", ".unv"):
        return read_recording_uff(path, direction, force_sensitivity, response_sensitivity)
    raise ValueError(f"unknown recording format {suffix!r}; expected .csv, .uff or .unv")
