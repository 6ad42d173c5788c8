"""UFF dataset 58 time records of a hammer recording (see :mod:`robovib.io.recording`): the
channel reader, the completeness check, and the writer."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .hammer import (
    _CODE_DIR,
    _DIR_CODE,
    _QUANTITY_TO_SPEC,
    _SI_LABEL,
    _SPEC_TO_QUANTITY,
    HammerRecording,
    Sensitivity,
)
from .hits import _channel_factor, _Channels, sample_rate_from_time

__all__ = ["write_recording_uff"]


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


def _time_records(recording: HammerRecording) -> list:
    from ..uff58 import Record58

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
    from ..uff58 import write_uff58

    write_uff58(path, _time_records(recording), inputs=inputs, force=force)
