"""Milling at a pose: forces -> pose-model dynamics -> vibration with a band; lobes.

The workspace stability map is :func:`robovib.milling.maps.workspace_lobe_map`.

The pose model is a fitted :class:`robovib.gp.PoseModalModel` over chapter-3 poses
``(x_mm, y_mm, rz_deg)`` with directions x, y, z (SI), e.g.
:func:`robovib.gp.load_chapter3_model`; the modes are read through ``model.modes``, by
direction name, not by column order.

Uncertainty: Monte-Carlo sampling of the GP's predictive normals (each output independently,
which ignores correlations between outputs), draws with non-physical values (k, fn, c <= 0 or
zeta >= 1) redrawn; the band is the 2.5-97.5 % range of the resulting peak-to-valley and mean
deflection.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._checks import check_choice, check_int, check_number
from .._numeric import percentile
from ..modal.parameters import ModalParameters
from .forces import CuttingCoefficients, CuttingConditions, MillingTool, milling_forces
from .prediction import convolve_force, summarise_vibration
from .stability import StabilityLobes, stability_lobes

__all__ = [
    "DirectionPrediction",
    "PoseLobes",
    "base_frame_forces",
    "lobes_at_pose",
    "pose_extrapolation",
    "pose_modes",
    "predict_at_pose",
]

DIRECTIONS = ("x", "y", "z")
#: High-mode probabilities between which the bands of :func:`predict_at_pose` draw from the
#: model's mixture of the two modes (outside, the other mode cannot reach a 2.5-97.5 % band).
MIXTURE_BAND_PROBABILITY = (0.025, 0.975)
FEED_DIRECTIONS = ("x", "y")  #: feed along base +X or +Y (tool axis along Z)


def base_frame_forces(local: np.ndarray, feed_direction: str) -> np.ndarray:
    """Tool-frame (feed, normal, axial) forces -> base X, Y, Z for feed along +X or +Y.

    Parameters
    ----------
    local : numpy.ndarray
        (n, 3) forces (feed, normal, axial) [N].
    feed_direction : {"x", "y"}
        Feed direction.

    Returns
    -------
    numpy.ndarray
        (n, 3) forces X, Y, Z [N].
    """
    check_choice("feed_direction", feed_direction, FEED_DIRECTIONS)
    if feed_direction == "x":
        return np.column_stack([local[:, 0], local[:, 1], local[:, 2]])
    if feed_direction == "y":
        return np.column_stack([-local[:, 1], local[:, 0], local[:, 2]])
    raise ValueError(f"feed_direction must be 'x' or 'y', got {feed_direction!r}")


def pose_modes(model, pose) -> dict:
    """Dominant mode per direction at one pose: ``{direction: PoseMode}`` (SI, with std).

    ``pose`` is one input row in the units of ``model.input_names`` (e.g. (x_mm, y_mm, rz_deg)).
    Each :class:`PoseMode` says whether it is an extrapolation; see also
    :func:`pose_extrapolation`.

    Parameters
    ----------
    model : object
        The pose model.
    pose : array_like
        One input row in the units of ``model.input_names``.

    Returns
    -------
    dict of str to PoseMode
        Direction -> mode with std and extrapolation flag.

    Raises
    ------
    ValueError
        A non-finite pose coordinate.
    """
    pose = np.asarray(pose, float)
    names = tuple(model.input_names)
    for name, v in zip(names, pose, strict=False):
        if not np.isfinite(v):
            unit = name.rsplit("_", 1)[-1] if "_" in name else "model units"
            raise ValueError(f"pose coordinate {name} must be a finite number in {unit}, got {v}")
    return model.modes(pose[None, :])[0]


def pose_extrapolation(model, pose) -> tuple[str, ...]:
    """Why a pose is outside the model's training data: the inputs outside their training
    range (e.g. ``("x_mm",)``), or ``("hull",)`` for a pose inside every range but outside
    the convex hull of the training poses; empty when the pose is inside.

    Every prediction at such a pose is a GP extrapolation (towards the prior) and must be
    flagged as such.

    Parameters
    ----------
    model : object
        The pose model.
    pose : array_like
        One input row in the units of ``model.input_names``.

    Returns
    -------
    tuple of str
        The reasons (empty: inside).
    """
    from ..gp.extrapolation import extrapolating, outside_inputs

    pose = np.asarray(pose, float).reshape(-1)
    names = tuple(model.input_names)
    outside = outside_inputs(model, pose, names)
    if not outside and bool(extrapolating(model, pose[None, :])[0]):
        return ("hull",)
    return outside


@dataclass(frozen=True)
class DirectionPrediction:
    """Predicted milling vibration in one direction at a pose.

    Attributes
    ----------
    direction
        ``"x"``, ``"y"`` or ``"z"``.
    mean_deflection_m, peak_to_valley_m
        Predicted mean deflection and per-revolution peak-to-valley [m].
    mean_deflection_band_m, peak_to_valley_band_m
        Their 2.5-97.5 % bands [m] over the modal-parameter draws (NaN without draws).
    mode
        The mean dominant mode.
    extrapolation
        Why the pose is an extrapolation (empty: interpolation).
    n_draws_used
        Modal-parameter draws used for the bands.
    modes
        Every mode used (a multi-mode model: all modelled modes of the direction).
    """

    direction: str
    mean_deflection_m: float
    peak_to_valley_m: float
    mean_deflection_band_m: tuple[float, float]
    peak_to_valley_band_m: tuple[float, float]
    mode: ModalParameters
    #: why the pose is an extrapolation (see :func:`pose_extrapolation`; empty: interpolation)
    extrapolation: tuple[str, ...] = ()
    #: modal-parameter draws used for the bands (bands are NaN when 0)
    n_draws_used: int = 0
    #: every mode used (a multi-mode model: all modelled modes of the direction; else ``(mode,)``)
    modes: tuple[ModalParameters, ...] = ()

    @property
    def extrapolating(self) -> bool:
        return bool(self.extrapolation)


def predict_at_pose(
    model,
    x_mm: float,
    y_mm: float,
    rz_deg: float,
    conditions: CuttingConditions,
    *,
    tool: MillingTool | None = None,
    coefficients: CuttingCoefficients | None = None,
    forces_n: np.ndarray | None = None,
    sample_rate_hz: float = 1000.0,
    duration_s: float = 3.0,
    feed_direction: str = "x",
    n_samples: int = 50,
    skip_s: float = 0.5,
    rng=0,
) -> list[DirectionPrediction]:
    """Predicted mean deflection and peak-to-valley per revolution in X, Y, Z at a pose.

    The pose model's modes at the pose (with their uncertainty) filter the cutting forces:
    measured ones, or the mechanistic model's. See ``docs/methods.md`` section 5. A multi-mode
    model (directions ``x1, x2, ..., y1``: :func:`robovib.campaign.fit_multimode_pose_model`)
    filters with every modelled mode of a direction and predicts only the directions it has.

    Parameters
    ----------
    model : PoseModalModel
        Pose model with inputs (x_mm, y_mm, rz_deg), e.g. :func:`robovib.gp.load_chapter3_model`.
    x_mm, y_mm : float
        Tool-tip position [mm].
    rz_deg : float
        Rotation about the tool axis [deg].
    conditions : CuttingConditions
        Spindle speed [rpm], feed per tooth [m], axial and radial depth [m], milling mode.
    tool : MillingTool, optional
        Tool of the simulated forces (default: ``MillingTool()``).
    coefficients : CuttingCoefficients, optional
        Cutting coefficients [N/m², N/m]; needed unless ``forces_n`` is given.
    forces_n : numpy.ndarray, shape (n, 3), optional
        Measured base-frame forces [N] at ``sample_rate_hz`` (e.g. resampled with
        :func:`robovib.milling.prediction.resample_force`); replaces the simulated forces.
    sample_rate_hz : float
        Sample rate of the forces [Hz].
    duration_s : float
        Simulated cutting time [s] (without ``forces_n``).
    feed_direction : {"x", "y"}
        Base-frame feed direction.
    n_samples : int
        Draws of the modes from the model's predictive distribution for the 95 % bands (>= 1).
    skip_s : float
        Start-up transient from rest left out of the summaries [s].
    rng : int or numpy.random.Generator
        Seed of the draws.

    Returns
    -------
    list of DirectionPrediction
        One per direction X, Y, Z: mean deflection [m], peak-to-valley per revolution [m],
        their 95 % bands [m] and the mode used.

    Raises
    ------
    ValueError
        Non-finite pose, unknown feed direction, ``n_samples < 1``, forces of the wrong shape,
        neither ``forces_n`` nor ``coefficients``.

    Examples
    --------
    >>> from robovib.gp import load_chapter3_model
    >>> from robovib.milling import ALUMINIUM_7075, CuttingConditions
    >>> from robovib.milling.at_pose import predict_at_pose
    >>> cond = CuttingConditions(1750.0, 58e-6, 3e-3, 25.4e-3)
    >>> res = predict_at_pose(load_chapter3_model(), 2400.0, 0.0, 45.0, cond,
    ...                       coefficients=ALUMINIUM_7075, n_samples=5)
    >>> [r.direction for r in res]
    ['x', 'y', 'z']
    """
    check_choice("feed_direction", feed_direction, FEED_DIRECTIONS)
    n_samples = check_int("n_samples", n_samples, lo=1, hi=100_000)
    sample_rate_hz = check_number("sample_rate_hz", sample_rate_hz, "Hz", lo=0.0, lo_open=True)
    duration_s = check_number("duration_s", duration_s, "s", lo=0.0, lo_open=True)
    skip_s = check_number("skip_s", skip_s, "s", lo=0.0)
    tool = tool or MillingTool()
    if forces_n is None:
        if coefficients is None:
            raise ValueError("give measured forces_n or cutting coefficients to simulate them")
        t = np.arange(round(duration_s * sample_rate_hz)) / sample_rate_hz
        forces_n = base_frame_forces(
            milling_forces(t, tool, conditions, coefficients), feed_direction
        )
    forces_n = np.asarray(forces_n, float)
    if forces_n.ndim != 2 or forces_n.shape[1] != 3:
        raise ValueError(f"forces_n must be (n, 3) base-frame forces, got {forces_n.shape}")
    if not np.all(np.isfinite(forces_n)):
        raise ValueError("forces_n contains NaN or inf")
    pose_modes(model, (x_mm, y_mm, rz_deg))  # checks the pose, names a bad coordinate
    # dominant-mode model: one mode per direction; multi-mode model (mode ids x1, x2, ..., y1):
    # every modelled mode of a direction, and only the directions it has (issue 29)
    mode_set = model.mode_set(np.array([[x_mm, y_mm, rz_deg]], float))[0]
    per_dir = {d: [m.mode for m in ms] for d, ms in mode_set.items()}
    ids_per_dir = {d: [m.mode_id for m in ms] for d, ms in mode_set.items()}
    outside = pose_extrapolation(model, (x_mm, y_mm, rz_deg))
    gen = np.random.default_rng(rng)
    out = []
    for i, d in enumerate(DIRECTIONS):
        if d not in per_dir:
            continue
        pms = per_dir[d]
        f = forces_n[:, i]
        central = summarise_vibration(
            convolve_force(f, sample_rate_hz, [p.parameters for p in pms]),
            sample_rate_hz,
            conditions.spindle_rpm,
            skip_s,
        )
        mu = np.array([[p.parameters.natural_frequency_hz, p.parameters.stiffness_n_per_m,
                        p.parameters.damping_ns_per_m] for p in pms])  # fmt: skip
        sd = np.array([[p.fn_std_hz, p.stiffness_std_n_per_m, p.damping_std_ns_per_m]
                       for p in pms])  # fmt: skip
        pv, md = [], []
        draws = 0
        # Where the dominant mode is uncertain (a modelled switch), draw from the model's
        # mixture of the two modes, never normals around the more probable one (issue 36).
        mixture = _mixture_draws(
            model, (x_mm, y_mm, rz_deg), ids_per_dir[d], pms, 20 * n_samples, gen
        )
        while len(pv) < n_samples and draws < 20 * n_samples:
            draws += 1
            s = gen.normal(mu, sd) if mixture is None else mixture[draws - 1]
            if np.any(s <= 0):
                continue
            try:
                ms = [ModalParameters.from_fn_k_c(*row) for row in s]
            except ValueError:
                continue
            if any(m.damping_ratio >= 1 for m in ms):
                continue
            summ = summarise_vibration(
                convolve_force(f, sample_rate_hz, ms),
                sample_rate_hz,
                conditions.spindle_rpm,
                skip_s,
            )
            pv.append(summ.peak_to_valley_m)
            md.append(summ.mean_deflection_m)

        def band(v):
            return (percentile(v, 2.5), percentile(v, 97.5)) if v else (np.nan, np.nan)

        out.append(
            DirectionPrediction(
                d,
                central.mean_deflection_m,
                central.peak_to_valley_m,
                band(md),
                band(pv),
                pms[0].parameters,
                outside,
                len(pv),
                tuple(p.parameters for p in pms),
            )
        )
    return out


def _mixture_draws(model, pose, mode_ids: list, pms: list, n: int, gen) -> np.ndarray | None:
    """(n, len(pms), 3) latent draws of fn, k, c of the modes ``pms`` (ids ``mode_ids``, as in
    the model's ``directions_``) from the model's predictive mixture, where the other mode can
    reach the 2.5-97.5 % band (its probability above 2.5 %); else None."""
    lo, hi = MIXTURE_BAND_PROBABILITY
    if not any(p.high_mode_probability is not None and lo < p.high_mode_probability < hi
               for p in pms):  # fmt: skip
        return None
    ids = list(model.directions_)
    cols = [3 * ids.index(k) + j for k in mode_ids for j in range(3)]
    draws = model.predictive(np.asarray(pose, float)[None, :]).sample(n, gen, kind="latent")
    return draws[:, 0, cols].reshape(n, len(pms), 3)


@dataclass(frozen=True)
class PoseLobes:
    """Stability lobes at a pose, sampled over a speed range, with the extrapolation flag.

    Attributes
    ----------
    lobes
        The lobes.
    spindle_rpm
        (n,) speeds [rpm].
    critical_depth_m
        (n,) lowest critical depth [m] (inf: no lobe there).
    feed_direction
        ``"x"`` or ``"y"``.
    extrapolation
        Inputs of the pose outside the model's training range (empty: interpolation).
    """

    lobes: StabilityLobes
    spindle_rpm: np.ndarray  #: (n,) speeds [rpm]
    critical_depth_m: np.ndarray  #: (n,) lowest critical depth [m] (inf: no lobe there)
    feed_direction: str
    #: inputs of the pose outside the model's training range (empty: interpolation)
    extrapolation: tuple[str, ...] = ()

    @property
    def extrapolating(self) -> bool:
        return bool(self.extrapolation)


def lobes_at_pose(
    model,
    x_mm: float,
    y_mm: float,
    rz_deg: float,
    coefficients: CuttingCoefficients,
    *,
    radial_depth_m: float = 6e-3,
    tool: MillingTool | None = None,
    feed_direction: str = "x",
    rpm_range: tuple[float, float] = (100.0, 3000.0),
    n_speeds: int = 200,
    n_lobes: int = 40,
) -> PoseLobes:
    """Zero-order stability lobes from the pose model's X/Y modes, checked at the door.

    The feed direction picks which predicted mode is along the feed (x: X feed, Y normal;
    y: Y feed, X normal). The result says whether the pose is outside the training data.

    Parameters
    ----------
    model : object
        The pose model (inputs ``x_mm, y_mm, rz_deg``).
    x_mm, y_mm, rz_deg : float
        The pose.
    coefficients : CuttingCoefficients
        Cutting coefficients.
    radial_depth_m : float
        Radial depth of cut [m].
    tool : MillingTool, optional
        The cutter (default :class:`MillingTool`).
    feed_direction : {"x", "y"}
        Feed direction.
    rpm_range : tuple of float
        Speed range [rpm].
    n_speeds : int
        Speeds sampled.
    n_lobes : int
        Lobes computed.

    Returns
    -------
    PoseLobes
        The lobes and their lower envelope over the speeds.

    Raises
    ------
    ValueError
        Unknown feed direction, non-finite pose, radial depth <= 0 m or beyond the tool
        diameter, speed range not 0 < min < max (rpm), ``n_speeds`` < 2, ``n_lobes`` < 1.
    """
    check_choice("feed_direction", feed_direction, FEED_DIRECTIONS)
    lo = check_number("rpm_range[0]", rpm_range[0], "rpm", lo=0.0, lo_open=True)
    hi = check_number("rpm_range[1]", rpm_range[1], "rpm", lo=0.0, lo_open=True)
    if lo >= hi:
        raise ValueError(f"speed range must have min < max, got {lo:g}-{hi:g} rpm")
    n_speeds = check_int("n_speeds", n_speeds, lo=2, hi=100_000)
    n_lobes = check_int("n_lobes", n_lobes, lo=1, hi=1000)
    tool = tool or MillingTool()
    radial_depth_m = check_number(
        "radial_depth_m", radial_depth_m, "m", lo=0.0, lo_open=True, hi=tool.diameter_m
    )
    pose_modes(model, (x_mm, y_mm, rz_deg))  # checks the pose, names a bad coordinate
    modes = model.mode_set(np.array([[x_mm, y_mm, rz_deg]], float))[0]  # every mode (contract)
    normal = "y" if feed_direction == "x" else "x"
    for d in (feed_direction, normal):
        if d not in modes:
            raise ValueError(f"the pose model has no mode in direction {d!r} (it has "
                             f"{', '.join(sorted(modes))})")  # fmt: skip
    cond = CuttingConditions(1000.0, 1e-4, 1e-3, radial_depth_m)
    lobes = stability_lobes(
        [m.parameters for m in modes[feed_direction]],
        [m.parameters for m in modes[normal]],
        tool, cond, coefficients, n_lobes=n_lobes,
    )  # fmt: skip
    speeds = np.linspace(lo, hi, n_speeds)
    return PoseLobes(
        lobes,
        speeds,
        lobes.critical_depth(speeds),
        feed_direction,
        pose_extrapolation(model, (x_mm, y_mm, rz_deg)),
    )
