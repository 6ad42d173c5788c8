"""Stability envelopes (critical depth vs speed) as one value for both methods, and their figures.

A :class:`LobeEnvelope` is what a machinist reads off a lobe chart: at each spindle speed the
axial depth above which the cut chatters (the lower envelope of all lobes). The semi-discretization
(:func:`robovib.milling.sdm.sdm_lobes`) returns one directly; :func:`zoa_envelope` takes the lower
envelope of the zero-order method's branches (:func:`robovib.milling.stability.stability_lobes`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .._numeric import median
from .stability import StabilityLobes

__all__ = [
    "LobeEnvelope",
    "insperger_benchmark",
    "lobes_title",
    "plot_lobes",
    "plot_method_comparison",
    "zoa_envelope",
]


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
        """Speed [rpm] and depth [m] of the highest *interior* maximum of the envelope.

        A maximum at the first or last computed speed only says the lobe continues outside the
        search range, so it is not returned; ``None`` when the envelope has no interior maximum
        (widen the range).

        Returns
        -------
        tuple of float or None
            ``(rpm, depth_m)``, or None.
        """
        a = np.asarray(self.a_lim_m, float)
        a = np.where(np.isfinite(a), a, np.nan)
        if a.size < 3:
            return None
        mid = a[1:-1]
        peak = (mid >= a[:-2]) & (mid >= a[2:]) & ~((mid == a[:-2]) & (mid == a[2:]))
        idx = np.flatnonzero(np.nan_to_num(peak, nan=0)) + 1
        if idx.size == 0:
            return None
        best = idx[np.nanargmax(a[idx])]
        return float(self.spindle_rpm[best]), float(a[best])

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


def lobes_title(
    *,
    pose: str | None = None,
    tool: str | None = None,
    material: str | None = None,
    extra: str | None = None,
) -> str:
    """One- or two-line chart title from the pose, tool and material descriptions.

    Parameters
    ----------
    pose, tool, material, extra : str, optional
        Descriptions (left out when None).

    Returns
    -------
    str
        The title.
    """
    parts = [p for p in (pose, tool, material) if p]
    title = " | ".join(parts) if parts else "stability lobes"
    return title + (f"\n{extra}" if extra else "")


def plot_lobes(
    envelope: LobeEnvelope,
    ax=None,
    *,
    operating_point: tuple[float, float] | None = None,
    cuts=None,
    title: str | None = None,
    depth_max_m: float | None = None,
    probability=None,
):
    """Stability chart: envelope, shaded unstable region, best speed, operating point, cuts.

    Parameters
    ----------
    envelope : LobeEnvelope
    ax : matplotlib Axes, optional
    operating_point : (rpm, depth [m]), optional
        Drawn as a star, green when below the envelope, red above.
    cuts : object with ``spindle_rpm``, ``depth_m`` and boolean ``chatter`` arrays, optional
        Measured test cuts (e.g. :func:`robovib.io.read_cuts_csv`): stable ``o``, chatter ``x``.
    title : str, optional
        E.g. from :func:`lobes_title`.
    depth_max_m : float, optional
        Top of the depth axis [m] (default 3x the minimum critical depth, at least the points).
    probability : StabilityProbability, optional
        Draws the probability of stability as shading instead of the plain unstable fill.

    Returns
    -------
    matplotlib.figure.Figure
    """
    import matplotlib.pyplot as plt

    if ax is None:
        _, ax = plt.subplots(figsize=(8, 4.5))
    rpm = np.asarray(envelope.spindle_rpm, float)
    a_mm = np.asarray(envelope.a_lim_m, float) * 1e3
    finite = np.isfinite(a_mm)
    top = depth_max_m * 1e3 if depth_max_m else None
    if top is None:
        base = np.nanmin(np.where(finite, a_mm, np.nan)) if finite.any() else 1.0
        top = 3.5 * base
        if operating_point is not None:
            top = max(top, 1.2 * operating_point[1] * 1e3)
        if cuts is not None and len(cuts.depth_m):
            top = max(top, 1.15 * float(np.max(cuts.depth_m)) * 1e3)
        best_auto = envelope.most_stable_speed()
        if best_auto is not None and np.isfinite(best_auto[1]):
            top = max(top, 1.1 * best_auto[1] * 1e3)  # the most stable speed's marker stays in view
    drawn = np.where(finite, np.minimum(a_mm, top), top)
    if probability is not None:
        mesh = ax.pcolormesh(
            probability.spindle_rpm,
            probability.depth_m * 1e3,
            probability.p_stable.T,
            cmap="RdYlGn",
            vmin=0,
            vmax=1,
            shading="nearest",
        )
        ax.figure.colorbar(mesh, ax=ax, label="probability of a stable cut [-]")
    else:
        ax.fill_between(rpm, drawn, top, color="C3", alpha=0.18, lw=0, label="unstable (chatter)")
        ax.fill_between(rpm, 0, drawn, color="C2", alpha=0.06, lw=0)
    label = f"stability limit ({envelope.method.upper()})"
    ax.plot(rpm, np.where(finite, a_mm, np.nan), color="k", lw=1.4, label=label)
    flip = np.asarray(envelope.kind) == "flip"
    if np.any(flip):
        ax.plot(rpm, np.where(flip & finite, a_mm, np.nan), color="C4", lw=2.4, label="flip lobes")
    best = envelope.most_stable_speed()
    if best is not None:
        ax.plot(best[0], min(best[1] * 1e3, top), "v", color="C0", ms=9,
                label=f"most stable speed {best[0]:.0f} rpm")  # fmt: skip
    if cuts is not None:
        c_rpm, c_d = np.asarray(cuts.spindle_rpm, float), np.asarray(cuts.depth_m, float) * 1e3
        chat = np.asarray(cuts.chatter, bool)
        ax.plot(c_rpm[~chat], c_d[~chat], "o", mfc="none", color="C2", ms=7, label="cut: stable")
        ax.plot(c_rpm[chat], c_d[chat], "x", color="C3", ms=8, mew=2, label="cut: chatter")
    if operating_point is not None:
        op_rpm, op_d = float(operating_point[0]), float(operating_point[1])
        inside = rpm.min() <= op_rpm <= rpm.max()
        ok = bool(envelope.is_stable(op_rpm, op_d)[0]) if inside else None
        colour = "C2" if ok else ("C3" if ok is False else "0.4")
        state = {True: "stable", False: "chatter", None: "outside the range"}[ok]
        ax.plot(op_rpm, op_d * 1e3, "*", color=colour, ms=15, mec="k",
                label=f"operating point ({state})")  # fmt: skip
    ax.set_xlim(rpm.min(), rpm.max())
    ax.set_ylim(0, top)
    ax.set_xlabel("spindle speed [rpm]")
    ax.set_ylabel("axial depth of cut [mm]")
    ax.set_title(title or "stability lobes", fontsize=10)
    # Outside the axes: a legend inside covers the low-speed lobes.
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0)
    ax.grid(alpha=0.3)
    ax.figure.tight_layout()
    return ax.figure


def plot_method_comparison(envelopes, ax=None, *, title: str | None = None):
    """Several envelopes on one chart (e.g. SDM vs ZOA), flip segments highlighted.

    Parameters
    ----------
    envelopes : sequence of LobeEnvelope
    ax : matplotlib Axes, optional
    title : str, optional

    Returns
    -------
    matplotlib.figure.Figure
    """
    import matplotlib.pyplot as plt

    if ax is None:
        _, ax = plt.subplots(figsize=(8, 4.5))
    tops = []
    styles = {"sdm": dict(color="k", lw=1.5), "zoa": dict(color="C1", lw=1.5, ls="--")}
    for env in envelopes:
        a_mm = np.asarray(env.a_lim_m, float) * 1e3
        style = styles.get(env.method, {})
        ax.plot(env.spindle_rpm, np.where(np.isfinite(a_mm), a_mm, np.nan),
                label=env.method.upper(), **style)  # fmt: skip
        flip = np.asarray(env.kind) == "flip"
        if np.any(flip):
            ax.plot(env.spindle_rpm, np.where(flip, a_mm, np.nan), color="C4", lw=3,
                    label=f"{env.method.upper()} flip lobes (period doubling)")  # fmt: skip
        if np.isfinite(a_mm).any():
            tops.append(np.nanmin(np.where(np.isfinite(a_mm), a_mm, np.nan)))
    if tops:
        ax.set_ylim(0, 6 * min(tops))
    ax.set_xlabel("spindle speed [rpm]")
    ax.set_ylabel("critical axial depth [mm]")
    ax.set_title(title or "stability limit: semi-discretization vs zero-order", fontsize=10)
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    return ax.figure


def insperger_benchmark(spindle_rpm=None, *, steps_per_period: int = 40):
    """SDM and ZOA envelopes of the published 1-DOF down-milling benchmark.

    Insperger, Mann, Stépán & Bayly, *Int. J. Mach. Tools Manuf.* 43 (2003) / Insperger & Stépán
    (2004): 2 teeth, ``K_t = 6e8``, ``K_n = 2e8`` N/m², ``fn = 922`` Hz, ``zeta = 0.011``,
    ``k = 1.34`` MN/m (x, feed direction only), radial immersion a/D = 0.05, down-milling.

    Parameters
    ----------
    spindle_rpm : array_like, optional
        Speeds [rpm] (default 5,000-25,000 rpm, 200 points).
    steps_per_period : int
        SDM steps across the cut.

    Returns
    -------
    (LobeEnvelope, LobeEnvelope)
        Semi-discretization and zero-order envelopes.
    """
    from ..modal.parameters import ModalParameters
    from .forces import CuttingCoefficients, CuttingConditions, MillingTool
    from .sdm import sdm_lobes
    from .stability import stability_lobes

    rpm = np.linspace(5000, 25000, 200) if spindle_rpm is None else np.asarray(spindle_rpm, float)
    mode = ModalParameters(922.0, 1.34e6, 0.011)
    tool = MillingTool(diameter_m=0.02, n_flutes=2, helix_deg=0.0)
    cond = CuttingConditions(10000, 1e-4, 1e-3, 0.05 * 0.02, down_milling=True)
    coef = CuttingCoefficients(ktc=6e8, krc=2e8, kac=0.0)
    sdm = sdm_lobes([mode], [], tool, cond, coef, rpm, steps_per_period=steps_per_period)
    zoa = zoa_envelope(stability_lobes([mode], [], tool, cond, coef, n_lobes=40), rpm,
                       settings={"n_lobes": 40})  # fmt: skip
    return sdm, zoa
