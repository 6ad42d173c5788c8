"""Process a hammer campaign: every manifest row -> FRFs -> dominant mode, in a process pool.

For each row (recording x direction): read every response channel
(:func:`robovib.io.read_recording_channels`), keep the channel of the row's direction (the
force must be along it too), average the hits with quality control
(:func:`robovib.frf.impact_frf`, thesis Eq. 3-5), convert to compliance and fit the dominant
mode (:func:`robovib.modal.fit_dominant_mode`, thesis Eq. 17). Cross channels (response along
another axis) are stored as FRFs but never fitted.

Outputs in ``out_dir`` (all written to temporary files and renamed only when every row
succeeded, or with ``skip_bad=True``):

* ``frfs.h5`` — every FRF (robovib-frf format) with its pose, row, file and channel;
  root attributes hold the robovib version and the processing settings;
* ``modal.csv`` — one row per manifest row: the pose columns, ``fn_hz``,
  ``stiffness_n_per_m``, ``damping_ns_per_m``, ``damping_ratio``, their ``*_std_*`` standard
  errors, ``n_hits_used``, ``n_hits_rejected``, ``mean_coherence``, ``flags``;
* ``campaign.json`` — settings, version, per-row reader reports and skipped rows;
* ``modes.csv`` — with ``modes_band_hz``: every tracked mode of every row.

The four names belong to this function: a run removes the ones it does not write (a
``modes.csv`` of an earlier run with ``modes_band_hz``), and refuses, before any work, an output
that is the manifest or one of its recordings (:mod:`robovib.files.safe_write`).
"""

from __future__ import annotations

import json
import os
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import numpy as np

from .manifest import CampaignRow, read_manifest

__all__ = [
    "CampaignResult",
    "ProcessingSettings",
    "campaign_accounting",
    "process_campaign",
    "process_row",
]

_FLAG_BAND_EDGE = "fn at the fit band edge"
#: The files :func:`process_campaign` writes into its output folder (and owns there).
OUTPUT_FILES = ("frfs.h5", "modal.csv", "campaign.json", "modes.csv")


def _default_ranges():
    from ..frf.plausibility import PlausibleRanges

    return PlausibleRanges()


@dataclass(frozen=True)
class ProcessingSettings:
    """How each recording is turned into an FRF and a mode (SI units).

    Attributes
    ----------
    estimator
        ``"H1"`` or ``"H2"``.
    pretrigger_s, force_window_s, exp_window_tau_s
        Impact windows of :func:`robovib.frf.impact_frf` [s] (None: no window).
    f_min_hz, f_max_hz
        Band kept in the compliance FRF [Hz]. The default 5 Hz keeps the accelerometer's
        noise, amplified by 1/(2 pi f)^2 in the compliance, from out-peaking a well damped
        mode (robot modes: 7-65 Hz in the thesis); lower it for slower structures.
    band_hz
        Dominant-mode fit band [Hz]; None: around the peak.
    keep_flagged
        Keep hits flagged for double hits or overload.
    threshold, hold_off_s
        Impact detection in continuous records (fraction of the peak, [s]).
    min_coherence
        Mean coherence in the fit band below this is flagged.
    plausible
        :class:`robovib.frf.PlausibleRanges` of peak force, response and compliance; a level
        outside is an error naming the likely unit mix-up (None: not checked).
    min_fit_bins
        Fewest FRF lines in the dominant-mode fit band; fewer (hits too short for the band)
        is an error naming the resolution.
    modes_band_hz
        Band [Hz] in which *every* mode of each direct FRF is fitted as well (LSCF/LSFD,
        :func:`robovib.campaign.multimode.fit_row_modes`) and tracked across poses into
        ``modes.csv``; None (default): the dominant mode only.
    """

    estimator: str = "H1"
    pretrigger_s: float = 0.01
    force_window_s: float | None = 0.01
    exp_window_tau_s: float | None = None
    f_min_hz: float = 5.0
    f_max_hz: float = 200.0
    band_hz: tuple[float, float] | None = None
    keep_flagged: bool = False
    threshold: float = 0.1
    hold_off_s: float = 0.5
    min_coherence: float = 0.8
    plausible: object = field(default_factory=_default_ranges)
    min_fit_bins: int = 5
    modes_band_hz: tuple[float, float] | None = None

    def __post_init__(self) -> None:
        if self.estimator not in ("H1", "H2"):
            raise ValueError(f"unknown estimator {self.estimator!r}; expected 'H1' or 'H2'")
        if not (0 < self.f_min_hz < self.f_max_hz):
            raise ValueError(
                f"need 0 < f_min_hz < f_max_hz, got {self.f_min_hz} Hz and {self.f_max_hz} Hz"
            )
        for name in ("pretrigger_s", "hold_off_s"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v >= 0):
                raise ValueError(f"{name} must be a finite number >= 0 s, got {v!r}")
        for name in ("force_window_s", "exp_window_tau_s"):
            v = getattr(self, name)
            if v is not None and not (np.isfinite(v) and v > 0):
                raise ValueError(f"{name} must be None or a positive number of seconds, got {v!r}")
        if isinstance(self.plausible, dict):  # from asdict() / JSON
            from ..frf.plausibility import PlausibleRanges

            object.__setattr__(
                self,
                "plausible",
                PlausibleRanges(**{k: tuple(v) for k, v in self.plausible.items()}),
            )
        if self.modes_band_hz is not None:
            lo, hi = (float(v) for v in self.modes_band_hz)
            if not (0 < lo < hi):
                raise ValueError(
                    f"modes_band_hz needs 0 < low < high Hz, got {self.modes_band_hz!r}"
                )
            object.__setattr__(self, "modes_band_hz", (lo, hi))
        if not (isinstance(self.min_fit_bins, int) and self.min_fit_bins >= 3):
            raise ValueError(f"min_fit_bins must be an integer >= 3, got {self.min_fit_bins!r}")


@dataclass(frozen=True)
class RowResult:
    """What one manifest row gave: a modal-table row, its FRFs, and the reader's report."""

    row: int
    modal: dict | None
    frfs: tuple = ()
    report: dict | None = None
    error: str | None = None
    modes: tuple = ()


@dataclass(frozen=True)
class CampaignResult:
    """The processed campaign.

    Attributes
    ----------
    table
        The modal table (a :class:`pandas.DataFrame`, columns as ``modal.csv``).
    n_frfs
        FRFs written to ``frfs.h5``.
    skipped
        ``(manifest line, reason)`` of the rows left out (``skip_bad=True``).
    out_dir
        Where the files were written.
    reports
        Reader report per processed row (dicts).
    accounting
        Every manifest row -> FRFs -> modal row (:func:`campaign_accounting`).
    """

    table: object
    n_frfs: int
    skipped: tuple[tuple[int, str], ...]
    out_dir: Path
    reports: tuple = field(default=(), repr=False)
    accounting: dict = field(default_factory=dict)


def _sens(row: CampaignRow):
    from ..io import Sensitivity

    f = Sensitivity(row.force_sensitivity_mv_per_n, "N") if row.force_sensitivity_mv_per_n else None
    r = (
        Sensitivity(row.response_sensitivity_mv_per_unit, row.response_unit)
        if row.response_sensitivity_mv_per_unit
        else None
    )
    return f, r


def process_row(row: CampaignRow, settings: ProcessingSettings) -> RowResult:
    """FRFs and the dominant mode of one manifest row (errors returned, not raised).

    Parameters
    ----------
    row : CampaignRow
        The manifest row (recording, direction, pose, sensitivities).
    settings : ProcessingSettings
        FRF estimation, hit checks, plausible levels and fit band.

    Returns
    -------
    RowResult
        The row's FRFs and modal row, or ``error`` (why it failed) with ``modal = None``.
    """
    try:
        return _process_row(row, settings)
    except (ValueError, RuntimeError, OSError) as exc:
        return RowResult(row.row, None, error=f"{row.file.name}: {exc}")


def _process_row(row: CampaignRow, s: ProcessingSettings) -> RowResult:
    from ..frf import check_lines_in_band, impact_compliance_frf
    from ..io import read_recording_channels, select_channel
    from ..modal import fit_dominant_mode

    f_sens, r_sens = _sens(row)
    channels = read_recording_channels(
        row.file, f_sens, r_sens, threshold=s.threshold, pretrigger_s=s.pretrigger_s,
        hold_off_s=s.hold_off_s,
    )  # fmt: skip
    direct = select_channel(channels, row.direction, str(row.file))
    pose = row.pose_tuple_si()
    frfs = []
    fitted = None
    for ch in channels:
        is_direct = ch is direct or (ch.direction in (None, row.direction) and len(channels) == 1)
        res = impact_compliance_frf(  # the pipeline of `frf compute` too
            ch.forces, ch.responses, ch.sample_rate_hz, f_min_hz=s.f_min_hz,
            response_quantity=ch.response_quantity, estimator=s.estimator,
            pretrigger_s=s.pretrigger_s, force_window_s=s.force_window_s,
            exp_window_tau_s=s.exp_window_tau_s, reject=not s.keep_flagged,
            f_max_hz=min(s.f_max_hz, ch.sample_rate_hz / 2), pose=pose,
            direction=row.direction if is_direct else ch.direction,
            plausible=s.plausible if is_direct else None,
        )  # fmt: skip
        frf = res.frf
        meta = {
            "row": row.row,
            "file": str(row.file),
            "replicate": row.replicate,
            "reference_direction": row.direction,
            "response_node": -1 if ch.response_node is None else ch.response_node,
            "n_hits_rejected": res.n_rejected,
            "fitted": int(is_direct),
            **{k: v for k, v in row.pose.items()},
        }
        frf = replace(frf, meta={**frf.meta, **meta})
        frfs.append(frf)
        if is_direct:
            fitted = (frf, res)
    frf, res = fitted
    n_fs = direct.forces.shape[1]
    resolution = (
        f"FRF resolution df = {frf.df_hz:.3g} Hz from hits of {n_fs} samples = "
        f"{n_fs / direct.sample_rate_hz:.3g} s"
    )
    try:
        fit = fit_dominant_mode(frf, s.band_hz)
    except ValueError as exc:
        raise ValueError(f"{exc} ({resolution}; longer hits give finer lines)") from None
    p, sd = fit.parameters, fit.std
    lo, hi = fit.band_hz
    band = frf.band(lo, hi)
    df = frf.df_hz
    check_lines_in_band(frf, (lo, hi), hit_samples=n_fs, sample_rate_hz=direct.sample_rate_hz,
                        min_lines=s.min_fit_bins, band_name="fit band")  # fmt: skip
    coh = float(np.mean(band.coherence)) if band.coherence is not None else float("nan")
    flags = []
    width = hi - lo
    if min(p.natural_frequency_hz - lo, hi - p.natural_frequency_hz) < 0.02 * width:
        flags.append(_FLAG_BAND_EDGE)
    if coh < s.min_coherence:
        flags.append(f"mean coherence {coh:.2f} < {s.min_coherence:g}")
    if fit.relative_rms_error > 0.2:
        flags.append(f"relative fit residual {fit.relative_rms_error:.2f}")
    half_power = 2 * p.damping_ratio * p.natural_frequency_hz
    if half_power < df:
        flags.append(
            f"peak not resolved: half-power bandwidth {half_power:.3g} Hz < df {df:.3g} Hz"
        )
    if res.n_rejected:
        reasons = sorted({r for h in res.hits for r in h.reasons})
        flags.append(f"{res.n_rejected} hit(s) rejected: {'; '.join(reasons)}")
    report = direct.report
    if report is not None and report.hits_rejected:
        flags.append(f"reader rejected {len(report.hits_rejected)} hit(s)")
    modal = {
        "row": row.row,
        "file": str(row.file),
        "direction": row.direction,
        **row.pose,
        "replicate": row.replicate,
        "fn_hz": p.natural_frequency_hz,
        "fn_std_hz": sd["natural_frequency_hz"],
        "stiffness_n_per_m": p.stiffness_n_per_m,
        "stiffness_std_n_per_m": sd["stiffness_n_per_m"],
        "damping_ns_per_m": p.damping_ns_per_m,
        "damping_std_ns_per_m": sd["damping_ns_per_m"],
        "damping_ratio": p.damping_ratio,
        "damping_ratio_std": sd["damping_ratio"],
        "n_hits_used": frf.n_averages,
        "n_hits_rejected": res.n_rejected + (len(report.hits_rejected) if report else 0),
        "mean_coherence": coh,
        "fit_band_lo_hz": lo,
        "fit_band_hi_hz": hi,
        "df_hz": df,
        "n_frfs": len(frfs),
        "flags": "; ".join(flags),
    }
    modes = ()
    if s.modes_band_hz is not None:
        from .multimode import fit_row_modes

        keys = {k: modal[k] for k in ("row", "file", "direction", *row.pose, "replicate")}
        try:
            modes = tuple({**keys, **m} for m in fit_row_modes(frf, s.modes_band_hz))
        except ValueError as exc:  # no stable mode: the row keeps its dominant mode
            modal["flags"] = "; ".join(filter(None, [modal["flags"], f"multi-mode fit: {exc}"]))
    return RowResult(row.row, modal, tuple(frfs), report.to_dict() if report else None,
                     modes=modes)  # fmt: skip


def _write_outputs(out_dir: Path, results, settings, manifest: Path, skipped, inputs=()) -> tuple:
    import h5py
    import pandas as pd

    from .. import __version__
    from ..files.h5safe import seal, seal_file
    from ..files.safe_write import remove_stale_outputs
    from ..io import atomic_output, json_dumps, write_frfs_hdf5

    good = [r for r in results if r.modal is not None]
    table = pd.DataFrame([r.modal for r in good])
    modes_table, presence = None, None
    if settings.modes_band_hz is not None:
        from .multimode import track_modes

        pose_columns = [c for c in ("x_mm", "y_mm", "z_mm", "rz_deg") if c in table.columns]
        modes_table = pd.DataFrame([m for r in good for m in r.modes])
        if len(modes_table):
            modes_table, presence = track_modes(modes_table, pose_columns)
    frfs = [f for r in good for f in r.frfs]
    accounting = campaign_accounting(results)
    settings_json = json.dumps(asdict(settings))
    doc = {
        "robovib_version": __version__,
        "manifest": str(manifest),
        "settings": asdict(settings),
        "units": "SI; pose columns as in the manifest (mm, deg)",
        "rows_processed": len(good),
        "accounting": accounting,
        "skipped": [{"line": line, "reason": why} for line, why in skipped],
        "reports": [{"line": r.row, **(r.report or {})} for r in good],
    }
    if presence is not None:
        doc["mode_presence"] = presence
    with (
        atomic_output(out_dir / "frfs.h5", inputs=inputs) as t_h5,
        atomic_output(out_dir / "modal.csv", inputs=inputs) as t_csv,
        atomic_output(out_dir / "campaign.json", inputs=inputs) as t_json,
    ):
        write_frfs_hdf5(t_h5, frfs)
        with h5py.File(t_h5, "a") as h5:
            h5.attrs["settings"] = settings_json
            h5.attrs["manifest"] = str(manifest)
            h5.attrs["units"] = "SI (frequency Hz, compliance m/N); pose (m, m, m, deg, deg, deg)"
            seal(h5)  # the checksum covers the attributes added here
        seal_file(t_h5)
        table.to_csv(t_csv, index=False, float_format="%.9g")
        t_json.write_text(json_dumps(doc, indent=2))  # NaN -> null + reason
    written = [out_dir / n for n in OUTPUT_FILES[:3]]
    if modes_table is not None:
        with atomic_output(out_dir / "modes.csv", inputs=inputs) as t_modes:
            modes_table.to_csv(t_modes, index=False, float_format="%.9g")
        written.append(out_dir / "modes.csv")
    remove_stale_outputs(out_dir, OUTPUT_FILES, written)  # no earlier run's modes.csv left
    return table, len(frfs)


#: Factors between a row's stiffness and its campaign neighbours' that point to a unit mix-up.
_UNIT_FACTORS = (
    (9.80665, "the response in g labelled m/s^2 (or the reverse)"),
    (1e3, "a force in kN labelled N, or a response in mm(/s^2) labelled m(/s^2) (or the reverse)"),
)


def _flag_unit_outliers(results) -> None:
    """Flag rows whose stiffness differs from the median of their direction by a unit factor.

    A robot's stiffness changes with the pose by a few times at most; a row 9.8x or 1000x off
    the others (within 30 %) is far likelier one file exported in other units. Needs >= 3 rows
    of a direction; the flag goes to the row's ``flags``.
    """
    good = [r for r in results if r.modal is not None]
    for d in ("x", "y", "z"):
        rows = [r for r in good if r.modal["direction"] == d]
        if len(rows) < 3:
            continue
        k = np.array([r.modal["stiffness_n_per_m"] for r in rows], float)
        med = float(np.median(k))
        for r, ki in zip(rows, k, strict=True):
            ratio = ki / med
            for factor, words in _UNIT_FACTORS:
                if any(abs(np.log(ratio * f)) < np.log(1.3) for f in (factor, 1 / factor)):
                    flag = (
                        f"stiffness {ratio:.3g}x the median of the {d} rows: likely a unit "
                        f"mix-up ({words})"
                    )
                    r.modal["flags"] = "; ".join(x for x in (r.modal["flags"], flag) if x)


def campaign_accounting(results) -> dict:
    """Where every manifest row went: row -> FRFs (direct, cross) -> modal row, or skipped.

    Parameters
    ----------
    results
        The :class:`RowResult` of every manifest row.

    Returns
    -------
    dict
        ``manifest_rows``, ``rows_processed``, ``rows_skipped`` (lines), ``frfs``,
        ``frfs_direct`` (one per processed row, fitted), ``frfs_cross`` (other response
        channels: stored, never fitted), ``modal_rows`` and ``summary`` (one sentence).
    """
    good = [r for r in results if r.modal is not None]
    n_frfs = sum(len(r.frfs) for r in good)
    n_direct = len(good)
    skipped = [r.row for r in results if r.modal is None]
    summary = (
        f"{len(results)} manifest rows: {len(good)} processed, {len(skipped)} skipped"
        + (f" (lines {', '.join(map(str, skipped))})" if skipped else "")
        + f"; {n_frfs} FRFs = {n_direct} direct (fitted, one modal row each) + "
        f"{n_frfs - n_direct} cross-channel (stored, not fitted); {len(good)} modal rows"
    )
    return {
        "manifest_rows": len(results),
        "rows_processed": len(good),
        "rows_skipped": skipped,
        "frfs": n_frfs,
        "frfs_direct": n_direct,
        "frfs_cross": n_frfs - n_direct,
        "modal_rows": len(good),
        "summary": summary,
    }


def process_campaign(
    manifest: str | Path,
    out_dir: str | Path,
    skip_bad: bool = False,
    n_workers: int | None = None,
    progress: Callable[[int, int], None] | None = None,
    settings: ProcessingSettings | None = None,
) -> CampaignResult:
    """Process every row of a campaign manifest (see the module docstring).

    Parameters
    ----------
    manifest
        Manifest CSV (:mod:`robovib.campaign.manifest`).
    out_dir
        Existing or new folder for ``frfs.h5``, ``modal.csv`` and ``campaign.json``.
    skip_bad
        Leave out rows that fail (reported in ``skipped``) instead of failing the campaign.
    n_workers
        Processes of the pool (None: CPU count; 1: in this process).
    progress
        Called as ``progress(done, total)`` after each row.
    settings
        :class:`ProcessingSettings` (default settings if None).

    Returns
    -------
    CampaignResult

    Raises
    ------
    ValueError
        A bad manifest, or (without ``skip_bad``) any failing row — named by its manifest
        line and reason; nothing is written then.

    Examples
    --------
    >>> import tempfile
    >>> from robovib.campaign import process_campaign
    >>> from robovib.sim import simulate_campaign
    >>> folder = tempfile.mkdtemp()
    >>> manifest = simulate_campaign(folder, rng=0)  # doctest: +SKIP
    >>> result = process_campaign(manifest, folder + "/out")  # doctest: +SKIP
    """
    manifest = Path(manifest)
    out_dir = Path(out_dir)
    settings = settings or ProcessingSettings()
    rows = read_manifest(manifest)
    if n_workers is not None and int(n_workers) < 1:
        raise ValueError(f"n_workers must be >= 1, got {n_workers}")
    if out_dir.exists() and not out_dir.is_dir():
        raise ValueError(f"{out_dir}: exists and is not a folder")
    inputs = [manifest, *(r.file for r in rows)]
    if out_dir.is_dir():  # refuse before any work: an output onto the manifest or a recording
        from ..files.safe_write import check_output_path

        for name in OUTPUT_FILES:
            check_output_path(out_dir / name, inputs=inputs)
    workers = min(int(n_workers or os.cpu_count() or 1), len(rows))
    results: list[RowResult] = []
    total = len(rows)
    if workers == 1:
        for row in rows:
            results.append(process_row(row, settings))
            if progress:
                progress(len(results), total)
    else:
        # A few rows per task: less inter-process traffic, still a smooth progress bar.
        chunk = max(1, total // (4 * workers))
        with ProcessPoolExecutor(max_workers=workers) as pool:
            for res in pool.map(process_row, rows, [settings] * total, chunksize=chunk):
                results.append(res)
                if progress:
                    progress(len(results), total)
    _flag_unit_outliers(results)
    bad = [(r.row, r.error) for r in results if r.error is not None]
    if bad and not skip_bad:
        detail = "; ".join(f"line {line}: {why}" for line, why in bad)
        raise ValueError(f"{manifest}: {len(bad)} of {total} rows failed ({detail})")
    if len(bad) == total:
        detail = "; ".join(f"line {line}: {why}" for line, why in bad)
        raise ValueError(f"{manifest}: every row failed; nothing written ({detail})")
    out_dir.mkdir(parents=True, exist_ok=True)
    table, n_frfs = _write_outputs(out_dir, results, settings, manifest, bad, inputs)
    return CampaignResult(
        table,
        n_frfs,
        tuple(bad),
        out_dir,
        tuple(r.report for r in results if r.report),
        campaign_accounting(results),
    )
