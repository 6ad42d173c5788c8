"""Every mode of a campaign, tracked across poses: the multi-mode modal table and its pose model.

The dominant-mode table (``modal.csv``, thesis Table A1) keeps one mode per recording; chatter
depends on every mode whose flexibility the cut excites (issue 29). Here:

* :func:`fit_row_modes` — every mode the stabilization diagram supports in a band
  (:func:`robovib.modal.fit_modes`: LSCF poles, automatic choice, LSFD stiffness), one dict per
  mode with the fit's relative residual and flags;
* :func:`track_modes` — a mode id per fitted mode, consistent across poses: per direction the
  reference number of modes ``K`` is the most common count; at poses with ``K`` modes the id is
  the rank in frequency (``x1 < x2 < ...``); at other poses the fitted modes are assigned to
  the ids by the least total |log frequency| distance to the ids' frequencies at the nearest
  complete poses (Hungarian assignment), and a mode farther than ``max_log_distance`` from
  every id is left untracked (``mode_id`` empty) rather than mislabelled. A mode id missing at
  a pose is simply absent there: its presence fraction is reported;
* :func:`fit_multimode_pose_model` — one :class:`robovib.gp.PoseModalModel` whose "directions"
  are the mode ids (``x1``, ``x2``, ``y1``, ...): fn, k, c of every tracked mode with the same
  calibrated bands as the dominant-mode model, saved in the same HDF5 format. The chapter-3
  model and ``modal.csv`` stay dominant-mode.
"""

from __future__ import annotations

import json

import numpy as np

__all__ = [
    "fit_campaign_table",
    "fit_multimode_pose_model",
    "fit_row_modes",
    "mode_direction",
    "track_modes",
]


def mode_direction(mode_id: str) -> str:
    """Physical direction of a mode id (``"x2"`` -> ``"x"``).

    Parameters
    ----------
    mode_id : str
        A mode id: direction letter(s) followed by the mode number.

    Returns
    -------
    str
        The direction.

    Raises
    ------
    ValueError
        Not a direction followed by a number.
    """
    d = str(mode_id).rstrip("0123456789")
    if not d or d == mode_id:
        raise ValueError(f"not a mode id (direction + number): {mode_id!r}")
    return d


def fit_row_modes(frf, band_hz: tuple[float, float], *, max_order: int = 30) -> list[dict]:
    """Every mode of one driving-point FRF in a band (one dict per mode, SI units).

    Parameters
    ----------
    frf : robovib.frf.FRF
        Driving-point FRF (any form; converted to compliance).
    band_hz : (float, float)
        Fit band [Hz].
    max_order : int
        Highest order of the stabilization diagram.

    Returns
    -------
    list of dict
        Keys ``fn_hz``, ``stiffness_n_per_m``, ``damping_ns_per_m``, ``damping_ratio``,
        ``rank`` (1 = lowest frequency), ``relative_rms_error`` (of the whole fit) and
        ``mode_flags`` (the fit's flags naming this mode, and the whole-fit flags).
    """
    import warnings

    from ..modal import fit_modes

    lo, hi = (float(v) for v in band_hz)
    if not (0 < lo < hi):
        raise ValueError(f"need 0 < band low < band high, got {band_hz!r} Hz")
    with warnings.catch_warnings():  # modes left out are reported in the flags
        warnings.simplefilter("ignore")
        fit = fit_modes(frf, (lo, hi), max_order=max_order)
    general = [f for f in fit.flags if not f.startswith("mode at")]
    out = []
    for i, m in enumerate(fit.modes):
        own = [f for f in fit.flags if f.startswith(f"mode at {m.natural_frequency_hz:.4g} Hz")]
        out.append({
            "fn_hz": m.natural_frequency_hz,
            "stiffness_n_per_m": m.stiffness_n_per_m,
            "damping_ns_per_m": m.damping_ns_per_m,
            "damping_ratio": m.damping_ratio,
            "rank": i + 1,
            "relative_rms_error": fit.relative_rms_error,
            "mode_flags": "; ".join(own + general),
        })  # fmt: skip
    return out


def track_modes(
    table,
    inputs=("x_mm", "y_mm", "rz_deg"),
    *,
    max_log_distance: float = 0.25,
    n_neighbours: int = 3,
):
    """Give every fitted mode a mode id consistent across poses (module docstring).

    Parameters
    ----------
    table : pandas.DataFrame
        One row per fitted mode with ``direction``, ``fn_hz``, a recording key ``row`` and the
        pose columns ``inputs``.
    inputs
        Pose columns (the neighbours of an incomplete pose are found in them, scaled to [0, 1]).
    max_log_distance
        Largest |ln(fn / fn_id)| at which a mode of an incomplete pose is given an id.
    n_neighbours
        Complete poses whose id frequencies (median) are the reference of an incomplete pose.

    Returns
    -------
    (pandas.DataFrame, dict)
        The table with a ``mode_id`` column (empty string: untracked) and, per mode id, its
        presence: ``{"x1": {"n_recordings": .., "n_seen": .., "presence": ..}, ...}``.
    """
    from scipy.optimize import linear_sum_assignment

    missing = [c for c in ("direction", "fn_hz", "row", *inputs) if c not in table.columns]
    if missing:
        raise ValueError(f"mode table lacks column(s) {', '.join(missing)}")
    if not (max_log_distance > 0):
        raise ValueError(f"max_log_distance must be > 0, got {max_log_distance!r}")
    table = table.copy()
    table["mode_id"] = ""
    presence: dict[str, dict] = {}
    for d, grp in table.groupby("direction", sort=True):
        recs = {r: g.sort_values("fn_hz") for r, g in grp.groupby("row", sort=True)}
        counts = np.array([len(g) for g in recs.values()])
        K = int(np.bincount(counts).argmax())
        complete = [r for r, g in recs.items() if len(g) == K]
        ref_X = np.array([recs[r][list(inputs)].iloc[0].to_numpy(float) for r in complete])
        ref_f = np.array([np.log(recs[r]["fn_hz"].to_numpy(float)) for r in complete])
        all_X = np.array([g[list(inputs)].iloc[0].to_numpy(float) for g in recs.values()])
        lo, span = all_X.min(axis=0), np.ptp(all_X, axis=0)
        span = np.where(span > 0, span, 1.0)
        ids = [f"{d}{k + 1}" for k in range(K)]
        for g in recs.values():
            if len(g) == K:
                table.loc[g.index, "mode_id"] = ids
                continue
            x = (g[list(inputs)].iloc[0].to_numpy(float) - lo) / span
            dist = np.linalg.norm((ref_X - lo) / span - x, axis=1)
            near = np.argsort(dist)[: max(1, int(n_neighbours))]
            ref = np.median(ref_f[near], axis=0)  # (K,) log frequency of each id here
            cost = np.abs(np.log(g["fn_hz"].to_numpy(float))[:, None] - ref[None, :])
            ri, ci = linear_sum_assignment(cost)
            for i, j in zip(ri, ci, strict=True):
                if cost[i, j] <= max_log_distance:
                    table.loc[g.index[i], "mode_id"] = ids[j]
        n_rec = len(recs)
        for k in ids:
            seen = int(np.sum(table.loc[grp.index, "mode_id"] == k))
            presence[k] = {"n_recordings": n_rec, "n_seen": seen, "presence": seen / n_rec}
    return table, presence


def fit_multimode_pose_model(
    modes_csv,
    inputs=("x_mm", "y_mm", "rz_deg"),
    kernel: str = "ard",
    *,
    directions=("x", "y"),
    min_presence: float = 0.5,
    n_folds: int = 5,
    rng=0,
    covariance: str = "auto",
):
    """Pose model of every tracked mode of a campaign's ``modes.csv`` (module docstring).

    The table is checked first (:func:`robovib.campaign.table_checks.check_modes_table`):
    blank ids, duplicates, crossed labels and outliers are refused or named with file, line and
    column. Every warning is issued as a
    :class:`~robovib.campaign.quality.ModelQualityWarning` and kept in ``warnings``.

    Parameters
    ----------
    modes_csv
        Path to ``modes.csv`` (written by ``campaign process --modes-band``) or a DataFrame
        with its columns (``mode_id`` included).
    inputs, kernel, n_folds, rng, covariance
        As for :func:`robovib.campaign.fit_pose_model_from_table`.
    directions
        Physical directions whose modes are modelled.
    min_presence
        Mode ids seen at fewer than this fraction of the recordings are left out (named in a
        warning and in the provenance): too few poses to learn a field from.

    Returns
    -------
    PoseModelFit
        Its model's ``directions`` are the mode ids (``x1``, ``x2``, ...), its provenance has
        ``mode_presence`` (JSON: per id, recordings, seen, fraction) and ``multimode = 1``.

    Raises
    ------
    ValueError
        A damaged table (file, line and column named) or no mode id to model.
    """
    import warnings
    from dataclasses import replace

    import pandas as pd

    from ..files.csv_table import read_table
    from .model import fit_pose_model_from_table
    from .quality import ModelQualityWarning
    from .table_checks import check_modes_table

    if isinstance(modes_csv, pd.DataFrame):
        table, source, lines = modes_csv, "mode table", None
    else:  # the one CSV reader: errors name the line
        raw = read_table(modes_csv, what="mode table")
        table, source, lines = raw.to_frame(), str(modes_csv), raw.lines
    # Checked before anything is fitted: errors and warnings name the file, line and column.
    checked = check_modes_table(table, source=source, lines=lines, inputs=tuple(inputs))
    notes = list(checked.warnings)
    table = table.assign(mode_id=table["mode_id"].astype("string").fillna("").astype(str))
    n_rec = {d: g["row"].nunique() for d, g in table.groupby("direction")}
    tracked = checked.table
    presence, ids = {}, []
    for k, g in tracked.groupby("mode_id", sort=True):
        d = mode_direction(k)
        frac = g["row"].nunique() / n_rec[d]
        presence[k] = {"n_recordings": int(n_rec[d]), "n_seen": int(g["row"].nunique()),
                       "presence": float(frac)}  # fmt: skip
        if d in directions and frac >= min_presence:
            ids.append(k)
    for k in sorted(set(presence) - set(ids)):
        p = presence[k]
        if mode_direction(k) in directions:  # other directions are left out by choice
            notes.append(
                f"{source}: mode {k} left out of the model: seen at {p['n_seen']} of "
                f"{p['n_recordings']} recordings ({100 * p['presence']:.0f} %), below "
                f"min_presence {min_presence:g}"
            )
    for w in notes:
        warnings.warn(w, ModelQualityWarning, stacklevel=2)
    if not ids:
        raise ValueError(f"{source}: no mode id of directions {directions} seen at >= "
                         f"{min_presence} of the recordings")  # fmt: skip
    ids.sort(key=lambda k: (mode_direction(k), int(k[len(mode_direction(k)) :])))
    use = tracked[tracked["mode_id"].isin(ids)].assign(direction=lambda t: t["mode_id"])
    use = use.assign(flags="")  # per-mode flags are in mode_flags; the fit checks its own
    fit = fit_pose_model_from_table(
        use, inputs, kernel, directions=tuple(ids), mode_switch=False, n_folds=n_folds,
        rng=rng, covariance=covariance,
    )  # fmt: skip
    fit.model.provenance_ = {
        **fit.model.provenance_,
        "multimode": 1,
        "mode_presence": json.dumps(presence),
        "modes_left_out": json.dumps(sorted(set(presence) - set(ids))),
    }
    if notes or fit.warnings:
        fit.model.provenance_["quality_warnings"] = json.dumps([*notes, *fit.warnings])
    return replace(fit, warnings=(*notes, *fit.warnings))


def fit_campaign_table(
    path,
    inputs=("x_mm", "y_mm", "rz_deg"),
    kernel: str = "ard",
    *,
    n_folds: int = 5,
    use_flagged: bool = False,
):
    """The pose model of a campaign table, whichever ``campaign process`` wrote (``model fit``).

    ``modes.csv`` (a ``mode_id`` column) gives every tracked mode
    (:func:`fit_multimode_pose_model`), ``modal.csv`` the dominant mode per direction
    (:func:`~robovib.campaign.fit_pose_model_from_table`).

    Parameters
    ----------
    path : str or pathlib.Path
        The table (read by :func:`robovib.files.csv_table.read_table`).
    inputs : sequence of str
        Pose columns, with their units (``x_mm``, ``rz_deg`` ...).
    kernel : {"ard", "isotropic"}
        The GP length scales (not the covariance family): one per input (ARD) or one shared.
    n_folds : int
        Cross-validation folds (grouped by pose).
    use_flagged : bool
        Keep rows whose fit is flagged (``modal.csv`` only).

    Returns
    -------
    PoseModelFit
        The fitted model with its cross-validation table.
    """
    from ..files.csv_table import read_table
    from .model import fit_pose_model_from_table

    if "mode_id" in read_table(path, what="modal table").header:
        return fit_multimode_pose_model(path, inputs=inputs, kernel=kernel, n_folds=n_folds)
    return fit_pose_model_from_table(path, inputs=inputs, kernel=kernel, n_folds=n_folds,
                                     use_flagged=use_flagged)  # fmt: skip
