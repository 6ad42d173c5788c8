"""FRF collections on disk: HDF5 (many poses x directions) and UFF dataset 58 (function type 4).

HDF5 layout (h5py), format tag ``robovib-frf`` version 1 (the header of
:mod:`robovib.files.h5format`; files written before it say ``version`` instead of ``format_version``)::

    /                      attrs: format="robovib-frf", format_version=1, robovib_version,
                                  created_utc, units
    /frf/000000/           attrs: quantity, direction, source, estimator, n_averages,
                                  exp_window_tau_s (NaN if none), pose (6 floats; NaN if none),
                                  meta_<key> for scalar metadata (e.g. meta_path_s_m)
        frequency_hz       (n_f,) float64
        values             (n_f,) complex128, SI (m/N for compliance)
        coherence          (n_f,) float64, optional
        meta_<key>         array metadata, optional (e.g. meta_flagged: OMA bins not to use)

UFF: one dataset 58 per FRF, function type 4, ordinate = response (8/11/12), denominator =
force (13), units in the labels (m/N, m/s/N, m/s^2/N); pose is not part of dataset 58 and is
written into the ID lines as ``pose=x,y,z,rx,ry,rz``.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ..files.h5format import FRF_FORMAT, as_text, open_checked, write_header
from ..files.h5safe import USERBLOCK_SIZE, FileContentError, read_array, seal, seal_file
from ..files.provenance import set_units, unit_of_key, write_provenance
from ..files.safe_write import atomic_output
from ..frf.core import FRF
from .frf_csv import check_frf_has_phase

__all__ = [
    "read_frfs",
    "read_frfs_hdf5",
    "read_frfs_uff",
    "write_frfs",
    "write_frfs_hdf5",
    "write_frfs_uff",
]

_FORMAT = FRF_FORMAT
#: Unit of the stored FRF values per quantity (SI).
FRF_UNITS = {"compliance": "m/N", "mobility": "m/s/N", "accelerance": "m/s^2/N"}
_QUANTITY_SPEC = {"compliance": 8, "mobility": 11, "accelerance": 12}
_SPEC_QUANTITY = {v: k for k, v in _QUANTITY_SPEC.items()}
_QUANTITY_LABEL = {"compliance": "m/N", "mobility": "m/s/N", "accelerance": "m/s^2/N"}
_DIR_CODE = {"x": 1, "y": 2, "z": 3}
_CODE_DIR = {v: k for k, v in _DIR_CODE.items()}


def write_frfs_hdf5(
    path: str | Path, frfs: Sequence[FRF], *, inputs: Sequence = (), force: bool = False
) -> None:
    """Write FRFs to a robovib HDF5 file, atomically (see :func:`robovib.io.atomic_output`).

    Parameters
    ----------
    path : path-like
        Output ``.h5`` file; replaced only after a complete write.
    frfs : sequence of FRF
    inputs : sequence of path-like, optional
        Files the FRFs come from; ``path`` must not be one of them unless ``force``.
    force : bool, default False

    Raises
    ------
    OutputPathError
        Missing / read-only output folder, or output = input without ``force``.
    ValueError
        Metadata that cannot be stored.
    """
    import h5py

    with atomic_output(path, inputs=inputs, force=force) as tmp:
        with h5py.File(tmp, "w", userblock_size=USERBLOCK_SIZE) as h5:
            write_header(
                h5, _FORMAT, 1,
                units="frequency_hz Hz; values SI per quantity (compliance m/N, mobility m/s/N, "
                "accelerance m/s^2/N); pose X, Y, Z m, Rx, Ry, Rz deg; exp_window_tau_s s",
            )  # fmt: skip
            grp = h5.create_group("frf")
            for i, frf in enumerate(frfs):
                g = grp.create_group(f"{i:06d}")
                set_units(g.create_dataset("frequency_hz", data=frf.frequency_hz), "Hz")
                set_units(g.create_dataset("values", data=frf.values), FRF_UNITS[frf.quantity])
                if frf.coherence is not None:
                    set_units(g.create_dataset("coherence", data=frf.coherence), "1")
                g.attrs["quantity"] = frf.quantity
                g.attrs["direction"] = frf.direction or ""
                g.attrs["source"] = frf.source
                g.attrs["estimator"] = frf.estimator
                g.attrs["n_averages"] = int(frf.n_averages)
                g.attrs["exp_window_tau_s"] = (
                    np.nan if frf.exp_window_tau_s is None else frf.exp_window_tau_s
                )
                g.attrs["pose"] = (
                    np.full(6, np.nan) if frf.pose is None else np.asarray(frf.pose, float)
                )
                for key, value in frf.meta.items():
                    if isinstance(value, np.ndarray):
                        set_units(
                            g.create_dataset(f"meta_{key}", data=value), unit_of_key(key) or "1"
                        )
                    elif isinstance(value, int | float | str | bool | np.generic):
                        g.attrs[f"meta_{key}"] = value
                    else:
                        raise ValueError(
                            f"FRF meta {key!r} of type {type(value).__name__} cannot be stored"
                        )
            write_provenance(h5, inputs=inputs)
            seal(h5)
        seal_file(tmp)


def read_frfs_hdf5(path: str | Path) -> list[FRF]:
    """Read a robovib FRF file (:func:`write_frfs_hdf5`), checked member by member.

    The file must touch only itself and match its checksum (:mod:`robovib.files.h5safe`); each
    FRF's datasets must be 1-D arrays of the same length (frequency real, values complex,
    coherence real) and its attributes of the written types.

    Parameters
    ----------
    path : str or pathlib.Path
        The ``.h5`` file.

    Returns
    -------
    list of FRF
        The FRFs in stored order.

    Raises
    ------
    ValueError
        Not a robovib FRF file, or a member missing or of the wrong type or shape (a
        :class:`robovib.files.h5safe.FileContentError` naming the file and the member).
    """
    path = Path(path)
    h5, _, _ = open_checked(path, {_FORMAT: 1}, what=f"robovib FRF ({_FORMAT})")
    with h5:
        if "frf" not in h5 or not isinstance(h5["frf"], _h5py().Group):
            raise FileContentError(path, "group is missing", "frf")
        return [_read_frf_group(h5["frf"][name], f"frf/{name}", path)
                for name in sorted(h5["frf"])]  # fmt: skip


def _h5py():
    import h5py

    return h5py


def _frf_attr(g, key: str, member: str, path, kind: str):
    if key not in g.attrs:
        raise FileContentError(path, f"attribute '{key}' is missing", member)
    v = g.attrs[key]
    if kind == "text":
        if not isinstance(v, str | bytes):
            raise FileContentError(path, f"attribute '{key}' is not text", member)
        return as_text(v)
    arr = np.asarray(v)
    if arr.dtype.kind not in "biuf" or (kind == "int" and arr.dtype.kind == "f"):
        raise FileContentError(path, f"attribute '{key}' is not a number", member)
    if kind == "pose":
        if arr.shape != (6,):
            raise FileContentError(path, f"attribute '{key}' is not 6 numbers", member)
        return arr.astype(float)
    if arr.ndim != 0:
        raise FileContentError(path, f"attribute '{key}' is not a single number", member)
    return int(arr) if kind == "int" else float(arr)


def _frf_data(g, key: str, member: str, path, kinds: str, optional: bool = False):
    if key not in g:
        if optional:
            return None
        raise FileContentError(path, "dataset is missing", f"{member}/{key}")
    v = read_array(g, key, path, member=f"{member}/{key}")
    if v.dtype.kind not in kinds:
        want = "complex numbers" if kinds == "fc" else "real numbers"
        raise FileContentError(path, f"holds {v.dtype} values, expected {want}", f"{member}/{key}")
    if v.ndim != 1:
        raise FileContentError(path, f"has shape {v.shape}, expected one axis", f"{member}/{key}")
    return v


def _read_frf_group(g, member: str, path) -> FRF:
    if not isinstance(g, _h5py().Group):
        raise FileContentError(path, "is a dataset where an FRF group was expected", member)
    f = _frf_data(g, "frequency_hz", member, path, "iuf")
    values = _frf_data(g, "values", member, path, "fc")
    coherence = _frf_data(g, "coherence", member, path, "iuf", optional=True)
    for key, v in (("values", values), ("coherence", coherence)):
        if v is not None and v.shape != f.shape:
            raise FileContentError(
                path, f"has {v.size} bins but frequency_hz has {f.size}", f"{member}/{key}"
            )
    pose = _frf_attr(g, "pose", member, path, "pose")
    tau = _frf_attr(g, "exp_window_tau_s", member, path, "float")
    meta = {}
    for k in g.attrs:
        if k.startswith("meta_"):
            v = g.attrs[k]
            meta[k[5:]] = as_text(v) if isinstance(v, bytes) else v
    for k in g:
        if k.startswith("meta_"):
            meta[k[5:]] = read_array(g, k, path, member=f"{member}/{k}")
    try:
        frf = FRF(
            frequency_hz=f,
            values=values,
            coherence=coherence,
            quantity=_frf_attr(g, "quantity", member, path, "text"),
            direction=_frf_attr(g, "direction", member, path, "text") or None,
            pose=None if np.all(np.isnan(pose)) else tuple(pose.tolist()),
            source=_frf_attr(g, "source", member, path, "text"),
            n_averages=_frf_attr(g, "n_averages", member, path, "int"),
            exp_window_tau_s=None if np.isnan(tau) else tau,
            estimator=_frf_attr(g, "estimator", member, path, "text"),
            meta=meta,
        )
    except ValueError as exc:  # the FRF's own checks, in words
        raise FileContentError(path, str(exc), member) from None
    return check_frf_has_phase(frf, f"{path}: /{member}/values")


def _uff_scalar_meta(i: int, frf: FRF) -> str:
    """ID line 5: the scalar metadata as compact JSON (``meta={...}``), checked to fit."""
    import json

    scalars = {}
    for key, value in frf.meta.items():
        if key == "reference_direction" or isinstance(value, np.ndarray):
            continue  # ref_dir field / companion record
        if isinstance(value, np.generic):
            value = value.item()
        if not isinstance(value, int | float | str | bool):
            raise ValueError(
                f"FRF {i}: meta {key!r} of type {type(value).__name__} cannot be stored in UFF; "
                "write .h5 instead"
            )
        if isinstance(value, float) and not np.isfinite(value):
            raise ValueError(f"FRF {i}: meta {key!r} = {value} cannot be stored in UFF")
        scalars[key] = value
    if not scalars:
        return "NONE"
    line = "meta=" + json.dumps(scalars, separators=(",", ":"))
    if len(line) > 80:
        raise ValueError(
            f"FRF {i}: its scalar metadata ({', '.join(scalars)}) needs {len(line)} characters, "
            "more than UFF's 80-character ID line; write .h5 instead"
        )
    return line


def write_frfs_uff(
    path: str | Path, frfs: Sequence[FRF], *, inputs: Sequence = (), force: bool = False
) -> None:
    """Write FRFs as UFF datasets 58 in one pass, atomically, keeping every field.

    Per FRF: one record of function type 4 (the FRF), and companion records with the same
    load case: the coherence (function type 6) and each array metadata (e.g. the OMA
    ``flagged`` bins; function type 0, ID line 1 ``robovib FRF meta <key>``). The ID lines
    hold source and estimator (1), pose (2), direction (3), number of averages and the
    exponential-window time constant (4) and the scalar metadata as JSON (5). The reference
    (force) direction is ``meta["reference_direction"]`` when set (a cross FRF), otherwise the
    response direction. What cannot be stored (metadata too long for an 80-character ID line,
    a frequency axis not representable in the 13-character abscissa fields) is refused, never
    dropped; ordinates keep 12 significant digits (UFF's E20.11).

    Parameters
    ----------
    path : str or pathlib.Path
        The ``.uff``/``.unv`` file to write.
    frfs : sequence of FRF
        The FRFs (evenly spaced frequency axes).
    inputs : sequence of path
        Files the FRFs were made from (never overwritten unless ``force``).
    force : bool
        Allow ``path`` to be one of ``inputs``.

    Raises
    ------
    OutputPathError
        Missing / read-only output folder, or output = input without ``force``.
    ValueError
        Uneven frequency axis, or a field that does not fit (write .h5 instead).
    """
    from .uff58 import Record58, _e13, write_uff58

    records = []
    for i, frf in enumerate(frfs):
        f = frf.frequency_hz
        df = np.diff(f)
        if f.size < 2 or (f.size > 2 and np.ptp(df) > 1e-9 * np.mean(df)):
            raise ValueError(f"FRF {i}: UFF dataset 58 needs an evenly spaced frequency axis")
        x0, dx = float(f[0]), float(np.mean(df))
        x0_w, dx_w = float(_e13(x0)), float(_e13(dx))
        back = x0_w + dx_w * np.arange(f.size)
        if np.max(np.abs(back - f)) > 1e-9 * dx:
            raise ValueError(
                f"FRF {i}: its frequency axis (start {x0!r} Hz, step {dx!r} Hz) cannot be written "
                "exactly in UFF's 13-character abscissa fields; write .h5 instead"
            )
        dcode = _DIR_CODE.get(frf.direction or "", 0)
        ref = str(frf.meta.get("reference_direction", "") or "")
        rcode = _DIR_CODE.get(ref, dcode)
        # pose: X, Y, Z [m] in ID line 2, Rx, Ry, Rz [deg] in ID line 3, exact (shortest repr)
        pose = rot = "NONE"
        if frf.pose is not None:
            pose = "pose=" + ",".join(repr(float(p)) for p in frf.pose[:3])
            rot = "rot=" + ",".join(repr(float(p)) for p in frf.pose[3:])
        tau = "" if frf.exp_window_tau_s is None else f";exp_window_tau_s={frf.exp_window_tau_s!r}"
        common = dict(
            x0=x0, dx=dx, abscissa_spec=18, abscissa_label="Hz", load_case_id=i, rsp_node=1,
            rsp_dir=dcode, ref_node=1, ref_dir=rcode,
        )  # fmt: skip
        records.append(
            Record58(
                data=np.asarray(frf.values, complex),
                func_type=4,
                ordinate_spec=_QUANTITY_SPEC[frf.quantity],
                ordinate_label=_QUANTITY_LABEL[frf.quantity],
                denominator_spec=13,
                denominator_label="N",
                ids=(
                    f"robovib FRF {frf.source} {frf.estimator}",
                    pose,
                    rot,
                    f"n_averages={frf.n_averages}{tau}",
                    _uff_scalar_meta(i, frf),
                ),
                **common,
            )
        )
        if frf.coherence is not None:
            records.append(
                Record58(
                    data=np.asarray(frf.coherence, float),
                    func_type=6,
                    ordinate_spec=0,
                    ordinate_label="NONE",
                    ids=("robovib FRF coherence", "NONE", "NONE", "NONE", "NONE"),
                    **common,
                )
            )
        for key, value in frf.meta.items():
            if not isinstance(value, np.ndarray):
                continue
            if value.ndim != 1 or value.dtype.kind not in "biufc":
                raise ValueError(
                    f"FRF {i}: meta {key!r} ({value.dtype}, shape {value.shape}) cannot be stored "
                    "in UFF (1-D numeric arrays only); write .h5 instead"
                )
            if value.size == 0:
                raise ValueError(f"FRF {i}: empty meta array {key!r} cannot be stored in UFF")
            if value.dtype.kind in "iu" and np.any(np.abs(value) >= 10**11):
                raise ValueError(f"FRF {i}: meta {key!r} has integers too large for UFF")
            ident = f"robovib FRF meta {key}"
            if len(ident) > 80 or " " in key:
                raise ValueError(f"FRF {i}: meta key {key!r} cannot be stored in UFF")
            records.append(
                Record58(
                    data=value.astype(complex if value.dtype.kind == "c" else float),
                    func_type=0,
                    ordinate_spec=0,
                    ordinate_label="NONE",
                    ids=(ident, f"dtype={value.dtype.str}", "NONE", "NONE", "NONE"),
                    x0=0.0,
                    dx=1.0,
                    abscissa_spec=0,
                    abscissa_label="index",
                    load_case_id=i,
                    rsp_node=1,
                    rsp_dir=dcode,
                    ref_node=1,
                    ref_dir=rcode,
                )
            )
    write_uff58(path, records, inputs=inputs, force=force)


def read_frfs_uff(path: str | Path) -> list[FRF]:
    """Read every dataset 58 FRF (function type 4) of a UFF file, converting units to SI.

    Parameters
    ----------
    path : str or pathlib.Path
        The UFF file.

    Returns
    -------
    list of FRF
        One per FRF record, in SI, with its coherence and metadata.
    """
    import pyuff

    from ..files.safe_read import check_input_file
    from ..files.units import si_factor

    path = check_input_file(path, "UFF file")  # regular file, below the size limit
    try:
        sets = pyuff.UFF(str(path)).read_sets()
    except Exception as exc:  # pyuff raises bare Exceptions on corrupt files
        raise ValueError(f"{path}: not a readable UFF file ({exc})") from None
    sets = [sets] if isinstance(sets, dict) else list(sets)
    from .recording.uff_layout import _check_uff_complete

    _check_uff_complete(path, sum(s.get("type") == 58 for s in sets))
    try:
        return _frfs_of_uff_sets(sets, path, si_factor)
    except ValueError as exc:  # the record's own check: name the file
        msg = str(exc)
        raise ValueError(msg if str(path) in msg else f"{path}: {msg}") from None
    except (KeyError, IndexError, TypeError, AttributeError):
        raise ValueError(
            f"{path}: a dataset 58 lacks a field or holds an unreadable one: a damaged file"
        ) from None


def _frfs_of_uff_sets(sets, path: Path, si_factor) -> list[FRF]:
    out = []
    lc_index: dict[int, int] = {}  # load case -> FRF index, for robovib's companion records
    companions = []
    for s in sets:
        if (
            s.get("type") == 58
            and str(s.get("id1", "")).startswith("robovib FRF ")
            and s.get("func_type") in (0, 6)
        ):
            companions.append(s)
            continue
        if s.get("type") != 58 or s.get("func_type") != 4:
            continue
        spec = int(s.get("ordinate_spec_data_type", 0))
        if spec not in _SPEC_QUANTITY:
            raise ValueError(f"{path}: FRF with unsupported ordinate specific data type {spec}")
        quantity = _SPEC_QUANTITY[spec]
        num_label = str(s.get("ordinate_axis_units_lab", "")).strip()
        den_label = str(s.get("orddenom_axis_units_lab", "")).strip() or "N"
        if num_label.endswith("/N"):  # our writer puts the whole FRF unit in the numerator label
            num_label = num_label[: -len("/N")]
        _, num = si_factor(
            num_label,
            {"compliance": "displacement", "mobility": "velocity", "accelerance": "acceleration"}[
                quantity
            ],
        )
        _, den = si_factor(den_label, "force")
        pose = None
        id2 = str(s.get("id2", ""))
        id3 = str(s.get("id3", "")).strip()
        try:
            if id2.startswith("pose="):
                pose = tuple(float(p) for p in id2[5:].split(","))
                if len(pose) == 3 and id3.startswith("rot="):
                    pose = pose + tuple(float(p) for p in id3[4:].split(","))
                if len(pose) != 6:
                    raise ValueError
        except ValueError:
            raise ValueError(
                f"{path}: FRF record {len(out)}: unreadable pose in ID lines 2-3 ({id2!r}, {id3!r})"
            ) from None
        code, ref = int(s.get("rsp_dir", 0)), int(s.get("ref_dir", 0))
        if abs(code) > 3 or abs(ref) > 3:
            raise ValueError(
                f"{path}: FRF record {len(out)} has a rotational DOF (rsp_dir {code}, "
                f"ref_dir {ref}); only translations (±1-3) are supported"
            )
        # A DOF along -X is the X one with opposite sign: H(+x, +x) = sign * H(file).
        sign = (-1.0 if code < 0 else 1.0) * (-1.0 if ref < 0 else 1.0)
        direction = _CODE_DIR.get(abs(code))
        meta = {}
        if ref and abs(ref) != abs(code):
            # A cross FRF: response along one axis, force along another.
            meta["reference_direction"] = _CODE_DIR[abs(ref)]
        extra = _robovib_ids(s, path, len(out))
        meta.update(extra.pop("meta", {}))
        if extra:
            lc = int(s.get("load_case_id", -1))
            if lc in lc_index:
                raise ValueError(f"{path}: two robovib FRF records share load case {lc}")
            lc_index[lc] = len(out)
        out.append(
            FRF(
                frequency_hz=np.asarray(s["x"], float),
                values=sign * np.asarray(s["data"], complex) * num / den,
                quantity=quantity,
                direction=direction,
                pose=pose,
                meta=meta,
                **extra,
            )
        )
    if not out:
        raise ValueError(f"{path}: no dataset 58 FRF records (function type 4)")
    for i, frf in enumerate(out):
        check_frf_has_phase(frf, f"{path}: FRF record {i}")
    return _attach_companions(out, companions, lc_index, path)


def _robovib_ids(s: dict, path, index: int) -> dict:
    """Fields written by robovib into the ID lines (empty for other writers' files)."""
    import json

    id1 = str(s.get("id1", "")).split()
    if id1[:2] != ["robovib", "FRF"] or len(id1) != 4:
        return {}
    out: dict = {"source": id1[2], "estimator": id1[3]}
    for item in str(s.get("id4", "")).strip().split(";"):
        key, _, value = item.partition("=")
        try:
            if key == "n_averages":
                out["n_averages"] = int(value)
            elif key == "exp_window_tau_s":
                out["exp_window_tau_s"] = float(value)
        except ValueError:
            raise ValueError(f"{path}: FRF record {index}: unreadable ID line 4 {item!r}") from None
    id5 = str(s.get("id5", "")).strip()
    if id5.startswith("meta="):
        try:
            meta = json.loads(id5[5:])
        except json.JSONDecodeError:
            raise ValueError(f"{path}: FRF record {index}: unreadable metadata {id5!r}") from None
        if not isinstance(meta, dict):
            raise ValueError(f"{path}: FRF record {index}: unreadable metadata {id5!r}")
        out["meta"] = meta
    return out


def _attach_companions(frfs: list[FRF], companions, lc_index, path) -> list[FRF]:
    """Coherence (function type 6) and array metadata records of robovib's FRFs."""
    from dataclasses import replace

    for s in companions:
        lc = int(s.get("load_case_id", -1))
        if lc not in lc_index:
            raise ValueError(
                f"{path}: {s.get('id1', '').strip()!r} record of unknown load case {lc}"
            )
        i = lc_index[lc]
        frf = frfs[i]
        data = np.asarray(s["data"])
        if s["func_type"] == 6:
            if data.shape != frf.frequency_hz.shape:
                raise ValueError(
                    f"{path}: FRF {i}: coherence has {data.size} bins, FRF {frf.frequency_hz.size}"
                )
            frfs[i] = replace(frf, coherence=np.asarray(data.real, float))
            continue
        key = str(s["id1"]).strip()[len("robovib FRF meta ") :]
        dtype = str(s.get("id2", "")).strip().removeprefix("dtype=")
        try:
            dt = np.dtype(dtype)
        except TypeError:
            raise ValueError(f"{path}: FRF {i}: meta {key!r} has unknown dtype {dtype!r}") from None
        value = np.asarray(data if dt.kind == "c" else data.real)
        if dt.kind in "biu":
            value = np.rint(value)
        frfs[i] = replace(frf, meta={**frf.meta, key: value.astype(dt)})
    return frfs


def write_frfs(
    path: str | Path, frfs: Sequence[FRF], *, inputs: Sequence = (), force: bool = False
) -> None:
    """Write FRFs by file extension: .h5/.hdf5 or .uff/.unv (atomic; output != input).

    Parameters
    ----------
    path : str or pathlib.Path
        The file to write; its extension picks the format.
    frfs : sequence of FRF
        The FRFs.
    inputs : sequence of path
        Files the FRFs were made from (never overwritten unless ``force``).
    force : bool
        Allow ``path`` to be one of ``inputs``.

    Returns
    -------
    None
    """
    suffix = Path(path).suffix.lower()
    if suffix in (".h5", ".hdf5"):
        return write_frfs_hdf5(path, frfs, inputs=inputs, force=force)
    if suffix in (".uff", ".unv"):
        return write_frfs_uff(path, frfs, inputs=inputs, force=force)
    if suffix == ".csv":
        from .frf_csv import write_frf_csv

        return write_frf_csv(path, frfs, inputs=inputs, force=force)
    raise ValueError(
        f"{path}: unknown FRF file format {suffix!r}; expected .h5, .hdf5, .uff, .unv or .csv"
    )


def read_frfs(path: str | Path) -> list[FRF]:
    """Read FRFs by file extension: .h5/.hdf5 or .uff/.unv.

    Parameters
    ----------
    path : str or pathlib.Path
        The FRF file.

    Returns
    -------
    list of FRF
        Every FRF of the file, in SI.
    """
    from ..files.safe_read import MAX_BINARY_BYTES, check_input_file

    suffix = Path(path).suffix.lower()
    if suffix in (".h5", ".hdf5", ".uff", ".unv", ".csv") or os.path.lexists(path):
        check_input_file(path, "FRF file", MAX_BINARY_BYTES)  # a FIFO, /dev/zero: refused
    if suffix in (".h5", ".hdf5"):
        return read_frfs_hdf5(path)
    if suffix in (".uff", ".unv"):
        return read_frfs_uff(path)
    if suffix == ".csv":
        from .frf_csv import read_frf_csv

        return read_frf_csv(path)
    raise ValueError(
        f"{path}: unknown FRF file format {suffix!r}; expected .h5, .hdf5, .uff, .unv or .csv"
    )
