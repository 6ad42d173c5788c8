"""Units of the keys of robovib's JSON documents, and the self-describing document itself.

Every number in a ``--json`` document has a unit: from its key's suffix (``_hz``,
``_n_per_m``, ...; :func:`robovib.files.provenance.unit_of_key`), from ``n_*`` (a count), from the
key of a ``*_std`` stem, or from :data:`KEY_UNITS` for keys whose names carry none.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from .json_safe import json_safe
from .provenance import plain_json, unit_of_key

__all__ = ["KEY_UNITS", "self_describing_document", "unit_of_json_key"]


#: Units of JSON keys whose names carry none (counts and ratios are "1").
KEY_UNITS: dict[str, str] = {
    "hits": "1 (count)",
    "hit": "1 (index)",
    "index": "1 (index)",
    "samples": "1 (count)",
    "samples_per_hit": "1 (count)",
    "segments": "1 (count)",
    "n_frfs": "1 (count)",
    "frfs": "1 (count)",
    "frfs_direct": "1 (count)",
    "frfs_cross": "1 (count)",
    "manifest_rows": "1 (count)",
    "modal_rows": "1 (count)",
    "rows_processed": "1 (count)",
    "rows_skipped": "1 (manifest line numbers)",
    "fitted": "1 (flag)",
    "n_hits": "1 (count)",
    "test": "1 (Table A1 test number)",
    "n_bins": "1 (count)",
    "n_oma": "1 (count)",
    "n_tests": "1 (count)",
    "n_averaged": "1 (count)",
    "n_oma_segments": "1 (count)",
    "seed": "1 (simulator seed)",
    "seeds": "1 (simulator seeds)",
    "nperseg": "1 (samples per Welch segment)",
    "background_noise_rel": "1 (x the RMS cutting force about its mean)",
    "background": "1 (x the RMS cutting force about its mean)",
    "backgrounds": "1 (x the RMS cutting force about its mean)",
    "thesis_gpr_rmse": "per output, in that output's thesis unit (fn Hz, k MN/m, c kN·s/m; see outputs)",
    "thesis_mlr_rmse": "per output, in that output's thesis unit (fn Hz, k MN/m, c kN·s/m; see outputs)",
    "gpr_plain_rmse": "per output, in that output's thesis unit (fn Hz, k MN/m, c kN·s/m; see outputs)",
    "gpr_grouped_rmse": "per output, in that output's thesis unit (fn Hz, k MN/m, c kN·s/m; see outputs)",
    "mlr_insample_rmse": "per output, in that output's thesis unit (fn Hz, k MN/m, c kN·s/m; see outputs)",
    "mlr_cv_rmse": "per output, in that output's thesis unit (fn Hz, k MN/m, c kN·s/m; see outputs)",
    "external_rmse": "per output, in that output's thesis unit (fn Hz, k MN/m, c kN·s/m; see outputs)",
    "thesis_gpr_r2": "1 (coefficient of determination, per output)",
    "thesis_mlr_r2": "1 (coefficient of determination, per output)",
    "gpr_plain_r2": "1 (coefficient of determination, per output)",
    "gpr_grouped_r2": "1 (coefficient of determination, per output)",
    "mlr_insample_r2": "1 (coefficient of determination, per output)",
    "mlr_cv_r2": "1 (coefficient of determination, per output)",
    "external_mean_relative_error": "1 (relative error, per output)",
    "external_max_relative_error": "1 (relative error, per output)",
    "peak_change_worst_pts": "percentage points (of the dominant-peak |H| error)",
    "position": "1 (index)",
    "mean_coherence": "1",
    "relative_rms_error": "1",
    "mean_rel_error": "1",
    "mean_relative_error": "1",
    "min": "1 (relative error)",
    "max": "1 (relative error)",
    "rotation": "1 (direction cosines)",
    "principal_directions": "1 (unit vectors)",
    "mode_directions": "1 (unit vectors)",
    "jacobian_condition_number": "1",
    "cartesian_stiffness_6x6": "N/m, N/rad, N m/m, N m/rad (blocks)",
    "w1": "m/m (command offset per metre of displacement)",
    "w2": "m/(m/s) = s (command offset per m/s of velocity)",
    "thesis_w1": "m/m",
    "thesis_w2": "s",
    "w1_poly_high_to_low": "m/m per m^k (polynomial in s [m], highest power first)",
    "w2_poly_high_to_low": "s per m^k (polynomial in s [m], highest power first)",
    "gains": "[m/m, s, ...] (W over the delay-augmented state)",
    "r": "1 (LQR input weight, Q = diag(1, 0.001))",
    "spectral_radius": "1",
    "spectral_radius_no_delay": "1",
    "spectral_radius_with_delay": "1",
    "gain_margins": "1 (factor)",
    "iterations_mean": "1 (optimiser iterations per GP)",
    "flagged_fraction": "1",
    "n_flutes": "1 (count)",
    "hits_formed": "1 (count)",
    "recordings": "1 (count)",
    "replicate": "1 (index)",
    "candidate_index": "1 (index)",
    "k": "1 (count)",
    "total_normalised_variance_before": "1 (variance / prior variance, summed)",
    "variance_reduction_normalised": "1 (variance / prior variance)",
    "row": "1 (manifest row number)",
    "records_read": "1 (count)",
    "rtol": "1 (relative tolerance)",
    "steps_per_period_min": "1 (count)",
    "steps_per_vibration": "1 (count)",
    "iterations_mean_per_gp": "1 (optimiser iterations per GP)",
    "iterations_total": "1 (count)",
    "n_observations": "1 (count)",
    "n_rejected": "1 (count)",
    "scale_real": "1 (noise scale factor)",
    "scale_imag": "1 (noise scale factor)",
    "scale_std": "1 (noise scale factor)",
}


def unit_of_json_key(key: str) -> str | None:
    """Unit of a JSON key: from its suffix (``_hz``, ``_n_per_m`` ...), ``n_*`` (a count) or
    :data:`KEY_UNITS`.

    Parameters
    ----------
    key : str
        The key.

    Returns
    -------
    str or None
        The unit, or None when unknown.
    """
    key = str(key)
    if key in KEY_UNITS:
        return KEY_UNITS[key]
    if key.startswith("n_"):  # n_hits, n_flagged, ...: counts
        return "1 (count)"
    if key.endswith("_std") and len(key) > 4:  # damping_ratio_std: the unit of damping_ratio
        return unit_of_json_key(key[:-4])
    return unit_of_key(key) or KEY_UNITS.get(key)


def _numeric_keys(obj: Any, key: str | None, out: set[str]) -> None:
    """Keys whose values (or list items) are numbers, anywhere in ``obj``; a dict under a key
    with a unit (``{"stiffness_n_per_m": {"x": ...}}``), with a ``unit`` entry or an ``output``
    whose name has a unit (``{"output": "x_fn_hz", "mean": ...}``) states its own."""
    if isinstance(obj, dict):
        if "unit" in obj or "units" in obj or (key is not None and unit_of_json_key(key)):
            return
        named = obj.get("output")  # a record of one output whose name says its unit
        if isinstance(named, str) and unit_of_json_key(named):
            return
        for k, v in obj.items():
            _numeric_keys(v, str(k), out)
    elif isinstance(obj, list):
        for v in obj:
            _numeric_keys(v, key, out)
    elif isinstance(obj, int | float) and not isinstance(obj, bool) and key is not None:
        out.add(key)


def self_describing_document(
    doc: Mapping[str, Any], provenance: Mapping[str, Any], units: Mapping[str, str] | None = None
) -> dict:
    """``doc`` with ``robovib_version``, ``command``, ``settings``, ``settings_units``,
    ``input_files`` (from ``provenance``, see :func:`robovib.files.provenance.run_provenance`) and
    ``units`` (unit of every numeric key whose name has no unit suffix) added.

    Keys of ``doc`` that collide with the added ones are kept as ``result_<key>``; keys with no
    known unit are listed as ``"unknown"`` so a test can find them.

    Parameters
    ----------
    doc : mapping
        The command's result document.
    provenance : mapping
        The run's provenance (:func:`robovib.files.provenance.run_provenance`).
    units : mapping, optional
        Units of keys whose names carry none.

    Returns
    -------
    dict
        The self-describing document.
    """
    raw = dict(doc)
    raw.pop("robovib_version", None)
    for key in ("command", "settings", "settings_units", "input_files"):
        if key in raw:  # the result's own: kept under result_<key>
            raw[f"result_{key}"] = raw.pop(key)
    body, _ = json_safe(raw)  # JSON-ready copy (NaN/inf -> null) to find the numbers
    keys: set[str] = set()
    _numeric_keys(body, None, keys)
    extra = dict(units or {})
    key_units = {}
    for k in sorted(keys):
        u = extra.get(k) or unit_of_json_key(k)
        if u is not None and (k in extra or k in KEY_UNITS):
            key_units[k] = u
        elif u is None:
            key_units[k] = "unknown"
    return {
        "robovib_version": provenance["robovib_version"],
        "command": provenance["command"],
        "settings": provenance["settings"],
        "settings_units": provenance["units"],
        "input_files": provenance["input_files"],
        **raw,
        "units": {**key_units, **plain_json(body.get("units", {}))},
    }
