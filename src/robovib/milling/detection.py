"""Chatter detection from a milling record, window by window (issue 39).

A stable milling cut vibrates at the tooth-passing frequency ``N n / 60`` and its harmonics
(and, with runout, at every spindle harmonic ``k n / 60``); everything else in its spectrum is
noise: the sensor's and the robot's response to the broadband part of the cutting force.
Regenerative chatter adds a narrow line at a frequency that is *not* such a harmonic (near a
mode of the structure). Each window of the record is cut into ``K`` non-overlapping segments;
their Hann-windowed periodograms are averaged (Welch, no overlap, so that each bin of white
Gaussian noise is ``Gamma(K, 1/K)`` times its expected value). The bins within
``harmonic_width_hz`` of a spindle (runout) or tooth-passing harmonic (or of its alias, below)
are masked; the remaining
*off-harmonic* bins are compared with a robust local noise floor (the running median over
``floor_width_hz``, which follows the smooth, coloured noise of a structure driven by broadband
force). A window chatters when

1. **a line is significant**: the largest off-harmonic bin exceeds the floor by the factor
   ``T`` for which pure noise exceeds it in any of the ``M`` off-harmonic bins of a window with
   probability ``false_alarm_rate`` (``1 - (1 - p)^M = alpha``, ``p`` the Gamma tail of one bin,
   divided by the Gamma median the floor estimates), *and*
2. **it is large**: the vibration within ``line_width_hz`` of that line and of its sidebands
   ``f_c + k N n / 60`` (the regenerative chatter's family, off the harmonics) carries at least
   ``min_line_fraction`` of the window's vibration (mean and linear trend removed) and, where
   given, an RMS of at least ``min_line_rms`` (for a displacement: a fraction of the feed;
   with a force reference and ``min_line_rms``, the RMS alone: the share's job, rejecting a
   noise-driven resonance, is condition 3's, and such a resonance dilutes the share). A
   significant but tiny line (a noise-driven resonance of a stable cut, a grazing flute) does not
   mark the surface: the same rule as the time-domain indicator of
   :mod:`robovib.milling.time_domain` (chatter is the vibration that is not tooth-periodic, when
   it is a sizeable part of the motion).

**Flip (period-doubling) chatter** vibrates at ``(m + 1/2)`` times the tooth-passing frequency:
with two flutes these are the odd spindle harmonics, where runout lines are masked. So the
strongest half-tooth line is a second candidate, tested the same way (significance against the
floor, size); a runout that carries half of the vibration and 5 % of the feed would be called
flip chatter (a limitation: runout of that size is a fault of its own).

**Aliased harmonics are not chatter.** A record sampled without an anti-alias filter (a laser
tracker samples position; a simulation holds the cutting force over each step) folds the
harmonics ``h`` between Nyquist and the sampling rate ``fs`` to ``fs - h``: steady periodic
lines that are not harmonics of the spindle in the sampled band, and that drive a nearby mode
hard (``robovib sim mill`` at 1 kHz and 1750 rpm: the 17th tooth harmonic, 991.7 Hz, folds to
8.3 Hz, beside the virtual robot's ~8 Hz Y mode). They are masked like the harmonics
(``aliased=True``), with the same speed-error allowance (0.5 % of ``h``).

**Forced resonance is not chatter.** The broadband (non-periodic) part of the cutting force
drives the structure's modes: a lightly damped mode then stands out of a displacement or
acceleration spectrum as a steady off-harmonic line at the mode's frequency, present from the
first window, that conditions 1 and 2 take for chatter (the virtual robot's ~8 Hz Y mode under
``robovib sim mill``). What tells them apart is the force (the field's force-based detection):
a forced resonance is the structure's FRF times a *smooth* force spectrum, ``X(f) = H(f) F(f)``,
so the force has no line there; regenerative chatter is self-excited, the dynamic chip
thickness ``x(t) - x(t - T)`` modulates the cutting force, and the force carries the same line.
So when the cutting force is recorded (``force=``, the dynamometer of the record), a window
chatters only if also

3. **the force has the line**: the force's periodogram within ``line_width_hz`` of the line
   exceeds its own local floor (running median, as above) by the factor that noise exceeds in
   any of those bins with probability ``false_alarm_rate / c``. With a force, the ``c - 1 =``
   :data:`N_FORCE_CANDIDATES` strongest separate off-harmonic peaks of the response and the
   half-tooth line are the ``c`` candidates (a forced resonance can outgrow a young chatter
   line in a displacement record); the strongest that meets conditions 1-3 is the chatter
   line. A resonance driven by a smooth (white or coloured) force passes condition 3 with
   probability at most ``false_alarm_rate`` per window (Bonferroni over the candidates): the
   stated false-alarm rate on a forced resonance (checked in the tests on a lightly damped
   mode driven by white force). A record without a force channel cannot make
   this check: a chatter label on a steady line at a known mode frequency is then suspect.

The stated false-alarm rate is that of condition 1 on white or smooth coloured Gaussian noise
(checked on synthetic noise in the tests), and of condition 3 on a forced resonance; condition
2 can only lower them. The frequency of the
strongest off-harmonic line is the chatter frequency, so a detected cut goes straight into a
test-cuts file (``result = chatter``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

__all__ = ["ChatterDetection", "detect_chatter", "read_detection_record"]

#: Separate off-harmonic peaks tested against the force (module docs, condition 3).
N_FORCE_CANDIDATES = 5


@dataclass(frozen=True)
class ChatterDetection:
    """Stable / chatter per window of a record.

    Attributes
    ----------
    window_start_s, window_end_s
        (w,) window limits [s] from the first sample.
    chatter
        (w,) chatter found in the window.
    chatter_hz
        (w,) frequency of the strongest off-harmonic line [Hz].
    peak_to_floor
        (w,) that line's power over the local noise floor.
    line_fraction
        (w,) fraction of the window's vibration power in the line's family (module docs).
    line_rms
        (w,) RMS of the signal in the line's family (signal units).
    force_line_to_floor
        (w,) the force's power at the line over its local floor (condition 3; None: no force).
    threshold
        Peak-to-floor factor of the stated false-alarm rate.
    spindle_rpm, n_flutes
        The cut's speed [rpm] and flutes.
    settings
        The detector's settings (false-alarm rate, widths, segments).
    """

    window_start_s: np.ndarray
    window_end_s: np.ndarray
    chatter: np.ndarray
    chatter_hz: np.ndarray
    peak_to_floor: np.ndarray
    line_fraction: np.ndarray
    line_rms: np.ndarray
    threshold: float
    spindle_rpm: float
    n_flutes: int
    settings: dict = field(default_factory=dict)
    force_line_to_floor: np.ndarray | None = None

    @property
    def tooth_passing_hz(self) -> float:
        return self.spindle_rpm * self.n_flutes / 60.0

    @property
    def result(self) -> str:
        """``"chatter"`` when the last window chatters (the settled cut), else ``"stable"``."""
        return "chatter" if bool(self.chatter[-1]) else "stable"

    @property
    def chatter_frequency_hz(self) -> float | None:
        """Chatter frequency [Hz] of the last chattering window (None: stable throughout)."""
        idx = np.flatnonzero(self.chatter)
        return None if idx.size == 0 else float(self.chatter_hz[idx[-1]])

    def to_dict(self) -> dict:
        force = (
            [None] * self.chatter.size
            if self.force_line_to_floor is None
            else [float(v) for v in self.force_line_to_floor]
        )
        return {
            "result": self.result,
            "chatter_frequency_hz": self.chatter_frequency_hz,
            "spindle_rpm": self.spindle_rpm,
            "n_flutes": self.n_flutes,
            "tooth_passing_hz": self.tooth_passing_hz,
            "threshold_peak_to_floor": self.threshold,
            "windows": [
                {"start_s": float(a), "end_s": float(b), "chatter": bool(c),
                 "chatter_hz": float(f), "peak_to_floor": float(r), "line_fraction": float(q),
                 "line_rms": float(a_rms), "force_line_to_floor": fr}
                for a, b, c, f, r, q, a_rms, fr in zip(
                    self.window_start_s, self.window_end_s, self.chatter, self.chatter_hz,
                    self.peak_to_floor, self.line_fraction, self.line_rms, force, strict=True)
            ],
            "settings": dict(self.settings),
        }  # fmt: skip


def peak_threshold(false_alarm_rate: float, n_bins: int, n_segments: int) -> float:
    """Peak-to-median factor exceeded by noise in any of ``n_bins`` bins with that probability.

    Parameters
    ----------
    false_alarm_rate : float
        Probability (per window) that pure noise crosses the threshold.
    n_bins : int
        Off-harmonic bins searched.
    n_segments : int
        Periodograms averaged (a bin is ``Gamma(K, 1/K)`` times its mean).

    Returns
    -------
    float
        The factor, relative to the median of a bin (what the running median estimates).
    """
    from scipy.stats import gamma

    if not 0 < false_alarm_rate < 1:
        raise ValueError(f"false_alarm_rate must be in (0, 1), got {false_alarm_rate!r}")
    k = int(n_segments)
    p_bin = -math.expm1(math.log1p(-false_alarm_rate) / max(int(n_bins), 1))
    return float(gamma.isf(p_bin, k, scale=1.0 / k) / gamma.median(k, scale=1.0 / k))


def _harmonic_mask(
    f: np.ndarray, spindle_hz: float, tooth_hz: float, width: float, runout, fs=None, rel=0.005
):
    """Bins within ``width + rel * harmonic`` of a harmonic; with ``fs``, also of the aliases
    ``fs - k base`` of the harmonics between Nyquist and ``fs`` (sampled without an anti-alias
    filter)."""
    base = spindle_hz if runout else tooth_hz
    mask = np.abs(f - base * np.round(f / base)) <= width + rel * f
    if fs is not None:
        orders = np.arange(np.floor(fs / 2 / base) + 1, np.floor(fs / base) + 1)
        harmonics = orders * base
        harmonics = harmonics[(harmonics > fs / 2) & (harmonics <= fs)]
        for h in harmonics:
            alias = fs - h
            # at a rate that is a multiple of the base, aliases fall on harmonics: nothing new
            if abs(alias - base * round(alias / base)) > width + rel * alias:
                mask |= np.abs(f - alias) <= width + rel * h
    return mask


def detect_chatter(
    signal,
    sample_rate_hz: float,
    spindle_rpm: float,
    n_flutes: int,
    *,
    window_s: float = 2.0,
    n_segments: int = 2,
    false_alarm_rate: float = 1e-3,
    min_line_fraction: float = 0.5,
    min_line_rms: float | None = None,
    harmonic_width_hz: float | None = None,
    line_width_hz: float | None = None,
    floor_width_hz: float = 20.0,
    band_hz: tuple[float, float] | None = None,
    runout: bool = True,
    force=None,
    aliased: bool = True,
) -> ChatterDetection:
    """Label each window of a milling record stable or chatter (module docs).

    Parameters
    ----------
    signal : array_like (n,) or (n, c)
        Force, acceleration or displacement samples; channels (columns) are summed in power
        after each is scaled by its own RMS (so that units do not matter).
    sample_rate_hz : float
        Sampling rate [Hz].
    spindle_rpm : float
        Spindle speed [rpm].
    n_flutes : int
        Teeth of the tool.
    window_s : float
        Window length [s]; the record must hold at least one.
    n_segments : int
        Non-overlapping segments averaged per window (frequency resolution
        ``n_segments / window_s``).
    false_alarm_rate : float
        Per-window probability that noise alone makes a significant line (condition 1).
    min_line_fraction : float
        Share of the window's vibration power that the line must carry (condition 2).
    min_line_rms : float, optional
        And the RMS the line must reach, in signal units (condition 2; e.g. 5 % of the feed
        per tooth for a displacement record: what marks the surface).
    harmonic_width_hz : float, optional
        Half-width of the masked band around each harmonic (default: 2 bins, the Hann main
        lobe); 0.5 % of the harmonic's frequency is added for speed error.
    line_width_hz : float, optional
        Half-width of the band counted as the line (default: 2 bins).
    floor_width_hz : float
        Width of the running median that estimates the noise floor [Hz].
    band_hz : (low, high), optional
        Frequencies searched (default: 2 bins to Nyquist).
    runout : bool
        Mask every spindle harmonic (runout lines), not only the tooth-passing ones.
    force : array_like (n,) or (n, c), optional
        The cutting force on the same samples (a dynamometer): a line is chatter only if the
        force has it too (condition 3, module docs), which tells a forced resonance from
        chatter. Channels are scaled by their RMS and summed in power.
    aliased : bool
        Also mask the aliases ``fs - h`` of the harmonics ``h`` between Nyquist and the
        sampling rate (module docs): a sensor without an anti-alias filter (a laser tracker
        samples position; a simulation holds the force over each step) folds them into the
        band, where they drive the structure like any periodic force.

    Returns
    -------
    ChatterDetection
    """
    from scipy.ndimage import median_filter

    x = np.asarray(signal, float)
    if x.ndim == 1:
        x = x[:, None]
    if x.ndim != 2 or x.shape[0] < 8:
        raise ValueError(f"signal must be (n,) or (n, channels) with n >= 8, got {x.shape}")
    if not np.all(np.isfinite(x)):
        raise ValueError("signal contains NaN or inf samples")
    for name, v in (("sample_rate_hz", sample_rate_hz), ("spindle_rpm", spindle_rpm),
                    ("window_s", window_s), ("floor_width_hz", floor_width_hz)):  # fmt: skip
        if not (np.isfinite(v) and v > 0):
            raise ValueError(f"{name} must be a positive number, got {v!r}")
    if int(n_flutes) < 1 or int(n_segments) < 1:
        raise ValueError("n_flutes and n_segments must be >= 1")
    if not 0 < min_line_fraction < 1:
        raise ValueError(f"min_line_fraction must be in (0, 1), got {min_line_fraction!r}")
    frc = None
    if force is not None:
        frc = np.asarray(force, float)
        frc = frc[:, None] if frc.ndim == 1 else frc
        if frc.ndim != 2 or frc.shape[0] != x.shape[0]:
            raise ValueError(
                f"force must be (n,) or (n, channels) with the signal's {x.shape[0]} samples, "
                f"got {np.shape(force)}"
            )
        if not np.all(np.isfinite(frc)):
            raise ValueError("force contains NaN or inf samples")
        frc = frc[:, np.ptp(frc, axis=0) > 0]
        if frc.shape[1] == 0:
            raise ValueError("force: every channel is constant")
    fs = float(sample_rate_hz)
    n_win = round(window_s * fs)
    k = int(n_segments)
    n_seg = n_win // k
    if n_seg < 8:
        raise ValueError(f"window_s {window_s:g} s gives {n_seg} samples per segment (< 8)")
    n_windows = x.shape[0] // n_win
    if n_windows < 1:
        raise ValueError(
            f"the record ({x.shape[0] / fs:.3g} s) is shorter than one window ({window_s:g} s)"
        )
    spindle_hz = spindle_rpm / 60.0
    tooth_hz = spindle_hz * int(n_flutes)
    f = np.fft.rfftfreq(n_seg, 1.0 / fs)
    df = f[1]
    lo, hi = band_hz if band_hz is not None else (2 * df, fs / 2)
    if not 0 <= lo < hi:
        raise ValueError(f"band_hz must be 0 <= low < high, got {band_hz}")
    hw = 2 * df if harmonic_width_hz is None else float(harmonic_width_hz)
    lw = 2 * df if line_width_hz is None else float(line_width_hz)
    harmonic = _harmonic_mask(f, spindle_hz, tooth_hz, hw, runout, fs if aliased else None)
    searched = (~harmonic) & (f >= lo) & (f <= hi)
    if searched.sum() < 3:
        raise ValueError("no off-harmonic frequencies to search: lower window_s/n_segments")
    half = tooth_hz * (np.round(f / tooth_hz - 0.5) + 0.5)
    flip_bins = (np.abs(f - half) <= lw) & (f >= lo) & (f <= hi)
    n_side = int(np.ceil(f[-1] / tooth_hz))
    thr = peak_threshold(false_alarm_rate, int((searched | flip_bins).sum()), k)
    half_floor = max(round(floor_width_hz / df / 2), 8)
    taper = np.hanning(n_seg)
    t_seg = np.arange(n_seg)
    out = {key: np.empty(n_windows) for key in ("hz", "ratio", "frac", "rms", "force")}
    chatter = np.zeros(n_windows, bool)
    # periodogram bins -> mean square of the signal (one-sided, Hann taper)
    to_ms = 2.0 / (n_seg * np.sum(taper**2))

    def periodogram(samples: np.ndarray, w: int, scaled: bool) -> np.ndarray:
        seg = samples[w * n_win : w * n_win + k * n_seg].reshape(k, n_seg, -1)
        # mean and linear trend of each segment out (quasi-static deflection along the path)
        coef = np.polynomial.polynomial.polyfit(t_seg, seg.transpose(1, 0, 2).reshape(n_seg, -1), 1)
        trend = (coef[0][None, :] + coef[1][None, :] * t_seg[:, None]).reshape(n_seg, k, -1)
        seg = seg - trend.transpose(1, 0, 2)
        if scaled:
            seg = seg / np.maximum(seg.std(axis=(0, 1), keepdims=True), 1e-300)
        return np.mean(
            np.sum(np.abs(np.fft.rfft(seg * taper[None, :, None], axis=1)) ** 2, axis=2), axis=0
        )

    def local_floor(psd: np.ndarray) -> np.ndarray:
        # running median of the off-harmonic bins (harmonics replaced by neighbours)
        off = np.where(searched, psd, np.nan)
        idx = np.flatnonzero(~np.isnan(off))
        filled = np.interp(np.arange(f.size), idx, off[idx])
        return median_filter(filled, size=2 * half_floor + 1, mode="nearest")

    thr_force = None
    for w in range(n_windows):
        psd = periodogram(x, w, False)
        total = psd[1:].sum()
        floor = local_floor(psd)
        ratio = psd / np.maximum(floor, 1e-300)
        # candidates: the strongest off-harmonic lines (Hopf chatter, with its sidebands
        # f_c + k f_tooth; with a force reference the N_FORCE_CANDIDATES strongest separate
        # peaks, since a forced resonance can outgrow a young chatter line in the response)
        # and the strongest half-tooth line (flip chatter at (m + 1/2) f_tooth, which a
        # 2-flute tool's runout mask would hide)
        hopf = np.where(searched, psd, -1.0)
        cands = []
        for _ in range(1 if frc is None else N_FORCE_CANDIDATES):
            j = int(np.argmax(hopf))
            if hopf[j] <= 0:
                break
            fam_f = np.abs(f[j] + tooth_hz * np.arange(-n_side, n_side + 1))
            family = (np.abs(f[:, None] - fam_f[None, :]) <= lw).any(axis=1) & ~harmonic
            cands.append((j, family))
            hopf[np.abs(f - f[j]) <= 2 * lw] = -1.0
        cands.append((int(np.argmax(np.where(flip_bins, psd, -1.0))), flip_bins))
        fpsd = fpsd_floor = None
        if frc is not None:
            fpsd = periodogram(frc, w, True)
            fpsd_floor = np.maximum(local_floor(fpsd), 1e-300)
        evaluated = []
        for j, family in cands:
            power = psd[family].sum()
            frac = float(power / max(total, 1e-300))
            rms = float(np.sqrt(power * to_ms))
            if fpsd is not None and min_line_rms is not None:
                # the share guards against noise-driven resonances, which condition 3 rejects
                # (and which dilute the share of a young chatter line): the RMS decides
                large = rms >= min_line_rms
            else:
                large = frac >= min_line_fraction and (min_line_rms is None or rms >= min_line_rms)
            f_ratio, forced_too = np.nan, True
            if fpsd is not None:
                # condition 3: the force has the line (chatter), not a smooth spectrum
                # (resonance); the false-alarm rate shared among the candidates tested
                near = np.abs(f - f[j]) <= lw
                f_ratio = float(np.max(fpsd[near] / fpsd_floor[near]))
                thr_force = peak_threshold(false_alarm_rate / len(cands), int(near.sum()), k)
                forced_too = f_ratio > thr_force
            passes = bool(ratio[j] > thr and large and forced_too)
            evaluated.append((passes, power, j, frac, rms, f_ratio))
        # the strongest chattering candidate, else the strongest candidate
        passes, _, j, frac, rms, f_ratio = max(evaluated, key=lambda e: (e[0], e[1]))
        out["hz"][w], out["ratio"][w], out["frac"][w], out["rms"][w] = f[j], ratio[j], frac, rms
        out["force"][w] = f_ratio
        chatter[w] = passes
    starts = np.arange(n_windows) * n_win / fs
    return ChatterDetection(
        starts, starts + n_win / fs, chatter, out["hz"], out["ratio"], out["frac"], out["rms"], thr,
        float(spindle_rpm), int(n_flutes),
        {"false_alarm_rate": float(false_alarm_rate), "min_line_fraction": float(min_line_fraction),
         "min_line_rms": None if min_line_rms is None else float(min_line_rms),
         "window_s": n_win / fs, "n_segments": k, "resolution_hz": float(df),
         "harmonic_width_hz": hw, "line_width_hz": lw, "floor_width_hz": float(floor_width_hz),
         "runout_lines_masked": bool(runout), "channels": int(x.shape[1]),
         "band_hz": [float(lo), float(hi)], "off_harmonic_bins": int(searched.sum()),
         "force_reference": frc is not None,
         "force_threshold": None if thr_force is None else float(thr_force)},
        None if frc is None else out["force"],
    )  # fmt: skip


_QUANTITY_PREFIX = ("displacement_", "force_", "acceleration_", "velocity_")


def read_detection_record(path, channel: str | None = None) -> tuple[np.ndarray, float, list[str]]:
    """Samples and rate of a milling record CSV for :func:`detect_chatter`.

    Parameters
    ----------
    path : str or pathlib.Path
        CSV with ``time_s`` and response columns ``<quantity>_<dir>_<unit>`` (``robovib sim
        mill`` output, a force-sensor, accelerometer or laser-tracker log).
    channel : str, optional
        A column name, or a quantity (``displacement``, ``force``, ``acceleration``,
        ``velocity``) whose every column is used; default: displacement, else acceleration,
        else force.

    Returns
    -------
    signal : numpy.ndarray
        (n, c) samples.
    sample_rate_hz : float
        From the time column.
    columns : list of str
        The columns used.
    """
    from ..files.csv_table import read_table
    from ..io.recording import sample_rate_from_time

    table = read_table(path, what="milling record")
    header = list(table.header)
    if "time_s" not in header:
        raise ValueError(f"{path}: no time_s column in {header}")
    if channel is None:
        for q in ("displacement", "acceleration", "velocity", "force"):
            cols = [h for h in header if h.startswith(q + "_")]
            if cols:
                break
        else:
            raise ValueError(f"{path}: no displacement/acceleration/velocity/force column")
    elif channel in header:
        cols = [channel]
    else:
        cols = [h for h in header if h.startswith(channel + "_")]
        if channel + "_" not in _QUANTITY_PREFIX or not cols:
            raise ValueError(f"{path}: no column {channel!r} (columns: {header})")
    data = table.matrix([*cols, "time_s"])
    time_s = data[:, -1]
    fs = sample_rate_from_time(time_s, 1e-6, str(path))
    signal = data[:, :-1]
    # a column that never changes (e.g. a Z channel of a planar cut) carries nothing
    keep = np.ptp(signal, axis=0) > 0
    if not np.any(keep):
        raise ValueError(f"{path}: the columns {cols} are constant")
    return signal[:, keep], fs, [c for c, k in zip(cols, keep, strict=True) if k]
