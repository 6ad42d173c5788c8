"""Plan the cut along a tool path: Rz and spindle speed per segment from the pose model (issue 39).

A six-axis robot milling with a spindle has a free rotation about the tool axis, Rz, which is
an input of the pose model: the stable depth changes with it several-fold. Along a tool path
cut into segments (their midpoints are the poses), for every segment, every Rz of a grid over
the allowed range and every spindle speed of a grid over the allowed range, the sampled
structures (:mod:`robovib.milling.structures`: the pose model's calibrated predictive
distribution over the workspace, prior or updated by test cuts) give the distribution of the
stability limit, so

* the axial depth allowed at the required P(stable) ``p`` is the weighted ``1 - p`` quantile of
  the limits (:func:`robovib.milling.cut_posterior.weighted_quantile`);
* P(stable) at the depth asked is the weighted fraction of limits above it.

With the process factor split (structures updated by test cuts with a local factor,
:meth:`~robovib.milling.structures.StructureSamples.on_factor_grid`), each weighted row's limit
is further multiplied by a local factor drawn afresh at every point, so a row's P(stable) is
smooth, ``1 - F_local(log(d / a_r))``: P(stable) is
:func:`~robovib.milling.factor_grid.local_p_stable` and the depth allowed its exact inverse,
:func:`~robovib.milling.factor_grid.local_quantile` (a 1-D root per segment, Rz and speed).

The value of a plan is its mean material removal rate over the path, the volume removed over
the machining time: ``a_e f_z N / 60 * sum(d_i L_i) / sum(L_i / n_i)`` (depth ``d_i``, length
``L_i`` and speed ``n_i`` [rpm] of segment ``i``; ``MRR = a_e a_p f_z N n``). The depth rule
(``depth_rule``) says what is cut:

* ``"segment"`` (default): each segment as deep as allowed at its Rz and speed;
* ``"path"``: one depth for the whole path, the deepest that every chosen configuration allows
  (a user who mills a pocket in passes of one depth);
* a depth asked (``depth_m``): that depth where its P(stable) reaches ``p`` (elsewhere the
  configuration is infeasible; a segment with no feasible configuration in reach takes the one
  of highest P(stable) and is flagged).

The speed may change from segment to segment; Rz may change by at most
``max_rz_rate_deg_per_mm`` times the segment length (the robot reorients smoothly). Rz and
speed are searched jointly: dynamic programming over the Rz grid, each (segment, Rz) with its
best speed, inside Dinkelbach's iteration for the ratio (volume / time), or, for one depth, over
every candidate depth (:func:`choose_configurations`). The comparison
(:func:`fixed_configuration`) is the best single fixed Rz and speed for the whole path under
the same depth rule and the same P(stable); both are reported (``PathPlan.fixed``:
``segment_depth`` and ``one_depth``).

Per segment the plan also predicts the vibration at the chosen configuration and depth (mean
deflection and peak-to-valley per revolution with 95 % bands over the structures, as
:func:`robovib.milling.at_pose.predict_at_pose` does with independent draws), and, optionally,
checks the
chosen configuration with the semi-discretization of the mean structure (``check_sdm``).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace

import numpy as np

from .cut_posterior import p_stable, weighted_quantile
from .forces import CuttingCoefficients, CuttingConditions, MillingTool
from .same_point import (
    DEFAULT_SAME_POINT,
    SamePointTolerance,
    matching_cuts,
    shared_local_p_stable,
    shared_local_quantile,
)
from .structures import StructureSamples

__all__ = [
    "ConfigurationChoice",
    "PathPlan",
    "choose_configurations",
    "fixed_configuration",
    "path_segments",
    "plan_path",
    "plot_path_plan",
    "read_path_csv",
]


def path_segments(points_mm, n_segments: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Segment midpoints and lengths of a polyline (or a straight start-end line cut in n).

    Parameters
    ----------
    points_mm : array_like
        (n, 2) base-frame X, Y points [mm] (n >= 2).
    n_segments : int, optional
        Cut a two-point path (start, end) into this many equal segments.

    Returns
    -------
    midpoints_mm : numpy.ndarray
        (m, 2) segment midpoints [mm].
    length_mm : numpy.ndarray
        (m,) segment lengths [mm].
    """
    p = np.asarray(points_mm, float)
    if p.ndim != 2 or p.shape[1] != 2 or p.shape[0] < 2:
        raise ValueError(f"the path needs >= 2 points (n, 2) X, Y [mm]; got shape {p.shape}")
    if not np.all(np.isfinite(p)):
        raise ValueError("the path contains NaN or inf")
    if n_segments is not None:
        if p.shape[0] != 2 or int(n_segments) < 1:
            raise ValueError("n_segments needs a start and an end point and >= 1 segment")
        t = np.linspace(0, 1, int(n_segments) + 1)[:, None]
        p = p[0] + t * (p[1] - p[0])
    length = np.linalg.norm(np.diff(p, axis=0), axis=1)
    if np.any(length <= 0):
        raise ValueError(f"the path repeats a point (segment {int(np.argmin(length))})")
    return 0.5 * (p[1:] + p[:-1]), length


def read_path_csv(path) -> np.ndarray:
    """Tool-path points from a CSV with columns ``x_mm, y_mm`` (base frame; ``z_mm`` ignored).

    Parameters
    ----------
    path : str or pathlib.Path
        The CSV file.

    Returns
    -------
    numpy.ndarray
        (n, 2) points [mm].
    """
    from ..files.csv_table import read_table

    table = read_table(path, what="tool path", comment="#")
    for name in ("x_mm", "y_mm"):
        if name not in table.header:
            raise ValueError(f"{path}: the tool path needs columns x_mm, y_mm; got {table.header}")
    return table.matrix(["x_mm", "y_mm"])


@dataclass(frozen=True)
class PathPlan:
    """Rz, spindle speed and depth per path segment, with P(stable), vibration and MRR.

    Attributes
    ----------
    midpoints_mm, length_mm
        (m, 2) segment midpoints [mm] and (m,) lengths [mm].
    rz_deg, spindle_rpm
        (m,) chosen Rz [deg] and speed [rpm].
    depth_allowed_m
        (m,) depth allowed at the required P(stable) there [m].
    depth_m
        (m,) depth planned [m] (allowed, or the depth asked).
    p_stable
        (m,) P(stable) at the planned depth.
    p_stable_at_asked
        (m,) P(stable) at the depth asked (None: "as deep as allowed").
    feasible
        (m,) the required P(stable) is met.
    mrr_m3_per_s
        (m,) material removal rate [m³/s].
    vibration
        Per segment dict of the predicted mean deflection and peak-to-valley [m] with bands.
    fixed
        The best single fixed Rz and speed (and at one depth), for comparison.
    settings
        Inputs and settings.
    limits_m
        (S, m, n_rz, n_speeds) the structures' limits [m] over the plan's grids, or None.
    """

    midpoints_mm: np.ndarray
    length_mm: np.ndarray
    rz_deg: np.ndarray
    spindle_rpm: np.ndarray
    depth_allowed_m: np.ndarray
    depth_m: np.ndarray
    p_stable: np.ndarray
    p_stable_at_asked: np.ndarray | None
    feasible: np.ndarray
    mrr_m3_per_s: np.ndarray
    vibration: list = field(default_factory=list)
    fixed: dict = field(default_factory=dict)
    settings: dict = field(default_factory=dict)
    #: (S, m, n_rz, n_speeds) limits [m] of every structure at every segment, Rz and speed of
    #: the grids (``settings["rz_grid_deg"]``, ``settings["rpm_grid"]``): the candidates of
    #: :func:`~robovib.milling.cut_posterior.choose_test_cuts`.
    limits_m: np.ndarray | None = field(default=None, repr=False, compare=False)

    def test_cut_candidates(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Every (segment, Rz, speed) of the plan's grids as test-cut candidates.

        Returns
        -------
        poses : numpy.ndarray
            (C, 3) x_mm, y_mm, rz_deg.
        spindle_rpm : numpy.ndarray
            (C,) speeds [rpm].
        limits_m : numpy.ndarray
            (S, C) the structures' limits there [m].
        """
        if self.limits_m is None:
            raise ValueError("this plan kept no limit table")
        rz = np.asarray(self.settings["rz_grid_deg"])
        rpm = np.asarray(self.settings["rpm_grid"])
        m = self.midpoints_mm.shape[0]
        seg, r, j = (a.ravel() for a in np.meshgrid(np.arange(m), np.arange(rz.size),
                                                     np.arange(rpm.size), indexing="ij"))  # fmt: skip
        poses = np.column_stack([self.midpoints_mm[seg], rz[r]])
        return poses, rpm[j], self.limits_m.reshape(self.limits_m.shape[0], -1)

    @property
    def mean_mrr_m3_per_s(self) -> float:
        """Mean MRR over the path, each segment weighted by its machining time."""
        return _time_weighted_mrr(self.mrr_m3_per_s, self.length_mm, self.spindle_rpm)

    def rows(self) -> list[dict]:
        """One dict per segment in the units of the CSV (mm, deg, rpm, mm³/s).

        Returns
        -------
        list of dict
            The rows.
        """
        out = []
        for i in range(self.rz_deg.size):
            row = {
                "segment": i,
                "x_mm": float(self.midpoints_mm[i, 0]),
                "y_mm": float(self.midpoints_mm[i, 1]),
                "length_mm": float(self.length_mm[i]),
                "rz_deg": float(self.rz_deg[i]),
                "spindle_rpm": float(self.spindle_rpm[i]),
                "depth_allowed_mm": float(self.depth_allowed_m[i] * 1e3),
                "depth_mm": float(self.depth_m[i] * 1e3),
                "p_stable": float(self.p_stable[i]),
                "p_stable_at_asked": None
                if self.p_stable_at_asked is None
                else float(self.p_stable_at_asked[i]),
                "feasible": bool(self.feasible[i]),
                "mrr_mm3_per_s": float(self.mrr_m3_per_s[i] * 1e9),
            }
            if self.vibration:
                v = self.vibration[i]
                for key in ("mean_deflection", "peak_to_valley"):
                    row[f"{key}_mm"] = v[f"{key}_m"] * 1e3
                    row[f"{key}_low_mm"] = v[f"{key}_band_m"][0] * 1e3
                    row[f"{key}_high_mm"] = v[f"{key}_band_m"][1] * 1e3
            if "sdm_mean_limit_m" in self.settings.get("checks", {}):
                row["sdm_mean_limit_mm"] = self.settings["checks"]["sdm_mean_limit_m"][i] * 1e3
            out.append(row)
        return out

    def to_frame(self):
        """The per-segment table (units in the column names).

        Returns
        -------
        pandas.DataFrame
            One row per segment.
        """
        import pandas as pd

        return pd.DataFrame(self.rows())

    def to_dict(self) -> dict:
        return {
            "units": {"x_mm": "mm", "y_mm": "mm", "rz_deg": "deg", "spindle_rpm": "rpm",
                      "depth_mm": "mm", "mrr_mm3_per_s": "mm^3/s",
                      "mean_deflection_mm": "mm (vector norm X, Y)",
                      "peak_to_valley_mm": "mm per revolution (largest of X, Y)"},
            "segments": self.rows(),
            "mean_mrr_mm3_per_s": self.mean_mrr_m3_per_s * 1e9,
            "fixed": self.fixed,
            "gain_over_fixed": self.mean_mrr_m3_per_s * 1e9 / self.fixed["mean_mrr_mm3_per_s"]
            if self.fixed.get("mean_mrr_mm3_per_s") else None,
            "settings": self.settings,
        }  # fmt: skip

    def write_csv(self, path, *, inputs=(), force: bool = False) -> None:
        """The per-segment table as CSV (units in the column names).

        Parameters
        ----------
        path : str or pathlib.Path
            The file to write.
        inputs : sequence of path
            Files the plan was made from (never overwritten unless ``force``).
        force : bool
            Allow ``path`` to be one of ``inputs``.
        """
        import csv
        import io

        from ..files.safe_write import atomic_output

        rows = self.rows()
        buf = io.StringIO()
        writer = csv.DictWriter(buf, fieldnames=list(rows[0]), lineterminator="\n")
        writer.writeheader()
        for r in rows:
            writer.writerow({k: (f"{v:.6g}" if isinstance(v, float) else v) for k, v in r.items()})
        with atomic_output(path, inputs=inputs, force=force) as tmp:
            tmp.write_text(buf.getvalue())


def _time_weighted_mrr(mrr, length_mm, rpm) -> float:
    # machining time of a segment ∝ length / feed speed ∝ length / rpm (fz, N fixed)
    t = np.asarray(length_mm, float) / np.asarray(rpm, float)
    return float(np.sum(np.asarray(mrr) * t) / np.sum(t))


def _grid(lo_hi, step_or_n, what: str, integer_count: bool) -> np.ndarray:
    lo, hi = (float(v) for v in lo_hi)
    if not (np.isfinite(lo) and np.isfinite(hi) and lo <= hi):
        raise ValueError(f"{what} range must be low <= high, got {lo_hi}")
    if integer_count:
        n = int(step_or_n)
        if n < 1:
            raise ValueError(f"{what}: at least one grid point")
        return np.linspace(lo, hi, n) if hi > lo else np.array([lo])
    step = float(step_or_n)
    if not step > 0:
        raise ValueError(f"{what} step must be positive, got {step_or_n}")
    n = int(np.floor((hi - lo) / step + 1e-9)) + 1
    return lo + step * np.arange(n)


def plan_path(
    structures: StructureSamples,
    points_mm,
    tool: MillingTool,
    conditions: CuttingConditions,
    coefficients: CuttingCoefficients,
    *,
    n_segments: int | None = None,
    feed_direction: str = "x",
    rz_range_deg: tuple[float, float] = (0.0, 180.0),
    rz_step_deg: float = 20.0,
    rpm_range: tuple[float, float] = (1000.0, 3500.0),
    n_speeds: int = 12,
    p_required: float = 0.95,
    depth_m: float | None = None,
    max_rz_rate_deg_per_mm: float = 1.0,
    max_depth_m: float = 0.02,
    depth_rule: str = "segment",
    vibration_samples: int = 24,
    check_sdm: bool = False,
    points_per_decade: float = 200.0,
    cuts=None,
    label_noise: float = 0.05,
    same_point=None,
) -> PathPlan:
    """Plan Rz and spindle speed along a tool path (module docs).

    Parameters
    ----------
    structures : StructureSamples
        Sampled structures of the pose model (prior, or updated by test cuts).
    points_mm : array_like
        (n, 2) base-frame X, Y points [mm] of the path (a polyline), or start and end with
        ``n_segments``.
    tool, conditions, coefficients
        Cutter; feed per tooth, radial depth and up/down milling (speed and axial depth are
        planned); cutting coefficients.
    n_segments : int, optional
        Cut a start-end path into this many segments.
    feed_direction : {"x", "y"}
        Base-frame feed direction of the stability analysis.
    rz_range_deg, rz_step_deg
        Allowed Rz [deg] and the grid step.
    rpm_range, n_speeds
        Allowed spindle speeds [rpm] and the number of grid speeds.
    p_required : float
        Required P(stable) (e.g. 0.95).
    depth_m : float, optional
        Axial depth wanted [m]; None: as deep as allowed.
    max_rz_rate_deg_per_mm : float
        Largest change of Rz per mm of path between segments [deg/mm].
    max_depth_m : float
        Deepest cut the tool allows [m] (caps "as deep as allowed").
    depth_rule : {"segment", "path"}
        With no depth asked: each segment as deep as allowed there, or one depth for the whole
        path (the deepest that every chosen configuration allows; :func:`choose_configurations`).
        The fixed comparison (``PathPlan.fixed``) follows the same rule.
    vibration_samples : int
        Structures (the heaviest) whose forced vibration gives the bands (0: none).
    check_sdm : bool
        Also compute the semi-discretization limit of the mean structure at each chosen
        configuration (``settings["checks"]``).
    points_per_decade : float
        Chatter-frequency grid of the zero-order search (:func:`~robovib.milling.structures.zoa_limits`).
    cuts : MeasuredCuts, optional
        The test cuts that ``structures`` were updated with (with a local factor): a grid point
        at a cut's own segment, Rz and speed (within ``same_point``) shares that cut's local
        factor, conditioned on its label (:mod:`robovib.milling.same_point`). None: the local
        factor is drawn afresh at every point.
    label_noise : float
        The label-noise rate the structures were updated with.
    same_point : SamePointTolerance, optional
        The tolerance (default :data:`~robovib.milling.same_point.DEFAULT_SAME_POINT`).

    Returns
    -------
    PathPlan
    """
    t0 = time.perf_counter()
    if depth_rule not in ("segment", "path"):
        raise ValueError(f"depth_rule must be 'segment' or 'path', got {depth_rule!r}")
    if not 0 < p_required < 1:
        raise ValueError(f"p_required must be in (0, 1), got {p_required!r}")
    if depth_m is not None and not (np.isfinite(depth_m) and depth_m > 0):
        raise ValueError(f"depth_m must be a positive depth [m] or None, got {depth_m!r}")
    if not (np.isfinite(max_rz_rate_deg_per_mm) and max_rz_rate_deg_per_mm >= 0):
        raise ValueError(f"max_rz_rate_deg_per_mm must be >= 0, got {max_rz_rate_deg_per_mm!r}")
    mid, length = path_segments(points_mm, n_segments)
    rz = _grid(rz_range_deg, rz_step_deg, "Rz", False)
    rpm = _grid(rpm_range, n_speeds, "spindle speed", True)
    if rpm[0] <= 0:
        raise ValueError(f"spindle speeds must be positive, got {rpm_range}")
    m, r, j = mid.shape[0], rz.size, rpm.size
    poses = np.column_stack([np.repeat(mid, r, axis=0), np.tile(rz, m)])  # (m r, 3)
    lim = structures.limits(poses, rpm, tool, conditions, coefficients,
                            feed_direction=feed_direction, points_per_decade=points_per_decade,
                            depth_cap_m=max_depth_m)  # fmt: skip
    lim = lim.reshape(structures.n_samples, m, r, j)
    w = structures.weights
    loc = structures.local_factor
    if loc is None:
        quantile, prob = weighted_quantile, p_stable
    else:  # a local factor drawn afresh at every point: smooth P(stable) per row
        from .factor_grid import local_p_stable, local_quantile

        def quantile(lim_, w_, q_):
            return local_quantile(lim_, w_, q_, loc)

        def prob(lim_, w_, d_):
            return local_p_stable(lim_, w_, d_, loc)

    # the tool's usable flute length caps the depth (a structure without a lobe in reach is
    # stable at any depth: inf)
    # just below the quantile: a cut there is stable for a weight of at least p_required
    allowed = np.minimum(quantile(lim, w, 1.0 - p_required) * (1 - 1e-9), max_depth_m)  # (m, r, j)
    feed_speed = conditions.feed_per_tooth_m * tool.n_flutes * rpm / 60.0  # (j,) m/s
    ae = conditions.radial_depth_m
    p_at = None if depth_m is None else prob(lim, w, depth_m)  # (m, r, j)
    shared = None
    if loc is not None and cuts is not None:
        shared = _SharedCutPoints.at_grid(
            cuts, poses, rpm, (m, r, j), structures, label_noise, same_point,
            (tool, conditions, coefficients),
            {"feed_direction": feed_direction, "points_per_decade": points_per_decade,
             "depth_cap_m": max_depth_m})  # fmt: skip
        for i, ri, ji in shared.points():
            cut = shared.cut_args(i, ri, ji)
            point = lim[:, i, ri, ji]
            allowed[i, ri, ji] = min(
                shared_local_quantile(point, w, 1.0 - p_required, *cut, loc, label_noise)
                * (1 - 1e-9), max_depth_m)  # fmt: skip
            if p_at is not None:
                p_at[i, ri, ji] = shared_local_p_stable(point, w, [depth_m], *cut, loc,
                                                        label_noise)[0]  # fmt: skip
    choice = choose_configurations(allowed, rz, rpm, length,
                                   max_rz_rate_deg_per_mm=max_rz_rate_deg_per_mm,
                                   depth_rule=depth_rule, depth_m=depth_m,
                                   p_stable_at_depth=p_at, p_required=p_required)  # fmt: skip
    seg = np.arange(m)
    path_r, jj, plan_depth = choice.rz_index, choice.speed_index, choice.depth_m
    plan_allowed = allowed[seg, path_r, jj]
    p_plan = prob(lim[:, seg, path_r, jj], w, plan_depth)
    if shared is not None:
        for i in seg:
            if shared.match[i, path_r[i], jj[i]].any():
                p_plan[i] = shared_local_p_stable(
                    lim[:, i, path_r[i], jj[i]], w, [plan_depth[i]],
                    *shared.cut_args(i, path_r[i], jj[i]), loc, label_noise)[0]  # fmt: skip
    feasible = (
        (plan_depth > 0) & (plan_depth <= plan_allowed)
        if p_at is None
        else p_at[seg, path_r, jj] >= p_required
    )
    mrr = ae * plan_depth * feed_speed[jj]
    fixed = fixed_configuration(allowed, rz, rpm, length, depth_rule=depth_rule, depth_m=depth_m,
                                p_stable_at_depth=p_at, p_required=p_required)  # fmt: skip
    fixed = _fixed_to_units(fixed, ae, conditions.feed_per_tooth_m * tool.n_flutes / 60.0)
    vib = []
    if int(vibration_samples) > 0:
        vib = _vibration(structures, mid, rz[path_r], rpm[jj], plan_depth, tool, conditions,
                         coefficients, feed_direction, int(vibration_samples))  # fmt: skip
    checks = {}
    if check_sdm:
        checks["sdm_mean_limit_m"] = _sdm_check(structures.model, mid, rz[path_r], rpm[jj], tool,
                                                conditions, coefficients, feed_direction)  # fmt: skip
    settings = {
        "p_required": float(p_required),
        "depth_asked_m": None if depth_m is None else float(depth_m),
        "feed_direction": feed_direction,
        "rz_grid_deg": rz.tolist(),
        "rpm_grid": rpm.tolist(),
        "max_rz_rate_deg_per_mm": float(max_rz_rate_deg_per_mm),
        "max_depth_m": float(max_depth_m),
        "depth_rule": depth_rule if depth_m is None else "asked",
        "radial_depth_m": float(ae),
        "feed_per_tooth_m": float(conditions.feed_per_tooth_m),
        "n_flutes": int(tool.n_flutes),
        "method": "zero-order (batched) over sampled structures"
        + ("" if loc is None else f", local factor log-uniform on {list(loc)} at every point"),
        "points_per_decade": float(points_per_decade),
        **({} if shared is None else {"same_point_tolerance": shared.tolerance.to_dict()}),
        "structures": dict(structures.settings),
        "effective_sample_size": structures.effective_sample_size,
        "checks": checks,
        "seconds": time.perf_counter() - t0,
    }
    return PathPlan(
        mid, length, rz[path_r], rpm[jj], plan_allowed, plan_depth, p_plan,
        None if p_at is None else p_at[seg, path_r, jj],
        feasible, mrr, vib, fixed, settings, lim,
    )  # fmt: skip


@dataclass(frozen=True)
class _SharedCutPoints:
    """The plan's grid points at test cuts' own poses and speeds, and the cuts' row limits."""

    match: np.ndarray  # (m, r, j, n_cuts) bool
    cut_limits_m: np.ndarray  # (R, n_cuts), on the plan's limit settings
    depth_m: np.ndarray
    chatter: np.ndarray
    tolerance: SamePointTolerance

    @classmethod
    def at_grid(cls, cuts, poses, rpm, shape, structures, label_noise, tolerance, cutting,
                limit_kw) -> _SharedCutPoints:  # fmt: skip
        if not 0 < label_noise < 0.5:
            raise ValueError(f"label_noise must be in (0, 0.5), got {label_noise!r}")
        tol = DEFAULT_SAME_POINT if tolerance is None else tolerance
        if not isinstance(tol, SamePointTolerance):
            raise TypeError(f"same_point must be a SamePointTolerance, got {tolerance!r}")
        if cuts.pose_mm_deg is None:
            raise ValueError("the test cuts have no poses: give the columns x_mm, y_mm, rz_deg")
        c_pose = np.atleast_2d(np.asarray(cuts.pose_mm_deg, float))
        c_rpm = np.asarray(cuts.spindle_rpm, float)
        match = matching_cuts(poses, rpm, c_pose, c_rpm, tol).reshape(*shape, c_rpm.size)
        cut_lim = np.full((structures.n_samples, c_rpm.size), np.inf)
        used = match.any(axis=(0, 1, 2))
        for speed in np.unique(c_rpm[used]):  # only the cuts at a grid point
            at = np.flatnonzero(used & (c_rpm == speed))
            cut_lim[:, at] = structures.limits(c_pose[at], [speed], *cutting,
                                               **limit_kw)[:, :, 0]  # fmt: skip
        return cls(match, cut_lim, np.asarray(cuts.depth_m, float),
                   np.asarray(cuts.chatter, bool), tol)  # fmt: skip

    def points(self):
        """(segment, Rz, speed) indices of the grid points at cuts."""
        return zip(*np.nonzero(self.match.any(axis=3)), strict=True)

    def cut_args(self, i, ri, ji) -> tuple:
        at = self.match[i, ri, ji]
        return self.cut_limits_m[:, at], self.depth_m[at], self.chatter[at]


@dataclass(frozen=True)
class ConfigurationChoice:
    """Rz and speed per segment (grid indices) and the depth cut there.

    Attributes
    ----------
    rz_index, speed_index
        (m,) indices into the Rz and speed grids.
    depth_m
        (m,) depth cut [m].
    score
        The mean MRR over the path divided by ``a_e f_z N / 60`` [m rpm]: ``sum(d_i L_i) /
        sum(L_i / n_i)`` (volume over machining time).
    """

    rz_index: np.ndarray
    speed_index: np.ndarray
    depth_m: np.ndarray
    score: float


def _rz_steps_allowed(rz_deg, length_mm, max_rz_rate_deg_per_mm) -> np.ndarray:
    """(m-1, r, r): from segment i at Rz a to segment i+1 at Rz b within the rate limit."""
    rz = np.asarray(rz_deg, float)
    length = np.asarray(length_mm, float)
    return np.abs(rz[:, None] - rz[None, :]) <= (
        max_rz_rate_deg_per_mm * 0.5 * (length[:-1, None, None] + length[1:, None, None]) + 1e-9
    )


def _best_rz_sequence(gain, step_ok) -> np.ndarray:
    """Dynamic programming: the Rz indices maximising ``sum_i gain[..., i, r_i]`` under the
    rate limit; ``gain`` (..., m, r) with leading batch axes (candidates)."""
    m = gain.shape[-2]
    score = gain[..., 0, :].copy()
    back = np.zeros(gain.shape, int)
    for i in range(1, m):
        cand = np.where(step_ok[i - 1], score[..., :, None], -np.inf)  # (..., from, to)
        back[..., i, :] = np.argmax(cand, axis=-2)
        score = (
            np.take_along_axis(cand, back[..., i, None, :], axis=-2)[..., 0, :] + gain[..., i, :]
        )
    path = np.empty(gain.shape[:-1], int)
    path[..., -1] = np.argmax(score, axis=-1)
    for i in range(m - 1, 0, -1):
        path[..., i - 1] = np.take_along_axis(back[..., i, :], path[..., i, None], axis=-1)[..., 0]
    return path


def _checked_table(allowed_m, rz_deg, spindle_rpm, length_mm, depth_rule, depth_m,
                   p_stable_at_depth, p_required):  # fmt: skip
    """The arrays of :func:`choose_configurations` and :func:`fixed_configuration`, checked."""
    allowed = np.asarray(allowed_m, float)
    rz = np.asarray(rz_deg, float).ravel()
    rpm = np.asarray(spindle_rpm, float).ravel()
    length = np.asarray(length_mm, float)
    if allowed.ndim != 3 or allowed.shape[1:] != (rz.size, rpm.size):
        raise ValueError(
            f"allowed_m must be (segments, {rz.size} Rz, {rpm.size} speeds), got {allowed.shape}"
        )
    if length.shape != allowed.shape[:1]:
        raise ValueError(f"length_mm must be ({allowed.shape[0]},), got {length.shape}")
    if not (np.all(np.isfinite(length)) and np.all(length > 0)):
        raise ValueError("length_mm must be finite segment lengths > 0 [mm]")
    if not (np.all(np.isfinite(rpm)) and np.all(rpm > 0)):
        raise ValueError("spindle_rpm must be finite speeds > 0 [rpm]")
    if not np.all(np.isfinite(rz)):
        raise ValueError("rz_deg must be finite angles [deg]")
    if depth_rule not in ("segment", "path"):
        raise ValueError(f"depth_rule must be 'segment' or 'path', got {depth_rule!r}")
    if np.any(np.isnan(allowed)) or np.any(allowed < 0):
        raise ValueError("allowed_m must be depths >= 0 (inf: unlimited)")
    if not 0 < p_required < 1:
        raise ValueError(f"p_required must be in (0, 1), got {p_required!r}")
    if depth_m is not None:
        if not (np.isfinite(depth_m) and depth_m > 0):
            raise ValueError(f"depth_m must be a finite depth > 0 [m], got {depth_m!r}")
        if p_stable_at_depth is None:
            raise ValueError("a depth asked needs p_stable_at_depth")
        p_at = np.asarray(p_stable_at_depth, float)
        if p_at.shape != allowed.shape:
            raise ValueError(
                f"p_stable_at_depth must be {allowed.shape} like allowed_m, got {p_at.shape}"
            )
        if np.any(np.isnan(p_at)) or np.any((p_at < 0) | (p_at > 1)):
            raise ValueError("p_stable_at_depth must be probabilities in [0, 1]")
    return allowed, rz, rpm, length


def choose_configurations(
    allowed_m,
    rz_deg,
    spindle_rpm,
    length_mm,
    *,
    max_rz_rate_deg_per_mm: float,
    depth_rule: str = "segment",
    depth_m: float | None = None,
    p_stable_at_depth=None,
    p_required: float = 0.95,
) -> ConfigurationChoice:
    """The Rz and speed per segment of largest mean MRR, Rz changes within the rate limit.

    The mean MRR over the path is the volume removed over the machining time,
    ``a_e f_z N / 60 * sum(d_i L_i) / sum(L_i / n_i)`` (depth ``d_i``, length ``L_i``, speed
    ``n_i`` [rpm] of segment ``i``): segments cut faster take less time.

    * ``depth_rule="segment"``: each segment is cut at the depth allowed at its Rz and speed.
      The ratio is maximised exactly by Dinkelbach's iteration (``max sum(V_i - lam T_i)``
      by dynamic programming over the Rz grid, ``lam`` the ratio of the last solution,
      until it no longer grows).
    * ``depth_rule="path"``: one depth ``d`` for the whole path, at most the depth allowed at
      every segment's Rz and speed. For every candidate ``d`` (each allowed depth of the table
      up to the smallest segment maximum) each (segment, Rz) takes the fastest speed that
      allows ``d``; dynamic programming finds the quickest Rz sequence; the candidate of
      largest ``d sum(L_i) / sum(L_i / n_i)`` wins.
    * ``depth_m`` given: that depth everywhere; configurations where ``p_stable_at_depth``
      reaches ``p_required`` are feasible; a segment without a feasible one within the rate
      limit takes the one of highest P(stable); among feasible ones the speeds and Rz of
      largest mean MRR (shortest time).

    Parameters
    ----------
    allowed_m : array_like
        (m, r, j) depth allowed at the required P(stable) per segment, Rz and speed [m].
    rz_deg, spindle_rpm : array_like
        (r,) Rz grid [deg], (j,) speed grid [rpm].
    length_mm : array_like
        (m,) segment lengths [mm].
    max_rz_rate_deg_per_mm : float
        Largest Rz change per mm of path between segments.
    depth_rule : {"segment", "path"}
        Depth per segment or one depth for the path (``depth_m`` None).
    depth_m : float, optional
        The depth asked [m].
    p_stable_at_depth : array_like, optional
        (m, r, j) P(stable) at ``depth_m`` (needed with it).
    p_required : float
        Required P(stable).

    Returns
    -------
    ConfigurationChoice
    """
    allowed, rz, rpm, length = _checked_table(
        allowed_m, rz_deg, spindle_rpm, length_mm, depth_rule, depth_m, p_stable_at_depth,
        p_required,
    )  # fmt: skip
    if not (np.isfinite(max_rz_rate_deg_per_mm) and max_rz_rate_deg_per_mm >= 0):
        raise ValueError(
            f"max_rz_rate_deg_per_mm must be finite and >= 0, got {max_rz_rate_deg_per_mm!r}"
        )
    m = allowed.shape[0]
    seg = np.arange(m)
    step_ok = _rz_steps_allowed(rz, length, max_rz_rate_deg_per_mm)
    time_ = np.broadcast_to(length[:, None, None] / rpm[None, None, :], allowed.shape)
    if depth_m is not None:
        if p_stable_at_depth is None:
            raise ValueError("a depth asked needs p_stable_at_depth")
        p_at = np.asarray(p_stable_at_depth, float)
        ok = p_at >= p_required
        volume = np.where(ok, float(depth_m) * length[:, None, None], 0.0)
        # infeasible configurations only where nothing else is within reach: a penalty larger
        # than any MRR difference, smaller for a higher P(stable)
        big = 4.0 * (np.abs(volume).max() + time_.max() * (volume / time_).max() + 1.0) * m
        penalty = np.where(ok, 0.0, big * (1.0 + 1e6 * (1.0 - p_at)))
        depth_table = np.full(allowed.shape, float(depth_m))
    elif depth_rule == "segment":
        if not np.all(np.isfinite(allowed)):
            raise ValueError("allowed_m must be finite with depth_rule='segment' (cap it)")
        volume = allowed * length[:, None, None]
        penalty = np.zeros(allowed.shape)
        depth_table = allowed
    else:
        return _one_depth_for_the_path(allowed, rpm, length, step_ok)
    lam, best = 0.0, None
    for _ in range(200):  # Dinkelbach: converges in a handful of steps
        g = volume - lam * time_ - penalty
        j_best = np.argmax(g, axis=2)  # (m, r)
        gain = np.take_along_axis(g, j_best[..., None], axis=2)[..., 0]
        path_r = _best_rz_sequence(gain, step_ok)
        jj = j_best[seg, path_r]
        ratio = float(volume[seg, path_r, jj].sum() / time_[seg, path_r, jj].sum())
        if best is not None and ratio <= lam * (1 + 1e-12):
            break
        best, lam = (path_r, jj), ratio
    path_r, jj = best
    return ConfigurationChoice(path_r, jj, depth_table[seg, path_r, jj], lam)


def _one_depth_for_the_path(allowed, rpm, length, step_ok) -> ConfigurationChoice:
    m = allowed.shape[0]
    seg = np.arange(m)
    reach = allowed.reshape(m, -1).max(axis=1)  # deepest cut each segment allows
    top = float(reach.min())
    # the fastest speed of a (segment, Rz) that allows d changes only where d passes a maximum
    # over the faster speeds; between those the time is constant and d * L / time grows, so
    # the best d is one of them
    order = np.argsort(rpm)
    suffix = np.flip(np.maximum.accumulate(np.flip(allowed[..., order], axis=2), axis=2), axis=2)
    cand = np.unique(suffix[suffix <= top])
    cand = cand[cand > 0] if np.isfinite(top) else cand[np.isfinite(cand) & (cand > 0)]
    if cand.size == 0:  # no depth > 0 anywhere: the fastest configuration at depth 0
        cand = np.array([0.0])
    best = (-1.0, None)
    for c0 in range(0, cand.size, 256):  # candidates in batches (memory)
        c = cand[c0 : c0 + 256]
        ok = allowed[None] >= c[:, None, None, None]  # (C, m, r, j)
        fastest = np.where(ok, rpm, 0.0).max(axis=3)  # (C, m, r)
        t = np.where(fastest > 0, length[None, :, None] / np.maximum(fastest, 1e-300), np.inf)
        gain = np.where(np.isfinite(t), -t, -1e300)
        path_r = _best_rz_sequence(gain, step_ok)  # (C, m)
        tt = np.take_along_axis(t, path_r[..., None], axis=2)[..., 0].sum(axis=1)
        score = np.where(np.isfinite(tt), c * length.sum() / tt, -1.0)
        k = int(np.argmax(score))
        if score[k] > best[0]:
            best = (float(score[k]), (c[k], path_r[k]))
    score, (d, path_r) = best
    okj = allowed[seg, path_r] >= d  # (m, j)
    jj = np.argmax(np.where(okj, rpm, -np.inf), axis=1)
    return ConfigurationChoice(path_r, jj, np.full(m, d), max(score, 0.0))


def fixed_configuration(
    allowed_m,
    rz_deg,
    spindle_rpm,
    length_mm,
    *,
    depth_rule: str = "segment",
    depth_m: float | None = None,
    p_stable_at_depth=None,
    p_required: float = 0.95,
) -> dict:
    """The best single Rz and speed for the whole path under the same depth rule.

    Parameters
    ----------
    allowed_m, rz_deg, spindle_rpm, length_mm, depth_rule, depth_m, p_stable_at_depth, p_required
        As :func:`choose_configurations`.

    Returns
    -------
    dict
        ``rz_deg``, ``spindle_rpm``, ``score`` (as :attr:`ConfigurationChoice.score`),
        ``rule`` (in words), and with no depth asked ``one_depth`` (``rz_deg``,
        ``spindle_rpm``, ``depth_m``, ``score``: one depth for the whole path, the smallest
        allowed along it at that Rz and speed) and ``segment_depth`` (the depth per segment).
    """
    allowed, rz, rpm, length = _checked_table(
        allowed_m, rz_deg, spindle_rpm, length_mm, depth_rule, depth_m, p_stable_at_depth,
        p_required,
    )  # fmt: skip
    lw = length / length.sum()
    # depth per segment at one Rz and speed: sum(d L) / sum(L / n) = n * mean_L(d)
    seg_score = np.einsum("i,irj->rj", lw, allowed) * rpm[None, :]
    one = allowed.min(axis=0)  # (r, j)
    one_score = one * rpm[None, :]

    def best_of(score):
        r0, j0 = np.unravel_index(int(np.argmax(score)), score.shape)
        return {"rz_deg": float(rz[r0]), "spindle_rpm": float(rpm[j0]),
                "score": float(score[r0, j0])}, (r0, j0)  # fmt: skip

    if depth_m is not None:
        ok = (np.asarray(p_stable_at_depth) >= p_required).all(axis=0)
        out, _ = best_of(np.where(ok, float(depth_m) * rpm[None, :], 0.0))
        out["rule"] = (
            "one Rz and speed for the whole path at the depth asked, feasible on every segment"
        )
        return out
    seg_best, _ = best_of(seg_score)
    one_best, (r1, j1) = best_of(one_score)
    one_best["depth_m"] = float(one[r1, j1])
    seg_best["rule"] = ("one Rz and speed for the whole path, the depth per segment as allowed "
                        "there at the same P(stable)")  # fmt: skip
    one_best["rule"] = ("one Rz, speed and depth for the whole path (the smallest allowed along "
                        "it) at the same P(stable)")  # fmt: skip
    out = dict(seg_best if depth_rule == "segment" else one_best)
    out["segment_depth"] = seg_best
    out["one_depth"] = one_best
    return out


def _fixed_to_units(fixed: dict, ae: float, per_rpm: float) -> dict:
    """The fixed comparison with MRR [mm³/s] and depths [mm] (``per_rpm`` = f_z N / 60)."""
    out = {}
    for key, val in fixed.items():
        if isinstance(val, dict):
            out[key] = _fixed_to_units(val, ae, per_rpm)
        elif key == "score":
            out["mean_mrr_mm3_per_s"] = float(val * ae * per_rpm * 1e9)
        elif key == "depth_m":
            out["depth_mm"] = float(val * 1e3)
        else:
            out[key] = val
    return out


def _vibration(structures, mid, rz, rpm, depth, tool, conditions, coefficients, feed, n_draws):
    """Mean deflection and peak-to-valley per revolution at each chosen configuration.

    The structures' modes at the segment (their weights: prior or posterior) filter the
    mechanistic cutting force (:func:`robovib.milling.forces.milling_forces` rotated into the
    base frame) by the sum of modal receptances from rest, exactly as
    :func:`robovib.milling.prediction.convolve_force` (FFT of the zero-padded force); the
    summaries are :func:`robovib.milling.prediction.summarise_vibration`'s. Reported: the
    weighted median and the weighted 2.5-97.5 % band over ``n_draws`` structures of the larger
    horizontal deflection (norm of X, Y) and the larger peak-to-valley of X and Y.
    """
    from .at_pose import base_frame_forces
    from .forces import milling_forces
    from .prediction import summarise_vibration

    fs, duration, skip = 1000.0, 1.5, 0.5
    t = np.arange(round(duration * fs)) / fs
    fn, k, zeta, in_feed = structures.modes(np.column_stack([mid, rz]), feed)
    w = structures.weights
    take = np.argsort(-w, kind="stable")[: max(int(n_draws), 1)]  # the heaviest structures
    wt = w[take] / w[take].sum()
    n_pad = 2 * t.size
    f = np.fft.rfftfreq(n_pad, 1.0 / fs)
    axis = {"x": 0, "y": 1}
    normal = "y" if feed == "x" else "x"
    out = []
    for i in range(mid.shape[0]):
        cond = replace(conditions, spindle_rpm=float(rpm[i]), axial_depth_m=float(depth[i]))
        force = base_frame_forces(milling_forces(t, tool, cond, coefficients), feed)
        mean_d, pv = np.zeros((take.size, 2)), np.zeros((take.size, 2))
        for d, sel in ((feed, in_feed), (normal, ~in_feed)):
            r = f[None, None, :] / fn[take, i][:, sel, None]
            g = (
                1.0 / (k[take, i][:, sel, None] * (1 - r**2 + 2j * zeta[take, i][:, sel, None] * r))
            ).sum(1)
            spec = np.fft.rfft(force[:, axis[d]], n_pad)
            disp = np.fft.irfft(spec[None, :] * g, n_pad)[:, : t.size]
            for s in range(take.size):
                summ = summarise_vibration(disp[s], fs, float(rpm[i]), skip)
                mean_d[s, axis[d]], pv[s, axis[d]] = summ.mean_deflection_m, summ.peak_to_valley_m
        md, p2v = np.linalg.norm(mean_d, axis=1), pv.max(axis=1)
        q = (0.025, 0.5, 0.975)
        a, b = (np.array([weighted_quantile(v[:, None], wt, qq)[0] for qq in q]) for v in (md, p2v))
        out.append({
            "mean_deflection_m": float(a[1]), "mean_deflection_band_m": [float(a[0]), float(a[2])],
            "peak_to_valley_m": float(b[1]), "peak_to_valley_band_m": [float(b[0]), float(b[2])],
        })  # fmt: skip
    return out


def _sdm_check(model, mid, rz, rpm, tool, conditions, coefficients, feed) -> list[float]:
    """Semi-discretization limit [m] of the mean structure at each chosen configuration."""
    from .sdm import sdm_lobes

    rows = model.modes(np.column_stack([mid, rz]))
    normal = "y" if feed == "x" else "x"
    out = []
    for i, row in enumerate(rows):
        by_dir: dict[str, list] = {feed: [], normal: []}
        for d, pm in row.items():
            base = d.rstrip("0123456789") or d
            if base in by_dir:
                by_dir[base].append(pm.parameters)
        env = sdm_lobes(by_dir[feed], by_dir[normal], tool, conditions, coefficients,
                        [float(rpm[i])], steps_per_period=20)  # fmt: skip
        out.append(float(env.a_lim_m[0]))
    return out


def plot_path_plan(plan: PathPlan, *, color_by: str = "depth"):
    """Path coloured by allowed depth or P(stable), and Rz and speed along it.

    Parameters
    ----------
    plan : PathPlan
        The plan.
    color_by : {"depth", "p_stable"}
        What colours the path.

    Returns
    -------
    matplotlib.figure.Figure
    """
    import matplotlib.pyplot as plt

    if color_by not in ("depth", "p_stable"):
        raise ValueError(f"color_by must be 'depth' or 'p_stable', got {color_by!r}")
    fig, (ax0, ax1) = plt.subplots(1, 2, figsize=(11, 4.5))
    c = plan.depth_allowed_m * 1e3 if color_by == "depth" else plan.p_stable
    c = np.where(np.isfinite(c), c, np.nan)
    sc = ax0.scatter(plan.midpoints_mm[:, 0], plan.midpoints_mm[:, 1], c=c, cmap="viridis", s=40)
    ax0.plot(plan.midpoints_mm[:, 0], plan.midpoints_mm[:, 1], color="0.6", lw=0.8, zorder=0)
    fig.colorbar(sc, ax=ax0, label="allowed depth [mm]" if color_by == "depth" else "P(stable)")
    ax0.set(xlabel="X [mm]", ylabel="Y [mm]", title="tool path")
    ax0.set_aspect("equal", adjustable="datalim")
    s = np.concatenate([[0], np.cumsum(plan.length_mm)[:-1]]) + 0.5 * plan.length_mm
    ax1.step(s, plan.rz_deg, where="mid", color="C0", label="Rz [deg]")
    grid = plan.settings.get("rz_grid_deg") or [float(plan.rz_deg.min()), float(plan.rz_deg.max())]
    pad = max(5.0, 0.05 * (grid[-1] - grid[0]))
    ax1.set(xlabel="path length [mm]", ylabel="Rz [deg]", ylim=(grid[0] - pad, grid[-1] + pad))
    ax2 = ax1.twinx()
    ax2.step(s, plan.spindle_rpm, where="mid", color="C1", label="speed [rpm]")
    ax2.set_ylabel("spindle speed [rpm]")
    ax1.set_title(f"Rz and speed along the path (P(stable) >= {plan.settings['p_required']:g})")
    fig.tight_layout()
    fig.legend(loc="lower right", fontsize=8)
    return fig
