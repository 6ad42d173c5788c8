"""Figures of stability envelopes (critical depth vs speed), and the SDM/ZOA benchmark.

The value itself, :class:`LobeEnvelope` (one for both methods), and :func:`zoa_envelope` live in
:mod:`robovib.milling.envelope`, which the semi-discretization (:mod:`robovib.milling.sdm`)
imports too; they are importable from here as before.
"""

from __future__ import annotations

import numpy as np

from .envelope import LobeEnvelope, zoa_envelope

__all__ = [
    "LobeEnvelope",
    "insperger_benchmark",
    "lobes_title",
    "plot_lobes",
    "plot_method_comparison",
    "zoa_envelope",
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
