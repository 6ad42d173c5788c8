"""Impact-hammer testing: hit quality control, windows and the averaged FRF (thesis §3.2.1, §5.2.1).

For each hit (one force and one response record, equally sampled):

1. **Trigger**: the first sample where |force| reaches ``trigger_level`` x its peak; the record
   is aligned so that ``pretrigger_s`` of signal precede it (the record must hold that much).
2. **Quality control**, per hit, reported in a :class:`HitReport`:
   *double hit* — outside the main (largest) pulse, before it or after it has decayed below
   the trigger level, the force reaches ``double_hit_level`` x peak; *overload* — a run of ``clip_run`` or more samples
   at the channel's extreme value (a clipped ADC), a flat top carrying noise (many samples
   near the extreme between steep flanks, :func:`overload_reason`), peaks of several hits
   piled up at exactly one value (the range limit, even for one-sample tops), or a given
   full-scale range reached, on the force and on the response channel;
   flagged hits are rejected (default) or only reported (``reject=False``).
3. **Windows**: a *force window* keeps the pulse (``force_window_s`` after the trigger, with a
   short cosine taper) and zeroes the hammer channel's noise elsewhere; an optional
   *exponential window* ``exp(-(t - t_trigger) / tau)`` is applied to **both** channels, which
   leaves the FRF exact but adds ``1/tau`` to every mode's decay rate: the FRF carries
   ``exp_window_tau_s`` so that fitted damping can be corrected
   (:func:`robovib.modal.remove_exponential_window_damping`).
4. **Averaging**: Gxx, Gyy, Gxy of the accepted hits (one rectangular segment per hit, SciPy
   Welch/CSD) are averaged; H1 or H2 and the coherence follow (Eq. 5).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .._checks import check_choice, check_int, check_number
from .core import FRF, RESPONSE_TO_QUANTITY
from .estimate import SpectralDensities, _frf_from_densities, spectral_densities

__all__ = ["HitReport", "ImpactResult", "check_hit", "impact_frf", "noise_level", "overload_reason"]


@dataclass(frozen=True)
class HitReport:
    """Quality of one hit.

    Attributes
    ----------
    index
        Position of the hit in the recording.
    trigger_index
        Sample where |force| first reaches the trigger level.
    peak_force_n
        Peak |force| [N].
    pulse_width_s
        Width of the main force pulse [s].
    accepted
        Whether the hit passed every check.
    reasons
        Why it was flagged (double hit, overload, short pre-trigger).
    """

    index: int
    trigger_index: int
    peak_force_n: float
    pulse_width_s: float
    accepted: bool
    reasons: tuple[str, ...] = ()


@dataclass(frozen=True)
class ImpactResult:
    """The averaged FRF of an impact test and the quality report of every hit.

    Attributes
    ----------
    frf
        The averaged FRF of the accepted hits.
    hits
        One :class:`HitReport` per hit (accepted or not).
    """

    frf: FRF
    hits: tuple[HitReport, ...] = field(default_factory=tuple)

    @property
    def n_rejected(self) -> int:
        return sum(not h.accepted for h in self.hits)


def _longest_run(mask: np.ndarray) -> tuple[int, int]:
    """(start, length) of the longest run of True in ``mask``."""
    edges = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    starts, stops = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    if starts.size == 0:
        return 0, 0
    k = int(np.argmax(stops - starts))
    return int(starts[k]), int(stops[k] - starts[k])


def noise_level(x: np.ndarray) -> float:
    """Robust noise standard deviation of a record, from its second differences.

    Parameters
    ----------
    x
        (n,) record.

    Returns
    -------
    float
        ``1.4826 median|d2 x| / sqrt(6)``: white noise of standard deviation s gives s; a
        smooth signal adds little (its second difference is small).
    """
    d2 = np.diff(np.asarray(x, float), 2)
    return float(1.4826 * np.median(np.abs(d2)) / np.sqrt(6.0)) if d2.size else 0.0


def overload_reason(
    x,
    run: int = 2,
    full_scale: float | None = None,
    *,
    min_plateau: int = 3,
    rel_band: float = 0.01,
    kink: float = 3.0,
    min_fraction: float = 1e-3,
) -> str | None:
    """Why a channel looks clipped (overloaded), or None.

    Three signatures, each on the largest and on the most negative excursion whose extreme is
    at least ``min_fraction`` of the record's peak ``max |x|``. A smaller excursion is noise or
    quantisation beside the signal, not a signal that reached an input range (input ranges are
    symmetric, so the clipped side is the larger one; the fraction leaves 60 dB for an offset).
    Noise a few quantisation steps (or subnormal floating-point steps) deep repeats its extreme
    value by chance, which is no overload. A record whose peak is subnormal is treated as zero.

    1. **Full scale**: ``|x|`` reaches 99.9 % of a given input range.
    2. **Equal samples**: ``run`` or more consecutive samples exactly at the extreme (an ADC
       stuck at its last code; a free peak repeats its top value by chance only).
    3. **Flat top with noise**: ``min_plateau`` or more consecutive samples within a band
       ``tol = max(5 noise deviations, rel_band x extreme)`` of the extreme
       (:func:`noise_level`), whose flanks fall more than ``kink`` times faster than a free
       peak that blunt can: a smooth peak within ``tol`` over ``L`` samples falls about
       ``tol (2 d / L)^2`` at ``d`` samples from its centre; a clipped top is flat between
       steep flanks.

    Parameters
    ----------
    x
        (n,) record.
    run
        Equal samples at the extreme that flag an overload.
    full_scale
        Input range in the record's unit (None: unknown).
    min_plateau, rel_band, kink
        Flat-top test settings (samples, fraction of the extreme, fraction of the band).
    min_fraction
        Smallest extreme, as a fraction of the record's peak, of an excursion that is tested.

    Returns
    -------
    str or None
        The reason (where and how many samples), None when no overload is seen.
    """
    x = np.asarray(x, float)
    peak = float(np.max(np.abs(x))) if x.size else 0.0
    if peak < np.finfo(float).tiny:  # zero or subnormal: no signal at all
        return None
    if full_scale is not None and peak >= 0.999 * full_scale:
        return f"reaches {peak:.4g} of the {full_scale:.4g} full scale"
    sigma = noise_level(x)
    for sign in (1.0, -1.0):
        y = sign * x
        top = float(y.max())
        if top <= 0 or top < min_fraction * peak:
            continue
        i0, n_eq = _longest_run(y >= top * (1 - 1e-12))
        if n_eq >= run:
            return f"{n_eq} equal samples at {sign * top:.6g} (sample {i0})"
        tol = max(5.0 * sigma, rel_band * top)
        if tol > 0.2 * top:
            continue
        # The run near the extreme holding the extreme, up to two stray noisy samples bridged.
        near = y >= top - tol
        bridged = near.copy()
        bridged[1:-1] |= near[:-2] & near[2:]
        bridged[1:-2] |= near[:-3] & near[3:]
        bridged[2:-1] |= near[:-3] & near[3:]
        j = int(np.argmax(y))
        a = j
        while a > 0 and bridged[a - 1]:
            a -= 1
        b = j
        while b < y.size - 1 and bridged[b + 1]:
            b += 1
        length = b - a + 1
        if length < min_plateau:
            continue
        # A free peak that stays within tol for `length` samples is at least that blunt: it
        # falls about tol * (2 d / length)^2 at d samples from its centre. A clipped top
        # falls far faster on both sides.
        m = max(2, length // 2)
        if a - m < 0 or b + 1 + m > y.size:
            continue
        centre = 0.5 * (a + b)
        ratios = []
        for idx in (np.arange(a - m, a), np.arange(b + 1, b + 1 + m)):
            expected = tol * (2.0 * np.abs(idx - centre) / length) ** 2
            ratios.append(float(np.mean(top - y[idx]) / np.mean(expected)))
        if min(ratios) > kink:
            return (
                f"flat top: {length} samples within {tol:.3g} of {sign * top:.6g} "
                f"from sample {a}, its flanks falling {min(ratios):.0f}x faster than a free peak"
            )
    return None


def _clipped(x: np.ndarray, run: int, full_scale: float | None) -> str | None:
    return overload_reason(x, run, full_scale)


def check_hit(
    force,
    response,
    sample_rate_hz: float,
    *,
    index: int = 0,
    trigger_level: float = 0.05,
    double_hit_level: float = 0.1,
    pretrigger_s: float = 0.0,
    clip_run: int = 2,
    force_full_scale: float | None = None,
    response_full_scale: float | None = None,
) -> HitReport:
    """Trigger, pulse width, double-hit and overload checks of one hit (see module docs).

    Parameters
    ----------
    force, response : array_like
        (n,) records of the hit (force [N], response in SI).
    sample_rate_hz : float
        Sample rate [Hz].
    index : int
        Position of the hit, used in messages.
    trigger_level : float
        Trigger at this fraction of the peak |force|.
    double_hit_level : float
        A second pulse reaching this fraction of the peak is a double hit.
    pretrigger_s : float
        Signal the record must hold before the trigger [s].
    clip_run : int
        Equal samples at the extreme that make an overload.
    force_full_scale, response_full_scale : float, optional
        Channel ranges; reaching one is an overload.

    Returns
    -------
    HitReport
        The hit's trigger, pulse width, and whether it is accepted (with the reasons).

    Raises
    ------
    ValueError
        Records of different shape, non-finite values, an all-zero force.
    """
    force = np.asarray(force, float)
    response = np.asarray(response, float)
    if force.ndim != 1 or force.shape != response.shape:
        raise ValueError(
            f"hit {index}: force and response must be 1-D of equal length, got {force.shape} and {response.shape}"
        )
    if not (np.all(np.isfinite(force)) and np.all(np.isfinite(response))):
        raise ValueError(f"hit {index}: force or response contains NaN or inf")
    peak = float(np.max(np.abs(force)))
    if peak == 0:
        raise ValueError(f"hit {index}: the force signal is identically zero (no impact recorded)")
    above = np.abs(force) >= trigger_level * peak
    trigger = int(np.argmax(above))
    reasons = []
    if trigger < round(pretrigger_s * sample_rate_hz):
        reasons.append(
            f"trigger at {trigger / sample_rate_hz:.4g} s leaves less than the {pretrigger_s:g} s pre-trigger"
        )
    # End of the main pulse: first sample after the peak that falls below the trigger level.
    i_peak = int(np.argmax(np.abs(force)))
    below = np.flatnonzero(~above[i_peak:])
    end = i_peak + (int(below[0]) if below.size else force.size - i_peak)
    width = (end - trigger) / sample_rate_hz
    # Start of the main pulse: first sample of the run above the trigger level holding the peak.
    before = np.flatnonzero(~above[:i_peak])
    start = int(before[-1]) + 1 if before.size else 0
    second = double_hit_level * peak
    if start > 0 and np.max(np.abs(force[:start])) >= second:
        t2 = int(np.flatnonzero(np.abs(force[:start]) >= second)[-1]) / sample_rate_hz
        reasons.append(f"double hit: another force pulse at {t2:.4g} s, before the largest one")
    if end < force.size and np.max(np.abs(force[end:])) >= second:
        t2 = (end + int(np.argmax(np.abs(force[end:]) >= second))) / sample_rate_hz
        reasons.append(f"double hit: second force pulse at {t2:.4g} s")
    why = _clipped(force, clip_run, force_full_scale)
    if why:
        reasons.append(f"force channel overload (clipped: {why})")
    why = _clipped(response, clip_run, response_full_scale)
    if why:
        reasons.append(f"response channel overload (clipped: {why})")
    return HitReport(index, trigger, peak, width, not reasons, tuple(reasons))


def _peak_pile_up(reports: list, forces: np.ndarray, responses: np.ndarray) -> list:
    """Hits whose peak |value| equals another hit's exactly hit the input range (an ADC's last
    code): hand-struck peaks never repeat to 1e-9; a clipped one-sample top does. Hits equal
    around the peak too are copies (synthetic data), not clipped."""
    from dataclasses import replace

    out = list(reports)
    for name, x in (("force", forces), ("response", responses)):
        if x.shape[0] < 2:
            continue
        peaks = np.max(np.abs(x), axis=1)
        at = np.argmax(np.abs(x), axis=1)
        around = [np.abs(x[i, max(int(k) - 2, 0) : int(k) + 3]) for i, k in enumerate(at)]

        for i, p in enumerate(peaks):
            # Equal peaks with different neighbours: a limit; equal neighbours too: copied hits
            # (synthetic data), not a clip.
            same = [
                j for j in np.flatnonzero(np.isclose(peaks, p, rtol=1e-9, atol=0.0))
                if j == i or around[j].shape != around[i].shape
                or not np.allclose(around[j], around[i], rtol=1e-9, atol=0.0)
            ]  # fmt: skip
            same = np.asarray(same)
            if p > 0 and same.size >= 2:
                others = ", ".join(str(j) for j in same if j != i)
                why = (
                    f"{name} channel overload (clipped: peak {p:.6g} equals that of hit(s) "
                    f"{others}: the input range)"
                )
                if why not in out[i].reasons:
                    out[i] = replace(out[i], accepted=False, reasons=(*out[i].reasons, why))
    return out


def _force_window(n: int, start: int, stop: int, taper: int) -> np.ndarray:
    w = np.zeros(n)
    w[max(start, 0) : min(stop, n)] = 1.0
    if taper > 0:
        ramp = 0.5 * (1 + np.cos(np.linspace(0, np.pi, taper)))
        seg = w[stop : stop + taper]
        w[stop : stop + taper] = ramp[: seg.size]
    return w


def impact_frf(
    forces,
    responses,
    sample_rate_hz: float,
    *,
    response_quantity: str = "acceleration",
    estimator: str = "H1",
    pretrigger_s: float = 0.01,
    force_window_s: float | None = 0.01,
    exp_window_tau_s: float | None = None,
    trigger_level: float = 0.05,
    double_hit_level: float = 0.1,
    clip_run: int = 2,
    force_full_scale: float | None = None,
    response_full_scale: float | None = None,
    reject: bool = True,
    f_max_hz: float | None = None,
    direction: str | None = None,
    pose: tuple[float, ...] | None = None,
    plausible=None,
) -> ImpactResult:
    """Averaged FRF of several hammer hits with per-hit quality control.

    Parameters
    ----------
    forces, responses
        (n_hits, n_samples) arrays (or a single 1-D hit), force [N] and response in SI units.
    sample_rate_hz
        Common sample rate of both channels.
    response_quantity
        ``"acceleration"`` (accelerometer), ``"velocity"`` or ``"displacement"``.
    estimator
        ``"H1"`` (noise on the response, default) or ``"H2"`` (noise on the force).
    pretrigger_s
        Signal kept before the trigger; each hit is aligned to trigger at this time.
    force_window_s
        Length of the force window after the trigger (None: no force window).
    exp_window_tau_s
        Time constant of the exponential window on both channels (None: no window). The
        added damping is recorded on the FRF, to be removed from fitted modes.
    reject
        Drop flagged hits (default) or keep them and only report.
    trigger_level
        Trigger: first sample where |force| reaches this fraction of the hit's peak, in (0, 1].
    double_hit_level
        A second force pulse above this fraction of the peak flags a double hit, in (0, 1].
    clip_run
        This many equal samples at the extreme of a channel flag an overload; a noisy flat top
        is found too (:func:`overload_reason`).
    force_full_scale, response_full_scale
        Input ranges [N], [response SI unit]; reaching 99.9 % of them flags an overload.
    f_max_hz
        Highest frequency kept [Hz] (must not exceed Nyquist).
    direction
        ``"x"``, ``"y"`` or ``"z"``: stored on the FRF.
    pose
        Tool-tip pose (X, Y, Z [m], Rx, Ry, Rz [deg]) stored on the FRF.
    plausible
        :class:`robovib.frf.PlausibleRanges`: peak force and response levels of the kept hits
        outside them are an error naming the likely unit mix-up (None: not checked).

    Returns
    -------
    ImpactResult
        ``frf`` (H1 or H2 over the kept hits, coherence, ``n_averages``) and ``hits`` (the
        quality report of every hit: trigger, double hit, overload, kept).

    Raises
    ------
    ValueError
        Shapes differ, unknown quantity or estimator, non-positive rate, windows longer than
        the record, ``f_max_hz`` above Nyquist, no hit left after rejection, or (with
        ``plausible``) implausible levels.

    See ``docs/methods.md`` section 1 (FRFs from impact tests, Eq. 3-5).

    Examples
    --------
    >>> from robovib.frf import impact_frf
    >>> from robovib.sim import VirtualRobot, simulate_hammer_test
    >>> rec = simulate_hammer_test(VirtualRobot(), (2.4, 0.0, 45.0), "x", n_hits=3, rng=0)
    >>> res = impact_frf(rec.forces, rec.responses, rec.sample_rate_hz, f_max_hz=200.0)
    >>> res.frf.quantity
    'accelerance'
    """
    forces = np.atleast_2d(np.asarray(forces, float))
    responses = np.atleast_2d(np.asarray(responses, float))
    if forces.shape != responses.shape or forces.ndim != 2:
        raise ValueError(
            f"forces and responses must be (n_hits, n_samples) of equal shape, got {forces.shape} and {responses.shape}"
        )
    if response_quantity not in RESPONSE_TO_QUANTITY:
        raise ValueError(
            f"unknown response quantity {response_quantity!r}; expected one of {list(RESPONSE_TO_QUANTITY)}"
        )
    fs = float(sample_rate_hz)
    if not np.isfinite(fs) or fs <= 0:
        raise ValueError(f"sample_rate_hz must be positive, got {sample_rate_hz!r}")
    n_hits, n = forces.shape
    # Checked at the door: a negative window must not silently mean "none".
    estimator = check_choice("estimator", estimator, ("H1", "H2"), case_insensitive=True)
    record_s = n / fs
    pretrigger_s = check_number(
        "pretrigger_s", pretrigger_s, "s", lo=0.0, hi=record_s, hi_open=True
    )
    if force_window_s is not None:
        force_window_s = check_number(
            "force_window_s", force_window_s, "s", lo=0.0, lo_open=True, hi=record_s
        )
    if exp_window_tau_s is not None:
        exp_window_tau_s = check_number(
            "exp_window_tau_s", exp_window_tau_s, "s", lo=0.0, lo_open=True
        )
    check_number(
        "trigger_level", trigger_level, "(fraction of the peak)", lo=0.0, hi=1.0, lo_open=True
    )
    check_number(
        "double_hit_level", double_hit_level, "(fraction of the peak)", lo=0.0, hi=1.0, lo_open=True
    )
    check_int("clip_run", clip_run, lo=1)
    if f_max_hz is not None:
        f_max_hz = check_number("f_max_hz", f_max_hz, "Hz", lo=0.0, lo_open=True)
    pre = round(pretrigger_s * fs)
    reports = []
    for i in range(n_hits):
        reports.append(check_hit(
            forces[i], responses[i], fs, index=i, trigger_level=trigger_level,
            double_hit_level=double_hit_level, pretrigger_s=pretrigger_s, clip_run=clip_run,
            force_full_scale=force_full_scale, response_full_scale=response_full_scale,
        ))  # fmt: skip
    reports = _peak_pile_up(reports, forces, responses)
    aligned = []
    for i, rep in enumerate(reports):
        if rep.accepted or not reject:
            shift = rep.trigger_index - pre
            f_al = np.zeros(n)
            r_al = np.zeros(n)
            src = slice(max(shift, 0), n)
            dst = slice(max(-shift, 0), max(-shift, 0) + (n - max(shift, 0)))
            f_al[dst], r_al[dst] = forces[i][src], responses[i][src]
            aligned.append((f_al, r_al))
    if not aligned:
        detail = "; ".join(f"hit {r.index}: {', '.join(r.reasons)}" for r in reports)
        raise ValueError(f"all {n_hits} hits were rejected ({detail})")
    if plausible is not None:
        from .plausibility import check_levels

        kept = [i for i, r in enumerate(reports) if r.accepted or not reject]
        bad = check_levels(forces[kept], responses[kept], response_quantity, plausible)
        if bad:
            raise ValueError("implausible levels: " + "; ".join(bad))
    t = np.arange(n) / fs - pretrigger_s
    w_force = np.ones(n)
    if force_window_s is not None:
        taper = max(1, round(0.1 * force_window_s * fs))
        w_force = _force_window(n, 0, pre + round(force_window_s * fs), taper)
    # A pure exponential over the whole record (also before the trigger) keeps
    # w(t) y(t) = ((w h) * (w f))(t) exact, so only the decay rates change.
    w_exp = np.ones(n) if exp_window_tau_s is None else np.exp(-t / exp_window_tau_s)
    gxx = gyy = gxy = 0.0
    freq = None
    for f_al, r_al in aligned:
        sd = spectral_densities(
            f_al * w_force * w_exp, r_al * w_exp, fs, nperseg=n, window="boxcar"
        )
        freq = sd.frequency_hz
        gxx, gyy, gxy = gxx + sd.gxx, gyy + sd.gyy, gxy + sd.gxy
    k = len(aligned)
    averaged = SpectralDensities(freq, gxx / k, gyy / k, gxy / k, k)
    frf = _frf_from_densities(
        averaged, fs, response_quantity, estimator, f_max_hz, direction, pose, "EMA",
        exp_window_tau_s=exp_window_tau_s,
    )  # fmt: skip
    return ImpactResult(frf, tuple(reports))


def impact_compliance_frf(
    forces, responses, sample_rate_hz: float, *, f_min_hz: float, plausible=None, **options
) -> ImpactResult:
    """The compliance FRF of a hammer test, its level checked: what ``frf compute`` and
    campaign processing (:func:`robovib.campaign.process_row`) both run.

    :func:`impact_frf`, then :meth:`FRF.to_compliance` from ``f_min_hz``, then (with
    ``plausible``) :func:`robovib.frf.check_frf_level`.

    Parameters
    ----------
    forces, responses
        (n_hits, n_samples) force [N] and response in SI units (:func:`impact_frf`).
    sample_rate_hz : float
        Common sample rate of both channels [Hz].
    f_min_hz : float
        Lowest frequency kept [Hz] (compliance = accelerance / -w² blows up at 0 Hz).
    plausible : PlausibleRanges, optional
        Check the hits' levels and the compliance peak (None: not checked).
    **options
        Further keywords of :func:`impact_frf` (``response_quantity``, ``estimator``,
        windows, ``reject``, ``f_max_hz``, ``direction``, ``pose`` ...).

    Returns
    -------
    ImpactResult
        ``frf`` the compliance FRF [m/N] from ``f_min_hz``; ``hits`` as :func:`impact_frf`.

    Raises
    ------
    ValueError
        As :func:`impact_frf`; ``"implausible FRF: ..."`` when the compliance level lies
        outside ``plausible`` (the likely unit mix-up named).
    """
    from dataclasses import replace

    res = impact_frf(forces, responses, sample_rate_hz, plausible=plausible, **options)
    frf = res.frf.to_compliance(f_min_hz)
    if plausible is not None:
        from .plausibility import check_frf_level

        bad = check_frf_level(frf, plausible)
        if bad:
            raise ValueError(f"implausible FRF: {bad}")
    return replace(res, frf=frf)
