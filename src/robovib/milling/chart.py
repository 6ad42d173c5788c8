"""One stability chart from what a user has: explicit modes or measured FRFs, tool, material.

This is the library side of ``robovib mill lobes``: the CLI parses the option strings and reads
the FRF and test-cut files (:mod:`robovib.io`), and passes their values here. The envelope is
computed by the semi-discretization (default) or the zero-order method, and
:func:`plot_lobes_chart` draws it with the operating point and the cuts.

With a measured FRF the semi-discretization needs modes: they are identified from each
direction's driving-point compliance (:func:`robovib.modal.fit_modes`, LSCF + LSFD); the
zero-order method uses the measured FRF directly.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import PurePath

import numpy as np

from ..io.frf_csv import read_frf_csv  # the reader lives in robovib.io
from ..modal.parameters import ModalParameters
from .forces import CuttingCoefficients, CuttingConditions, MillingTool
from .lobes import LobeEnvelope, lobes_title, plot_lobes, zoa_envelope
from .sdm import sdm_lobes
from .stability import stability_lobes

__all__ = [
    "LobesChart",
    "cutting_setup",
    "lobes_chart",
    "plot_lobes_chart",
    "read_frf_csv",
]


def cutting_setup(
    coefficients,
    *,
    diameter_m: float,
    n_flutes: int,
    helix_deg: float,
    radial_depth_m: float | None = None,
    radial_immersion: float | None = None,
    milling: str = "down",
    ktc_n_per_m2: float | None = None,
    krc_n_per_m2: float | None = None,
):
    """Tool, cutting conditions and coefficients of a stability chart (SI).

    Parameters
    ----------
    coefficients : CuttingCoefficients
        Material preset (e.g. :data:`robovib.milling.ALUMINIUM_7075`).
    diameter_m : float
        Tool diameter [m].
    n_flutes : int
        Number of teeth.
    helix_deg : float
        Helix angle [deg] (forces only; the stability methods ignore it).
    radial_depth_m : float, optional
        Radial depth of cut [m]; ignored when ``radial_immersion`` is given.
    radial_immersion : float, optional
        Radial immersion a/D in (0, 1].
    milling : {"down", "up"}
        Milling mode.
    ktc_n_per_m2, krc_n_per_m2 : float, optional
        Tangential / radial cutting coefficients [N/m²] replacing the preset's.

    Returns
    -------
    tool : MillingTool
    conditions : CuttingConditions
        Placeholder speed, feed and axial depth (the chart sweeps them); radial depth and mode set.
    coefficients : CuttingCoefficients

    Raises
    ------
    ValueError
        Unknown milling mode, immersion outside (0, 1], or neither radial input given.
    """
    from dataclasses import replace

    if milling not in ("up", "down"):
        raise ValueError(f"milling must be 'up' or 'down', got {milling!r}")
    tool = MillingTool(diameter_m=diameter_m, n_flutes=n_flutes, helix_deg=helix_deg)
    if radial_immersion is not None:
        if not 0 < radial_immersion <= 1:
            raise ValueError(f"radial immersion is a/D in (0, 1], got {radial_immersion}")
        ae_m = radial_immersion * tool.diameter_m
    elif radial_depth_m is not None:
        ae_m = radial_depth_m
    else:
        raise ValueError("give the radial depth of cut [m] or the radial immersion a/D")
    cond = CuttingConditions(1000.0, 1e-4, 1e-3, ae_m, down_milling=milling == "down")
    if ktc_n_per_m2 is not None:
        coefficients = replace(coefficients, ktc=ktc_n_per_m2)
    if krc_n_per_m2 is not None:
        coefficients = replace(coefficients, krc=krc_n_per_m2)
    return tool, cond, coefficients


@dataclass(frozen=True)
class LobesChart:
    """A stability chart with its inputs (everything the JSON output and the figure need).

    Attributes
    ----------
    envelope
        The stability envelope.
    modes_x, modes_y
        Tool-tip modes along feed and normal.
    tool, conditions, coefficients
        Cutter, cutting conditions and cutting coefficients.
    title
        Chart title.
    cuts
        Measured test cuts (:class:`robovib.io.MeasuredCuts`), if given.
    operating_point, operating_point_stable
        ``(rpm, depth [m])`` and whether it lies below the envelope.
    frf_file
        Label of the measured FRFs the envelope came from (the CLI's file path), if any.
    settings
        Settings of the computation.
    probability
        :class:`~robovib.milling.uncertainty.StabilityProbability`, if computed.
    notes
        Which mode the deterministic envelope assumed where the pose model is unsure.
    operating_point_p_stable
        P(stable) of the operating point from the sampled envelopes, if both are given.
    cut_forecast
        The test cuts' update of the forecast (:class:`~robovib.milling.cut_forecast.
        CutForecast`), with a pose model, samples and cuts.
    """

    envelope: LobeEnvelope
    modes_x: tuple[ModalParameters, ...]
    modes_y: tuple[ModalParameters, ...]
    tool: MillingTool
    conditions: CuttingConditions
    coefficients: CuttingCoefficients
    title: str
    cuts: object | None = None
    operating_point: tuple[float, float] | None = None
    operating_point_stable: bool | None = None
    frf_file: str | None = None
    settings: dict = field(default_factory=dict)
    probability: object | None = None
    #: Which mode the deterministic envelope assumed where the pose model is unsure (mixtures).
    notes: tuple[str, ...] = ()
    #: P(stable) of the operating point from the sampled envelopes (with ``probability``).
    operating_point_p_stable: float | None = None
    #: Test cuts' update of the forecast (:class:`~robovib.milling.cut_forecast.CutForecast`).
    cut_forecast: object | None = None

    @property
    def n_flip_limited(self) -> int:
        """How many of the envelope's speeds are limited by a flip (period-doubling) lobe.

        Returns
        -------
        int
            Speeds whose limiting lobe is of kind ``"flip"``.
        """
        return int(np.sum(np.asarray(self.envelope.kind) == "flip"))

    def to_dict(self) -> dict:
        """JSON document: ``rpm``, ``a_lim_m`` arrays, units in every key, all inputs.

        Returns
        -------
        dict
            The chart as plain JSON types.
        """
        from .. import __version__

        env = self.envelope.to_dict()
        doc = {
            "robovib_version": __version__,
            "method": self.envelope.method,
            "rpm": env["rpm"],
            "a_lim_m": env["a_lim_m"],
            "chatter_hz": env["chatter_hz"],
            "kind": env["kind"],
            "minimum_depth_m": env["minimum_depth_m"],
            "most_stable_rpm": env["most_stable_rpm"],
            "most_stable_depth_m": env["most_stable_depth_m"],
            "modes_x": [m.to_dict() for m in self.modes_x],
            "modes_y": [m.to_dict() for m in self.modes_y],
            "tool": {"diameter_m": self.tool.diameter_m, "n_flutes": int(self.tool.n_flutes),
                     "helix_deg": self.tool.helix_deg},
            "cutting": {"radial_depth_m": self.conditions.radial_depth_m,
                        "milling": "down" if self.conditions.down_milling else "up",
                        "ktc_n_per_m2": self.coefficients.ktc, "krc_n_per_m2": self.coefficients.krc},
            "frf_file": self.frf_file,
            "settings": {**self.envelope.settings, **self.settings},
            "title": self.title,
            "notes": list(self.notes),
        }  # fmt: skip
        if self.operating_point is not None:
            doc["operating_point"] = {
                "rpm": self.operating_point[0],
                "depth_m": self.operating_point[1],
                "stable": self.operating_point_stable,
            }
            if self.operating_point_p_stable is not None:
                doc["operating_point"]["p_stable"] = self.operating_point_p_stable
            if self.operating_point_p_stable is not None and self.cut_forecast is not None:
                before = self.cut_forecast.stability_probability(self.envelope, posterior=False)
                doc["operating_point"]["p_stable_before_cuts"] = before.p_stable_at(
                    *self.operating_point
                )
        if self.cuts is not None:
            doc["cuts"] = self.cuts.to_dict()
        if self.cut_forecast is not None:
            doc["test_cuts"] = self.cut_forecast.to_dict()
        if self.probability is not None:
            p = self.probability
            doc["probability"] = {
                "n_samples": p.settings["n_samples"],
                "a_lim_p05_m": p.depth_quantile_m(0.05),
                "a_lim_p50_m": p.depth_quantile_m(0.5),
                "a_lim_p95_m": p.depth_quantile_m(0.95),
                "sampling": p.settings["sampling"],
                "time_domain_ratio": p.settings.get("time_domain_ratio"),
            }
        return doc


def lobes_chart(
    *,
    tool: MillingTool,
    conditions: CuttingConditions,
    coefficients: CuttingCoefficients,
    spindle_rpm,
    method: str = "sdm",
    modes_x=(),
    modes_y=(),
    frfs: Sequence | None = None,
    frf_label: str | None = None,
    cuts=None,
    operating_point: tuple[float, float] | None = None,
    pose_label: str | None = None,
    material_label: str | None = None,
    steps_per_period: int = 40,
    pose_model=None,
    pose: tuple[float, float, float] | None = None,
    feed_direction: str = "x",
    n_samples: int = 0,
    rng=0,
    time_domain_margin: bool = False,
    progress=None,
    label_noise: float = 0.05,
    local_factor: tuple[float, float] | None = None,
    common_factor: tuple[float, float] = (0.9, 1.1),
) -> LobesChart:
    """Stability envelope from modes or measured FRFs, with cuts and an operating point.

    Parameters
    ----------
    tool, conditions, coefficients
        Tool geometry (diameter, flutes; the helix is ignored by both methods), radial depth and
        up/down milling, cutting coefficients [N/m²].
    spindle_rpm : array_like (n,)
        Speeds [rpm].
    method : {"sdm", "zoa"}
    modes_x, modes_y : sequence of ModalParameters
        Tool-tip modes in the feed and normal directions (ignored with ``frfs``).
    frfs : sequence of robovib.frf.FRF, optional
        Measured tool-tip FRFs (e.g. from :func:`robovib.io.read_frfs`); the first FRF of
        direction x (feed) and of direction y (normal) are used, converted to compliance.
    frf_label : str, optional
        Where ``frfs`` came from (the CLI passes the file path): it begins the FRF errors, is
        echoed as ``frf_file`` in :meth:`LobesChart.to_dict` and its last path component is
        in the title.
    cuts : robovib.io.MeasuredCuts, optional
        Measured test cuts (e.g. from :func:`robovib.io.read_cuts_csv`).
    operating_point : (rpm, depth [m]), optional
        Marked on the chart, with its verdict.
    steps_per_period : int
        Semi-discretization steps per tooth period (``method="sdm"``).
    feed_direction : {"x", "y"}
        Feed direction in the base frame (picks the feed/normal modes of a pose model).
    rng : int or numpy.random.Generator
        Seed of the Monte-Carlo samples.
    pose_label, material_label : str, optional
        For the title.
    pose_model, pose : optional
        Without modes or an FRF file: the pose model and the pose ``(x_mm, y_mm, rz_deg)`` whose
        predicted feed/normal modes are used (``feed_direction`` x or y in the base frame).
    n_samples : int
        With a pose model: Monte-Carlo samples of its predictive distribution for the probability
        of a stable cut (:func:`robovib.milling.uncertainty.stability_probability`); 0 = none.
    time_domain_margin : bool
        With ``n_samples``: scale the sampled envelopes by the time-domain limit / linear limit
        of the mean modes at each speed (a cut entering at full depth; ~1 s per speed).
    progress : callable, optional
        ``progress(done, total)`` while the samples are computed (never printed here).
    label_noise : float
        With a pose model, ``n_samples`` and ``cuts``: the probability that a test cut's
        label is wrong. The cuts then update the forecast (a posterior over the pose model's
        sampled structures, :mod:`robovib.milling.cut_forecast`): P(stable) and the limit
        quantiles come from the weighted structures; cuts without poses are taken at ``pose``.
    local_factor, common_factor
        With ``cuts``: the factor split of the update (:func:`robovib.milling.cut_forecast.
        forecast_with_cuts`), as ``mill plan --cuts``; None: one factor over the whole range.

    Returns
    -------
    LobesChart

    Raises
    ------
    TypeError
        An item of ``frfs`` is not an FRF, or ``cuts`` is not measured cuts.
    ValueError
        No FRF of direction x or y, an FRF zero at every frequency, modes that cannot be
        identified for SDM, or bad settings.
    """
    if method not in ("sdm", "zoa"):
        raise ValueError(f"method must be 'sdm' or 'zoa', got {method!r}")
    from .._checks import check_int

    steps_per_period = check_int("steps_per_period", steps_per_period, lo=2, hi=10_000)
    n_samples = check_int("n_samples", n_samples, lo=0, hi=100_000)
    if time_domain_margin and n_samples == 0:
        raise ValueError("the time-domain margin applies to P(stable): give n_samples > 0")
    if cuts is not None:
        from ..io.cuts import MeasuredCuts

        if not isinstance(cuts, MeasuredCuts):
            raise TypeError(f"cuts must be robovib.io.MeasuredCuts, got {type(cuts).__name__}")
    update_cuts = (cuts is not None and pose_model is not None and n_samples > 0
                   and not tuple(modes_x) and not tuple(modes_y) and frfs is None)  # fmt: skip
    if update_cuts and time_domain_margin:
        raise ValueError(
            "test cuts update the sampled structures, whose process factor already spans the "
            "time-domain margin: give the cuts or the time-domain margin, not both"
        )
    rpm = np.atleast_1d(np.asarray(spindle_rpm, float))
    modes_x, modes_y = tuple(modes_x), tuple(modes_y)
    measured_frfs, frfs = frfs, {}
    if measured_frfs is not None:
        from ..frf import FRF

        where = frf_label if frf_label is not None else "frfs"
        if isinstance(measured_frfs, FRF):
            measured_frfs = (measured_frfs,)
        for frf in measured_frfs:
            if not isinstance(frf, FRF):
                raise TypeError(
                    f"{where}: expected robovib.frf.FRF items, got {type(frf).__name__}"
                )
            if frf.direction in ("x", "y") and frf.direction not in frfs:
                frfs[frf.direction] = frf.to_compliance()
        if not frfs:
            raise ValueError(f"{where}: no FRF with direction x or y")
        for d, f in frfs.items():
            if not np.any(np.abs(f.values) > 0):  # LSCF would end in "SVD did not converge"
                raise ValueError(f"{where}: the {d} FRF is zero at every frequency")
        from ..modal.lscf import fit_modes

        fitted = {}
        for d, f in frfs.items():
            try:
                fitted[d] = tuple(fit_modes(f).modes)
            except ValueError as exc:
                if method == "sdm":  # the user sets no max_order here: say what to do instead
                    raise ValueError(
                        f"{where}: the modes of the {d} FRF cannot be identified for SDM "
                        f"({exc}); --method zoa uses the measured FRF itself"
                    ) from None
                fitted[d] = ()  # the zero-order method uses the measured FRF itself
        modes_x, modes_y = fitted.get("x", ()), fitted.get("y", ())
    probability = None
    notes: tuple[str, ...] = ()
    from_model = not modes_x and not modes_y and not frfs and pose_model is not None
    if from_model:
        from .uncertainty import mode_distribution_at_pose, stability_probability

        if pose is None or len(pose) != 3:
            raise ValueError("a pose (x_mm, y_mm, rz_deg) is needed with a pose model")
        if feed_direction not in ("x", "y"):
            raise ValueError(f"feed_direction must be 'x' or 'y', got {feed_direction!r}")
        normal = "y" if feed_direction == "x" else "x"
        from ..gp.contract import DOMINANT

        if pose_model.kind == DOMINANT:  # one mode per direction (chapter 3, modal.csv)
            dist = mode_distribution_at_pose(pose_model, pose)
            notes = _assumed_mode_notes(pose_model, pose, (feed_direction, normal))
            modes_x, modes_y = (dist[feed_direction].mean,), (dist[normal].mean,)
        else:  # multi-mode model: directions are mode ids x1, x2, ..., y1, ... (issue 29)
            from .uncertainty import mode_distributions_at_pose

            dist = mode_distributions_at_pose(pose_model, pose)
            for d in (feed_direction, normal):
                if d not in dist:
                    raise ValueError(f"the pose model has no mode in direction {d!r}")
            modes_x = tuple(m.mean for m in dist[feed_direction])
            modes_y = tuple(m.mean for m in dist[normal])
            notes = (
                "every modelled mode used: "
                + ", ".join(m.name for d in (feed_direction, normal) for m in dist[d]),
            )
        if int(n_samples) > 0 and not update_cuts:
            probability = stability_probability(
                dist, tool, conditions, coefficients, rpm, n_samples=int(n_samples),
                method=method, feed_direction=feed_direction, rng=rng,
                time_domain_margin=bool(time_domain_margin), progress=progress,
                **({"steps_per_period": steps_per_period} if method == "sdm" else {}),
            )  # fmt: skip
            if time_domain_margin:
                r = np.asarray(probability.settings["time_domain_ratio"])
                notes = (*notes, (
                    "P(stable) includes the time-domain margin: time-domain limit / linear "
                    f"limit of the mean modes {r.min():.3f}-{r.max():.3f} over the speeds "
                    "(a cut entering at full depth)"))  # fmt: skip
    if not modes_x and not modes_y and not frfs:
        raise ValueError("give at least one mode (modes_x, modes_y), FRFs or a pose model")
    if method == "sdm":
        env = sdm_lobes(modes_x, modes_y, tool, conditions, coefficients, rpm,
                        steps_per_period=steps_per_period)  # fmt: skip
    elif frfs:

        def measured(f_hz):
            out = []
            for d in ("x", "y"):
                if d in frfs:
                    out.append(frfs[d].interpolate(f_hz, outside="zero").values)
                else:
                    out.append(np.zeros_like(f_hz, complex))
            return tuple(out)

        band = (
            max(min(g.frequency_hz[0] for g in frfs.values()), 1e-3),
            min(g.frequency_hz[-1] for g in frfs.values()),
        )
        lobes = stability_lobes(modes_x, modes_y, tool, conditions, coefficients, n_lobes=40,
                                frequency_range_hz=band, frf=measured)  # fmt: skip
        env = zoa_envelope(lobes, rpm, settings={"frf": "measured"})
    else:
        lobes = stability_lobes(modes_x, modes_y, tool, conditions, coefficients, n_lobes=40)
        env = zoa_envelope(lobes, rpm, settings={"n_lobes": 40})
    forecast = None
    if update_cuts and from_model:
        from .cut_forecast import cuts_at_pose, forecast_with_cuts

        forecast = forecast_with_cuts(
            pose_model, [pose], rpm, cuts_at_pose(cuts, pose), tool, conditions, coefficients,
            feed_direction=feed_direction, n_samples=n_samples, label_noise=label_noise, rng=rng,
            local_factor=local_factor, common_factor=common_factor,
        )  # fmt: skip
        probability = forecast.stability_probability(env)
        split = "" if forecast.local_factor is None else (
            f"; a local factor log-uniform on {list(forecast.local_factor)} drawn afresh at "
            "every point, the cuts learning the common one")  # fmt: skip
        notes = (*notes, (
            f"P(stable) after {cuts.chatter.size} test cuts: {n_samples} sampled structures "
            f"(zero-order limits, process factor) weighted by the cuts' likelihood{split}"))  # fmt: skip
    op_stable = op_p = None
    if operating_point is not None:
        op_rpm, op_depth = (float(v) for v in operating_point)
        if not (op_rpm > 0 and op_depth > 0):
            raise ValueError(
                f"operating point needs a positive speed [rpm] and depth [m], got {operating_point}"
            )
        if rpm.min() <= op_rpm <= rpm.max():
            op_stable = bool(env.is_stable(op_rpm, op_depth)[0])
            if probability is not None:
                op_p = probability.p_stable_at(op_rpm, op_depth)
        operating_point = (op_rpm, op_depth)
    ae_mm = conditions.radial_depth_m * 1e3
    tool_txt = (f"Ø{tool.diameter_m * 1e3:g} mm, {tool.n_flutes} teeth, ae {ae_mm:g} mm "
                f"{'down' if conditions.down_milling else 'up'}-milling")  # fmt: skip
    frf_txt = (
        "" if not frfs else f", FRF {PurePath(frf_label).name}" if frf_label else ", measured FRF"
    )
    title = lobes_title(pose=pose_label, tool=tool_txt, material=material_label,
                        extra=f"{method.upper()}{frf_txt}")  # fmt: skip
    return LobesChart(env, modes_x, modes_y, tool, conditions, coefficients, title, cuts,
                      operating_point, op_stable, None if not frfs else frf_label,
                      probability=probability, notes=notes,
                      operating_point_p_stable=op_p, cut_forecast=forecast)  # fmt: skip


def _assumed_mode_notes(model, pose, directions) -> tuple[str, ...]:
    """One line per direction whose dominant mode the pose model is unsure of (a mixture):
    the deterministic envelope uses the more probable mode; P(stable) samples both."""
    row = model.modes(np.asarray(pose, float)[None, :])[0]
    out = []
    for d in directions:
        p = row[d].high_mode_probability
        if p is not None and 0.05 < p < 0.95:
            fn = row[d].parameters.natural_frequency_hz
            out.append(
                f"{d}: P(high mode dominant) = {p:.2f}; the envelope assumes the more probable "
                f"mode ({fn:.1f} Hz); --samples draws both modes"
            )
    return tuple(out)


def plot_lobes_chart(chart: LobesChart, ax=None):
    """The chart's envelope, shaded unstable region, best speed, operating point and cuts.

    Parameters
    ----------
    chart : LobesChart
        The chart.
    ax : matplotlib.axes.Axes, optional
        Axes to draw on (default: a new figure).

    Returns
    -------
    matplotlib.figure.Figure
    """
    cuts = chart.cuts
    if chart.cut_forecast is not None and cuts is not None:  # only the cuts at this pose
        from dataclasses import replace

        at = np.all(np.isclose(chart.cut_forecast.cuts.pose_mm_deg,
                               chart.cut_forecast.poses_mm_deg[0]), axis=1)  # fmt: skip
        cuts = replace(cuts, spindle_rpm=cuts.spindle_rpm[at], depth_m=cuts.depth_m[at],
                       chatter=cuts.chatter[at], pose_mm_deg=None)  # fmt: skip
    if chart.probability is not None:
        from .uncertainty import plot_stability_probability

        return plot_stability_probability(chart.probability, ax=ax, title=chart.title,
                                          operating_point=chart.operating_point, cuts=cuts)  # fmt: skip
    return plot_lobes(chart.envelope, ax=ax, operating_point=chart.operating_point,
                      cuts=cuts, title=chart.title)  # fmt: skip
