"""Options shared by the ``robovib mill`` commands (units in every help text)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import numpy as np
import typer

XOpt = Annotated[float, typer.Option("--x", help="Tool-tip X [mm].")]
YOpt = Annotated[float, typer.Option("--y", help="Tool-tip Y [mm].")]
RzOpt = Annotated[float, typer.Option("--rz", help="Rotation about the tool axis [deg].")]
OptionalRzOpt = Annotated[
    float | None, typer.Option("--rz", help="Rotation about the tool axis [deg].")
]
RpmRangeOpt = Annotated[str, typer.Option("--rpm-range", help="Speeds MIN:MAX:N [rpm].")]
RpmOpt = Annotated[float, typer.Option(help="Spindle speed [rpm].")]
FzOpt = Annotated[float, typer.Option("--fz", help="Feed per tooth [mm].")]
ApOpt = Annotated[float, typer.Option("--ap", help="Axial depth of cut [mm].")]
AeOpt = Annotated[
    float,
    typer.Option("--ae", help="Radial depth of cut [mm] (25.4 = slotting with the 25.4 mm tool)."),
]
MaterialOpt = Annotated[
    str, typer.Option("--material", help="Cutting-coefficient preset: al7075 or acetal.")
]
FeedOpt = Annotated[str, typer.Option(help="Feed direction in the base frame: x or y.")]
TeethOpt = Annotated[int, typer.Option("--teeth", help="Number of teeth (flutes) of the tool.")]
DiameterOpt = Annotated[float, typer.Option("--diameter", help="Tool diameter [mm].")]
HelixOpt = Annotated[
    float,
    typer.Option("--helix", help="Helix angle [deg] (forces; the stability methods ignore it)."),
]
KtOpt = Annotated[
    float | None,
    typer.Option("--kt", help="Tangential cutting coefficient [N/m²] (overrides --material)."),
]
KnOpt = Annotated[
    float | None,
    typer.Option("--kn", help="Radial (normal) cutting coefficient [N/m²] (overrides --material)."),
]
RadialOpt = Annotated[
    float | None,
    typer.Option("--radial-immersion", help="Radial immersion a/D [-] (instead of --ae)."),
]
MillingOpt = Annotated[str, typer.Option("--milling", help="up or down milling.")]
StepsOpt = Annotated[
    int,
    typer.Option("--steps", help="SDM steps across the cut (40; 20 is ~4x faster, <1 % change)."),
]
MethodOpt = Annotated[
    str,
    typer.Option("--method", help="sdm (semi-discretization, flip lobes) or zoa (zero-order)."),
]


def cutting(coefficients, kt, kn, diameter, teeth, helix, ae, radial_immersion, milling):
    """Tool, conditions and coefficients from the shared options (mm -> SI at the edge)."""
    from ..files.units import to_si
    from ..milling.chart import cutting_setup

    return cutting_setup(coefficients, diameter_m=to_si(diameter, "mm"), n_flutes=teeth,
                         helix_deg=helix, radial_depth_m=to_si(ae, "mm"), radial_immersion=radial_immersion,
                         milling=milling, ktc_n_per_m2=kt, krc_n_per_m2=kn)  # fmt: skip


ModeSpecOpt = Annotated[
    list[str] | None,
    typer.Option(
        "--mode", help="Explicit mode DIR:FN_HZ,K_N_PER_M,ZETA (repeat; DIR x=feed, y=normal)."
    ),
]
FrfFileOpt = Annotated[
    Path | None,
    typer.Option(
        "--frf",
        help="Measured tool-tip FRFs: .h5, .uff or .csv (frequency_hz, x_real_<unit>, ...).",
    ),
]
CutsOpt = Annotated[
    Path | None,
    typer.Option("--cuts", help="Test cuts CSV: spindle_rpm,depth_mm,result (stable/chatter)."),
]
OperatingPointOpt = Annotated[
    str | None,
    typer.Option("--operating-point", help="RPM,DEPTH_MM drawn on the chart and checked."),
]
LobeSamplesOpt = Annotated[
    int,
    typer.Option(help="Pose model only: samples of its predictive distribution (shaded lobes)."),
]
TimeDomainMarginOpt = Annotated[
    bool,
    typer.Option(
        "--time-domain-margin",
        help="With --samples: scale P(stable) by the simulated time-domain limit (a cut "
        "entering at full depth chatters up to 15 % below, and with several modes up to 45 % "
        "above, linear theory; ~1.3 s of CPU for 200 speeds).",
    ),
]
LabelNoiseOpt = Annotated[
    float,
    typer.Option(
        help="With --cuts and --samples (pose model): probability that a test cut's label is "
        "wrong; the cuts then update P(stable) (a posterior over the sampled structures)."
    ),
]

LocalFactorOpt = Annotated[
    str,
    typer.Option(
        help="With --cuts: LO,HI of the local factor on the limit, drawn afresh at every cut "
        "and point (the time-domain / linear limit ratio), the cuts learning only a common "
        "factor (--common-factor), as in 'mill plan --cuts'; 'none': one common factor over "
        "the structures' whole range (the earlier behaviour)."
    ),
]
CommonFactorOpt = Annotated[
    str,
    typer.Option(help="With --cuts: LO,HI of the common factor the cuts learn."),
]


def factor_range(spec: str, what: str) -> tuple[float, float]:
    """A LO,HI (or LO:HI) factor range, ``0 < LO <= HI``, the error naming the option."""
    try:
        lo, hi = (float(v) for v in spec.replace(",", ":").split(":"))
    except ValueError as exc:
        raise ValueError(f"{what} must be A:B (two numbers), got {spec!r}") from exc
    if not (np.isfinite(lo) and np.isfinite(hi) and 0 < lo <= hi):
        raise ValueError(f"{what} must be LO,HI with 0 < LO <= HI, got {spec!r}")
    return lo, hi


def factor_split(
    local_factor: str, common_factor: str
) -> tuple[tuple[float, float] | None, tuple[float, float]]:
    """``--local-factor`` (None for 'none') and ``--common-factor``, checked (``mill plan``,
    ``mill lobes`` and ``mill map`` with ``--cuts``)."""
    local = (
        None
        if local_factor.strip().lower() == "none"
        else factor_range(local_factor, "--local-factor")
    )
    return local, factor_range(common_factor, "--common-factor")


def echo_cut_update(u: dict, where: str) -> None:
    """Print how much the test cuts moved the forecast (``CutForecast.to_dict()``)."""
    typer.echo(
        f"test cuts: {u['n_cuts']} (label noise {u['label_noise']:g}): effective sample size "
        f"{u['effective_sample_size_prior']:.0f} -> {u['effective_sample_size']:.1f}, "
        f"information {u['information_nats']:.2f} nats; median limit "
        f"{100 * u['median_limit_shift_rel']:+.0f} % at the cuts, "
        f"{100 * u['median_limit_shift_rel_at_forecast']:+.0f} % {where}"
    )
