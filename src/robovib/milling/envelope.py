"""The value both stability methods return: critical depth vs speed (:class:`LobeEnvelope`).

A :class:`LobeEnvelope` is what a machinist reads off a lobe chart: at each spindle speed the
axial depth above which the cut chatters (the lower envelope of all lobes). The semi-discretization
(:func:`robovib.milling.sdm.sdm_lobes`) returns one directly; :func:`zoa_envelope` takes the lower
envelope of the zero-order method's branches (:func:`robovib.milling.stability.stability_lobes`).
Their figures are in :mod:`robovib.milling.lobes`, which imports both methods; this module imports
neither figure nor method, so both import it without a circle.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .._numeric import median
from .stability import StabilityLobes

__all__ = ["SPEED_MARGIN", "LobeEnvelope", "zoa_envelope"]

#: Relative speed margin of :meth:`LobeEnvelope.most_stable_speed`: the spindle holds its speed
#: to about ±1 % and a 1-2 % error in the predicted natural frequency moves a lobe as much.
SPEED_MARGIN = 0.02


@dataclass(frozen=True)
class LobeEnvelope:
    """Critical axial depth [m] at each spindle speed [rpm] (``inf``: stable over the search).

    ``kind`` per speed: ``hopf`` (chatter near a mode, lobes of both methods), ``flip`` (period
    doubling, chatter at odd multiples of half the tooth-passing frequency), ``fold``, ``none``.

    Attributes
    ----------
    spindle_rpm
        (n,) speeds [rpm].
    a_lim_m
        (n,) critical axial depth [m].
    chatter_hz
        (n,) chatter frequency at the limit [Hz].
    kind
        (n,) bifurcation kind.
    method
        ``"sdm"`` or ``"zoa"``.
    settings
        Settings of the computation.
    """

    spindle_rpm: np.ndarray
    a_lim_m: np.ndarray
    chatter_hz: np.ndarray
    kind: np.ndarray
    method: str
    settings: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        n = np.shape(self.spindle_rpm)
        for name in ("a_lim_m", "chatter_hz", "kind"):
            if np.shape(getattr(self, name)) != n:
                raise ValueError(
                    f"{name} has shape {np.shape(getattr(self, name))}, spindle_rpm has {n}"
                )

    def critical_depth(self, spindle_rpm) -> np.ndarray:
        """Critical depth [m] at other speeds [rpm] by linear interpolation (inside the range).

        Parameters
        ----------
        spindle_rpm : array_like
            Speeds [rpm].

        Returns
        -------
        numpy.ndarray
            Critical depths [m].
        """
        s = np.atleast_1d(np.asarray(spindle_rpm, float))
        rpm = np.asarray(self.spindle_rpm, float)
        if np.any(s < rpm.min()) or np.any(s > rpm.max()):
            raise ValueError(
                f"speeds must lie in the computed range {rpm.min():g}-{rpm.max():g} rpm"
            )
        a = np.asarray(self.a_lim_m, float)
        finite = np.isfinite(a)
        cap = np.where(
            finite, a, np.nanmax(np.where(finite, a, np.nan)) * 1e6 if finite.any() else 1
        )
        return np.interp(s, rpm, cap)

    def is_stable(self, spindle_rpm, depth_m) -> np.ndarray:
        """True where the depth [m] lies below the envelope at the speed [rpm].

        Parameters
        ----------
        spindle_rpm, depth_m : array_like
            Speeds [rpm] and depths [m] (broadcast).

        Returns
        -------
        numpy.ndarray
            bool.
        """
        return np.asarray(depth_m, float) < self.critical_depth(spindle_rpm)

    @property
    def minimum_depth_m(self) -> float:
        """Depth [m] stable at every computed speed."""
        return float(np.min(self.a_lim_m))

    def most_stable_speed(self) -> tuple[float, float] | None:
        """Speed [rpm] with the deepest cut that stays stable a little either side of it.

        A lobe peak one speed wide is no place to cut: the spindle drifts and the lobes move
        with the predicted natural frequency by a few %. So each interior speed ``n`` is rated
        by the depth stable over ``n (1 ± SPEED_MARGIN)`` and its neighbouring speeds on the
        grid (margin on both sides), and the highest interior maximum of that rating is
        returned with the rated depth. A maximum at the edge of the computed range only says
        the lobe continues outside it, so it is not returned; ``None`` when there is no
        interior maximum (widen the range).

        Returns
        -------
        tuple of float or None
            ``(rpm, depth_m)``: the speed and the depth stable within ±``SPEED_MARGIN`` of it
            (and at its grid neighbours), or None.
        """
        a = np.asarray(self.a_lim_m, float)
        a = np.where(np.isfinite(a), a, np.nan)
        rpm = np.asarray(self.spindle_rpm, float)
        if a.size < 3:
            return None
        rated = np.full(a.size, np.nan)
        for i in range(1, a.size - 1):
            lo, hi = rpm[i] * (1 - SPEED_MARGIN), rpm[i] * (1 + SPEED_MARGIN)
            near = a[max(i - 1, 0) : i + 2]
            inside = a[(rpm >= lo) & (rpm <= hi)]
            ends = np.interp([max(lo, rpm[0]), min(hi, rpm[-1])], rpm, a)
            rated[i] = np.min(np.concatenate([near, inside, ends]))
        rated[[0, -1]] = a[[0, -1]]  # the range's edges: a rise towards them is no maximum
        mid, left, right = rated[1:-1], rated[:-2], rated[2:]
        peak = (mid >= left) & (mid >= right) & ~((mid == left) & (mid == right))
        idx = np.flatnonzero(np.nan_to_num(peak, nan=0)) + 1
        if idx.size == 0:
            return None
        best = idx[np.nanargmax(rated[idx])]
        return float(rpm[best]), float(rated[best])

    def to_dict(self) -> dict:
        """JSON-ready arrays with units in the keys (``inf`` as ``None``).

        Returns
        -------
        dict
            The envelope as plain JSON types.
        """

        def clean(v):
            return [None if not np.isfinite(x) else float(x) for x in np.asarray(v, float)]

        best = self.most_stable_speed()
        return {
            "method": self.method,
            "rpm": [float(x) for x in self.spindle_rpm],
            "a_lim_m": clean(self.a_lim_m),
            "chatter_hz": clean(self.chatter_hz),
            "kind": [str(k) for k in self.kind],
            "minimum_depth_m": self.minimum_depth_m if np.isfinite(self.minimum_depth_m) else None,
            "most_stable_rpm": None if best is None else best[0],
            "most_stable_depth_m": None if best is None else best[1],
            "settings": dict(self.settings),
        }


def zoa_envelope(
    lobes: StabilityLobes, spindle_rpm, *, settings: dict | None = None
) -> LobeEnvelope:
    """Lower envelope of zero-order lobes on a speed grid [rpm] (chatter frequency of the lobe).

    Parameters
    ----------
    lobes : StabilityLobes
        The lobes.
    spindle_rpm : array_like
        Speed grid [rpm].
    settings : dict, optional
        Settings stored with the envelope.

    Returns
    -------
    LobeEnvelope
        The envelope (method ``"zoa"``).
    """
    s = np.atleast_1d(np.asarray(spindle_rpm, float))
    depth = np.full(s.shape, np.inf)
    freq = np.full(s.shape, np.nan)
    branch_f = lobes.branch_chatter_hz or [None] * len(lobes.depth_m)
    for rpm_b, d_b, fb_b in zip(lobes.spindle_rpm, lobes.depth_m, branch_f, strict=True):
        for piece in _monotone_pieces(rpm_b, fb_b):
            if piece.size < 2:
                continue
            rpm, d = rpm_b[piece], d_b[piece]
            order = np.argsort(rpm)
            r, dd = rpm[order], d[order]
            inside = (s >= r[0]) & (s <= r[-1])
            val = np.interp(s[inside], r, dd)
            better = val < depth[inside]
            idx = np.flatnonzero(inside)[better]
            depth[idx] = val[better]
            if fb_b is not None:
                freq[idx] = np.interp(s[idx], r, np.asarray(fb_b)[piece][order])
    kind = np.where(np.isfinite(depth), "hopf", "none")
    return LobeEnvelope(s, depth, freq, kind, "zoa", dict(settings or {}))


def _monotone_pieces(rpm, chatter_hz) -> list[np.ndarray]:
    """Index runs of one lobe branch along which the speed is monotone and the scan contiguous.

    With several modes a branch's speed turns back as the chatter frequency passes between
    modes, and the scan skips frequencies where no lobe exists; interpolating the whole branch
    over speed would join unrelated pieces (a depth far above the true lobe).
    """
    n = np.asarray(rpm).size
    if n < 3:
        return [np.arange(n)]
    direction = np.sign(np.diff(rpm))
    turns = set((np.flatnonzero(direction[1:] * direction[:-1] < 0) + 1).tolist())
    gaps: set[int] = set()
    if chatter_hz is not None:
        step = np.diff(np.asarray(chatter_hz, float))
        typical = median(np.abs(step))
        if typical > 0:
            gaps = set((np.flatnonzero(np.abs(step) > 1.5 * typical) + 1).tolist())
    pieces = np.split(np.arange(n), sorted(turns | gaps))
    # A turning point belongs to both pieces it joins (no speed left uncovered between them).
    return [
        np.append(p, nxt[0]) if nxt[0] in turns and nxt[0] not in gaps else p
        for p, nxt in zip(pieces, [*pieces[1:], np.array([-1])], strict=True)
    ]
