"""JSON without NaN or Infinity: non-finite numbers become ``null`` with a stated reason.

``json.dumps`` writes ``NaN`` and ``Infinity`` by default — tokens that are not JSON and that
strict parsers (JavaScript, jq, most databases) reject, or worse, read as a number. Every JSON
document robovib prints or writes goes through :func:`dumps`: each non-finite float is replaced
by ``null`` and its location is listed under ``"null_reasons"`` (``{"path.to[3].value": "NaN"}``)
so that a reader can tell "no value" from "value lost".
"""

from __future__ import annotations

import json
import math
from typing import Any

import numpy as np

__all__ = ["dumps", "json_safe"]


def _reason(x: float) -> str:
    if math.isnan(x):
        return "not a number: no value could be computed"
    return f"{'+' if x > 0 else '-'}infinity: no finite value (unbounded)"


def json_safe(obj: Any, _path: str = "", _reasons: dict | None = None) -> tuple[Any, dict]:
    """Plain-JSON copy of ``obj`` (numpy arrays/scalars converted) and the null reasons.

    Returns
    -------
    clean : object
        Only dict/list/str/int/float/bool/None; floats are finite.
    reasons : dict[str, str]
        JSON path of every non-finite number replaced by ``None`` -> why.

    Parameters
    ----------
    obj : object
        The document.
    _path, _reasons
        Recursion state (JSON path so far, reasons found so far); leave them out.
    """
    reasons = {} if _reasons is None else _reasons
    if isinstance(obj, dict):
        out = {}
        for k, v in obj.items():
            key = str(k)
            out[key], _ = json_safe(v, f"{_path}.{key}" if _path else key, reasons)
        return out, reasons
    if isinstance(obj, list | tuple):
        return [json_safe(v, f"{_path}[{i}]", reasons)[0] for i, v in enumerate(obj)], reasons
    if isinstance(obj, np.ndarray):
        return json_safe(obj.tolist(), _path, reasons)
    if isinstance(obj, np.generic):
        return json_safe(obj.item(), _path, reasons)
    if isinstance(obj, complex):
        return json_safe({"re": obj.real, "im": obj.imag}, _path, reasons)
    if isinstance(obj, float) and not math.isfinite(obj):
        reasons[_path or "(document)"] = _reason(obj)
        return None, reasons
    if obj is None or isinstance(obj, str | int | float | bool):
        return obj, reasons
    if hasattr(obj, "__fspath__"):
        return str(obj), reasons
    raise TypeError(f"{_path or 'document'}: {type(obj).__name__} is not JSON serialisable")


def dumps(doc: Any, *, indent: int | None = 2) -> str:
    """``json.dumps`` that never writes NaN/Infinity (see module docs).

    When something was replaced and ``doc`` is a dict, a ``"null_reasons"`` entry is added (or
    merged with an existing one).

    Parameters
    ----------
    doc : object
        The document (dicts, lists, numbers, numpy arrays/scalars).
    indent : int, optional
        Indentation of the JSON text.

    Returns
    -------
    str
        The JSON text.
    """
    clean, reasons = json_safe(doc)
    if reasons:
        if isinstance(clean, dict):
            clean["null_reasons"] = {**clean.get("null_reasons", {}), **reasons}
        else:
            clean = {"value": clean, "null_reasons": reasons}
    return json.dumps(clean, indent=indent, allow_nan=False)
