"""Sampled structures over the workspace and their zero-order stability limits, fast (issue 39).

**Sampled structures.** The pose model predicts, per pose, a calibrated predictive distribution
of every mode's latent fn, k and c (:meth:`robovib.gp.PoseModalModel.predictive`: per output a
mixture of a low and a high mode, each a Student-t with a calibrated scale). A *structure* is
one draw of that distribution at **every** pose at once: to learn at one pose from a test cut
at another, a draw must be a smooth function of the pose, not independent pose by pose. Each
output ``o`` of structure ``s`` carries a random field ``z_so(pose)`` with a standard-normal
marginal, built from ``n_features`` random Fourier features of a squared-exponential kernel
with ``correlation_length`` (x [mm], y [mm], Rz [deg]) (Rahimi & Recht, 2007)::

    z_so(u) = sqrt(2 / K) sum_k a_sok cos(w_ok . u / L + b_ok),   a ~ N(0, 1), w ~ N(0, I)

and the value at the pose is the calibrated quantile ``mean + scale * t_dof^-1(Phi(z))`` of the
pose's predictive component (marginals exact; the fields only add the correlation between
poses, which the independent-output GPs do not give). Where a mode switch is modelled, one more
field per direction picks the component (``Phi(z) < P(high)``). So at one pose the structures
are draws of the model's calibrated predictive distribution, like the draws of
:func:`robovib.milling.uncertainty.stability_probability`; across poses they are correlated
over ``correlation_length`` (a stated assumption: the model's own length scales are not
exposed through the public API). With ``shared_fraction = rho > 0`` a share of each field is
one workspace-wide deviation per structure, ``z = sqrt(1 - rho) z_local + sqrt(rho) g_so``,
``g ~ N(0, 1)``: the marginals stay exact and the correlation between any two poses is at
least ``rho`` (a campaign model biased as a whole, e.g. stiffer or softer everywhere, which a
test cut anywhere then learns).

Each structure also carries a **process factor** ``q_s``, log-uniform on ``process_factor``
(default 0.5-1.5), that multiplies its linear (zero-order) limit: linear theory assumes the
flutes never leave the cut, but a cut entering at full depth chatters 5-45 % below the linear
limit in the regenerative time-domain simulation (edge forces, the fly-over zone: see
:mod:`robovib.milling.time_domain`); modes the pose model does not have (a dominant-mode model
of a robot with more) move the limit either way (on the virtual robot up to +80 %: 16 mm
simulated against 9 mm for its dominant modes at 3000 rpm); the cutting coefficients are known
to some ±10 %. The factor is common to the whole workspace, so test cuts anywhere learn it
(:mod:`robovib.milling.cut_posterior`).

**What the prior gets wrong, measured (issue 39).** On the virtual robot (36-pose campaign, 22
random poses and speeds, 1 mm radial depth of the 25.4 mm two-flute cutter, seed 7): the
linear limits of a *dominant-mode* model's structures centre on the zero-order limit of the
truth's own dominant modes (median ratio 0.97, 10-90 % of the structures within x1.26): the
pose model's band is not what is wrong. The robot's time-domain limit (every mode, full-depth
entry) is a median 1.35x that limit (log sd 0.50): the modes the dominant model drops *raise*
the limit there, while the factor's prior (median 0.87) pulls it down, so the forecast is
pessimistic (mean P(stable) 0.31 at 0.8x the true limit). Two corrections of the linear limit
itself, not of the factor: a **multi-mode** pose model (:func:`robovib.campaign.
fit_multimode_pose_model`; its structures carry every tracked mode, and the time-domain limit
is then a median 0.90x their zero-order one), and the **SDM correction**
(:meth:`StructureSamples.with_sdm_correction`): at 4 % radial immersion the zero-order method
misses the flip lobes (up to 2.7x the SDM limit); with the truth's own modes the log sd of
time-domain / linear limit is 0.43 for the zero-order method and 0.23 for the SDM.

**Zero-order limits, batched.** For every structure, pose and spindle speed the critical depth
of Altintas & Budak's zero-order method (:mod:`robovib.milling.stability`, the same equations)
is found on a fixed log-spaced chatter-frequency grid: with ``u(f) = 60 f / (N n) - eps(f) /
2 pi`` a lobe crosses the speed ``n`` where ``u`` passes an integer; the depth there is
interpolated and the smallest over both eigenvalue branches is the limit (inf: no lobe). All in
NumPy over (structures x poses) in chunks: the search of a plan, where
:func:`~robovib.milling.uncertainty.stability_probability` (one SDM/ZOA call per sample) is the
check.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from .forces import CuttingCoefficients, CuttingConditions, MillingTool, engagement_angles
from .stability import directional_coefficients

__all__ = ["StructureSamples", "sample_structures", "zoa_limits"]

_PARAMS = ("fn_hz", "stiffness_n_per_m", "damping_ns_per_m")


@dataclass(frozen=True)
class StructureSamples:
    """Sampled structures of a pose model over the workspace (module docs).

    Attributes
    ----------
    model
        The pose model (``predictive(X)`` with inputs x_mm, y_mm, rz_deg).
    weights
        (S,) normalised weights of the structures (uniform: the prior; after test cuts: the
        posterior, :func:`robovib.milling.cut_posterior.update_with_cuts`).
    process_factor
        (S,) factor on each row's linear limit (drawn per structure; on a factor grid the
        grid point of each (structure, factor) row).
    correlation_length
        (x [mm], y [mm], Rz [deg]) of the fields.
    frequencies, phases, amplitudes
        The random Fourier features ``w`` (n_fields, K, 3), ``b`` (n_fields, K) and the
        structures' coefficients ``a`` (S, n_fields, K).
    settings
        How they were drawn.
    shared, shared_fraction
        (S, n_fields) standard-normal workspace-wide deviations ``g`` and the share ``rho`` of
        each field's variance they carry (module docs; None / 0: none).
    factor_grid
        None, or the (K,) process factors when every structure is K weighted rows
        (:meth:`on_factor_grid`; what :func:`~robovib.milling.cut_posterior.update_with_cuts`
        returns): ``weights`` and ``process_factor`` then have ``n_structures * K`` rows.
    sdm_correction
        Whether the zero-order limits are scaled by the point prediction's SDM / zero-order
        ratio (:meth:`with_sdm_correction`).
    local_factor
        None, or the (low, high) range of a log-uniform local factor drawn afresh at every cut
        and point on top of the rows' common factor (:meth:`on_factor_grid`).
    """

    model: object = field(repr=False, compare=False)
    weights: np.ndarray
    process_factor: np.ndarray
    correlation_length: tuple[float, float, float]
    frequencies: np.ndarray = field(repr=False)  #: (n_outputs + n_dirs, K, 3) w of the features
    phases: np.ndarray = field(repr=False)  #: (n_outputs + n_dirs, K) b
    amplitudes: np.ndarray = field(repr=False)  #: (S, n_outputs + n_dirs, K) a
    settings: dict = field(default_factory=dict)
    shared: np.ndarray | None = field(default=None, repr=False)  #: (S, n_outputs + n_dirs) g
    shared_fraction: float = 0.0
    #: (K,) the process-factor grid when the rows are (structure, factor) pairs
    #: (:meth:`on_factor_grid`), else None
    factor_grid: np.ndarray | None = field(default=None, repr=False)
    #: scale every structure's zero-order limit by the SDM / zero-order ratio of the model's
    #: point-prediction structure at the same pose and speed (:meth:`with_sdm_correction`)
    sdm_correction: bool = False
    #: (low, high) of a log-uniform local factor drawn afresh at every cut and point on top of
    #: the rows' (common) factor (:meth:`on_factor_grid` with ``local_factor``), else None
    local_factor: tuple[float, float] | None = None

    @property
    def n_samples(self) -> int:
        """Rows of the weights: structures, or (structure, factor) pairs on a factor grid."""
        return int(self.weights.size)

    @property
    def n_structures(self) -> int:
        """Structures drawn (fields), whatever their process factors."""
        return int(self.amplitudes.shape[0])

    def on_factor_grid(
        self,
        n_factors: int = 32,
        *,
        process_factor: tuple[float, float] | None = None,
        local_factor: tuple[float, float] | None = None,
    ) -> StructureSamples:
        """The structures with the process factor on a stratified grid (Rao-Blackwellised).

        Every structure ``s`` with weight ``w_s`` becomes ``K`` rows ``(s, k)`` with the factor
        ``q_k`` (:func:`robovib.milling.factor_grid.factor_grid` of the structures' own
        log-uniform range) and the weight ``w_s / K``: the prior of
        :mod:`robovib.milling.factor_grid`, where test cuts weight (structure, factor) pairs
        instead of one drawn factor per structure. Rows are structure-major (``s K + k``);
        the modes and linear limits are still computed once per structure.

        **The factor split** (``local_factor``): the structures' own factor is replaced by
        a common factor on ``process_factor`` (learnt by test cuts anywhere: e.g. the cutting
        coefficients, +-10 %) times a local factor log-uniform on ``local_factor``, drawn
        afresh at every cut and forecast point (where the pose and speed sit in their lobes:
        the time-domain / linear limit ratio, :mod:`robovib.milling.factor_grid`). The rows
        then carry the common factor; P(stable) and the depth allowed integrate the local one
        (:func:`~robovib.milling.factor_grid.local_p_stable`,
        :func:`~robovib.milling.factor_grid.local_quantile`).

        Parameters
        ----------
        n_factors : int
            Grid points ``K >= 1``.
        process_factor : (low, high), optional
            Range of the gridded (common) factor; default the structures' own range.
        local_factor : (low, high), optional
            Range of the local factor (``local_factor`` attribute); None: none.

        Returns
        -------
        StructureSamples
            ``n_samples = n_structures * K`` rows.

        Raises
        ------
        ValueError
            The structures are already on a factor grid.
        """
        from .factor_grid import factor_grid

        if self.factor_grid is not None:
            raise ValueError("the structures are already on a process-factor grid")
        if process_factor is None:
            lo, hi = self.settings.get(
                "process_factor_range",
                [float(self.process_factor.min()), float(self.process_factor.max())],
            )
        else:
            lo, hi = (float(v) for v in process_factor)
        q = factor_grid((lo, hi), n_factors)
        if local_factor is not None:
            loc = tuple(float(v) for v in local_factor)
            if len(loc) != 2 or not (np.all(np.isfinite(loc)) and 0 < loc[0] <= loc[1]):
                raise ValueError(f"local_factor must be 0 < low <= high, got {local_factor}")
            local_factor = loc
        n = self.n_structures
        w = np.repeat(self.weights, q.size) / q.size
        settings = dict(
            self.settings,
            n_factors=int(q.size),
            factor_grid="stratified quantiles of the log-uniform (bin medians)",
        )
        if process_factor is not None or local_factor is not None:
            settings["process_factor_range"] = [lo, hi]
            settings["local_factor_range"] = None if local_factor is None else list(local_factor)
        return replace(self, weights=w / w.sum(), process_factor=np.tile(q, n),
                       settings=settings, factor_grid=q, local_factor=local_factor)  # fmt: skip

    @property
    def structure_weights(self) -> np.ndarray:
        """(n_structures,) each structure's weight (on a factor grid: summed over its factors)."""
        if self.factor_grid is None:
            return self.weights
        return self.weights.reshape(self.n_structures, self.factor_grid.size).sum(axis=1)

    @property
    def effective_sample_size(self) -> float:
        """Kish's effective sample size of the structures, ``1 / sum w_s^2`` (on a factor grid
        ``w_s`` sums the structure's factors: how many structures still carry the forecast)."""
        return float(1.0 / np.sum(self.structure_weights**2))

    def with_weights(self, weights) -> StructureSamples:
        """The same structures with other weights (normalised here).

        Parameters
        ----------
        weights : array_like
            (S,) non-negative weights, not all zero.

        Returns
        -------
        StructureSamples
        """
        w = np.asarray(weights, float)
        if w.shape != self.weights.shape or np.any(~np.isfinite(w)) or np.any(w < 0):
            raise ValueError(f"weights must be {self.weights.shape} finite and >= 0")
        if w.sum() <= 0:
            raise ValueError("all weights are zero")
        return replace(self, weights=w / w.sum(), settings=dict(self.settings))

    def fields(self, poses) -> np.ndarray:
        """(S, P, n_fields) standard-normal fields at poses (x_mm, y_mm, rz_deg).

        Parameters
        ----------
        poses : array_like
            (P, 3) poses.

        Returns
        -------
        numpy.ndarray
            The field values.
        """
        u = _checked_poses(poses) / np.asarray(self.correlation_length)[None, :]
        k = self.phases.shape[1]
        arg = np.einsum("pd,fkd->pfk", u, self.frequencies) + self.phases[None]  # (P, F, K)
        local = np.sqrt(2.0 / k) * np.einsum("sfk,pfk->spf", self.amplitudes, np.cos(arg))
        rho = float(self.shared_fraction)
        if self.shared is None or rho == 0.0:
            return local
        return np.sqrt(1.0 - rho) * local + np.sqrt(rho) * self.shared[:, None, :]

    def modes(self, poses, feed_direction: str = "x"):
        """Modal parameters of every structure at poses, feed and normal modes side by side.

        Parameters
        ----------
        poses : array_like
            (P, 3) poses (x_mm, y_mm, rz_deg).
        feed_direction : {"x", "y"}
            Base-frame feed direction (the other horizontal one is the normal).

        Returns
        -------
        fn_hz, stiffness_n_per_m, damping_ratio : numpy.ndarray
            (S, P, M) each, one row per weight (on a factor grid: each structure's modes
            repeated for its ``K`` factors).
        in_feed : numpy.ndarray
            (M,) bool, True for the modes along the feed.
        """
        fn, k, zeta, in_feed = self._structure_modes(poses, feed_direction)
        if self.factor_grid is not None:
            rep = self.factor_grid.size
            fn, k, zeta = (np.repeat(a, rep, axis=0) for a in (fn, k, zeta))
        return fn, k, zeta, in_feed

    def _structure_modes(self, poses, feed_direction: str = "x"):
        """:meth:`modes` once per structure (n_structures rows)."""
        from scipy.special import ndtr, stdtrit

        if feed_direction not in ("x", "y"):
            raise ValueError(f"feed_direction must be 'x' or 'y', got {feed_direction!r}")
        x = _checked_poses(poses)
        pred = self.model.predictive(x)
        names = list(pred.output_names)
        z = self.fields(x)  # (S, P, n_fields)
        n_out = len(names)
        dirs = sorted(set(pred.directions), key=list(pred.directions).index)
        col_dir = np.array([dirs.index(d) for d in pred.directions])
        scale = pred.component_scale("latent")  # (P, n_out, 2)
        dof = np.broadcast_to(pred.dof[None], scale.shape)
        # component of each direction: a field of its own against P(high)
        p_dir = np.stack(
            [pred.high_probability[:, col_dir == j].max(axis=1) for j in range(len(dirs))], axis=1
        )
        high = (ndtr(z[:, :, n_out : n_out + len(dirs)]) < p_dir[None])[:, :, col_dir]
        prob = np.clip(ndtr(z[:, :, :n_out]), 1e-12, 1 - 1e-12)
        t = np.where(
            np.isfinite(dof[None]),
            stdtrit(np.where(np.isfinite(dof), dof, 1.0)[None], prob[..., None]),
            _ndtri(prob)[..., None],
        )  # (S, P, n_out, 2)
        draws = pred.mean[None] + scale[None] * t
        value = np.where(high, draws[..., 1], draws[..., 0])  # (S, P, n_out)
        feed, normal = feed_direction, "y" if feed_direction == "x" else "x"
        fn, k, zeta, in_feed = [], [], [], []
        for d in dirs:
            base = d.rstrip("0123456789") or d
            if base not in (feed, normal):
                continue
            cols = {p: names.index(f"{d}_{p}") for p in _PARAMS if f"{d}_{p}" in names}
            if len(cols) != 3:
                raise ValueError(f"the pose model's direction {d!r} lacks fn, k or c outputs")
            means = pred.point()[:, [cols[p] for p in _PARAMS]]  # (P, 3)
            vals = value[:, :, [cols[p] for p in _PARAMS]]
            # physical draws: a draw at or below 1 % of the mean is held there
            vals = np.maximum(vals, 0.01 * np.abs(means)[None])
            f_, k_, c_ = vals[..., 0], vals[..., 1], vals[..., 2]
            z_ = np.minimum(c_ * 2 * np.pi * f_ / (2 * k_), 0.99)
            fn.append(f_)
            k.append(k_)
            zeta.append(z_)
            in_feed.append(base == feed)
        if not any(in_feed) or all(in_feed):
            raise ValueError("the pose model needs modes in both the x and the y direction")
        return np.stack(fn, -1), np.stack(k, -1), np.stack(zeta, -1), np.array(in_feed)

    def limits(
        self,
        poses,
        spindle_rpm,
        tool: MillingTool,
        conditions: CuttingConditions,
        coefficients: CuttingCoefficients,
        *,
        feed_direction: str = "x",
        points_per_decade: float = 250.0,
        depth_cap_m: float = np.inf,
    ) -> np.ndarray:
        """(S, P, J) limits [m] of every structure at poses and speeds (factor included).

        Parameters
        ----------
        poses : array_like
            (P, 3) poses (x_mm, y_mm, rz_deg).
        spindle_rpm : array_like
            (J,) speeds [rpm].
        tool, conditions, coefficients
            Cutter, engagement (radial depth, up/down) and cutting coefficients.
        feed_direction : {"x", "y"}
            Base-frame feed direction.
        points_per_decade : float
            Density of the chatter-frequency grid (:func:`zoa_limits`).
        depth_cap_m : float
            Limits above this (after the process factor, and with a local factor after its
            lowest value) may be reported as inf.

        Returns
        -------
        numpy.ndarray
            Critical axial depths [m] (inf where no lobe reaches the speed).
        """
        cap = depth_cap_m / float(self.process_factor.min())
        if self.local_factor is not None:  # a row above the cap may still chatter below it
            cap = cap / self.local_factor[0]
        lim = self._linear_limits(poses, spindle_rpm, tool, conditions, coefficients,
                                  feed_direction, points_per_decade, cap)  # fmt: skip
        if self.factor_grid is not None:  # rows (s, k): structure-major
            lim = np.repeat(lim, self.factor_grid.size, axis=0)
        return lim * self.process_factor[:, None, None]

    def _linear_limits(self, poses, spindle_rpm, tool, conditions, coefficients, feed_direction,
                       points_per_decade, depth_cap_m) -> np.ndarray:  # fmt: skip
        """(n_structures, P, J) linear limits [m] without a process factor."""
        fn, k, zeta, in_feed = self._structure_modes(poses, feed_direction)
        if self.sdm_correction:  # a zero-order limit above the cap may be corrected below it
            depth_cap_m = np.inf
        lim = zoa_limits(fn, k, zeta, in_feed, spindle_rpm, tool, conditions, coefficients,
                         points_per_decade=points_per_decade, depth_cap_m=depth_cap_m)  # fmt: skip
        if self.sdm_correction:
            lim = lim * self.sdm_ratio(poses, spindle_rpm, tool, conditions, coefficients,
                                       feed_direction=feed_direction,
                                       points_per_decade=points_per_decade)[None]  # fmt: skip
        return lim

    def with_sdm_correction(self, on: bool = True) -> StructureSamples:
        """The same structures, their limits corrected by the SDM of the point prediction.

        The zero-order method averages the directional factors over the tooth period; at low
        radial immersion it misses the period-doubling (flip) lobes, and its limit lies far
        above the semi-discretization's there (on the virtual robot at 1 mm of a 25.4 mm cutter:
        up to 1.9x, at 5 of 22 poses and speeds). With the correction each structure's
        zero-order limit ``a_s(u, n)`` becomes ``a_s(u, n) r(u, n)``, ``r = a_SDM / a_ZOA`` of
        the model's point-prediction structure at the pose and speed (:meth:`sdm_ratio`): the
        flip lobes at the lobe positions of the point prediction (a first-order transfer; the
        structures' own lobes shift a little with their frequencies). One SDM per pose and
        speed: for forecasts at tens to hundreds of points, not for a plan's whole grid.

        Parameters
        ----------
        on : bool
            Correct (True) or plain zero-order limits.

        Returns
        -------
        StructureSamples
        """
        return replace(self, sdm_correction=bool(on),
                       settings=dict(self.settings, sdm_correction=bool(on)))  # fmt: skip

    def sdm_ratio(self, poses, spindle_rpm, tool: MillingTool, conditions: CuttingConditions,
                  coefficients: CuttingCoefficients, *, feed_direction: str = "x",
                  points_per_decade: float = 250.0) -> np.ndarray:  # fmt: skip
        """(P, J) semi-discretization / zero-order limit of the point-prediction structure.

        The point prediction is the structure whose fields are all zero (every output at the
        median of its more probable component). 1 where neither method finds a finite limit.

        Parameters
        ----------
        poses : array_like
            (P, 3) poses (x_mm, y_mm, rz_deg).
        spindle_rpm : array_like
            (J,) speeds [rpm].
        tool, conditions, coefficients
            Cutter, engagement and cutting coefficients.
        feed_direction : {"x", "y"}
            Base-frame feed direction.
        points_per_decade : float
            Grid of the zero-order search (:func:`zoa_limits`).

        Returns
        -------
        numpy.ndarray
            The ratios.
        """
        from ..modal.parameters import ModalParameters
        from .sdm import sdm_lobes

        point = replace(
            self, weights=np.ones(1), process_factor=np.ones(1), factor_grid=None,
            amplitudes=np.zeros((1, *self.amplitudes.shape[1:])), shared=None,
            shared_fraction=0.0, sdm_correction=False,
        )  # fmt: skip
        fn, k, zeta, in_feed = point._structure_modes(poses, feed_direction)
        rpm = np.atleast_1d(np.asarray(spindle_rpm, float))
        zoa = zoa_limits(
            fn,
            k,
            zeta,
            in_feed,
            rpm,
            tool,
            conditions,
            coefficients,
            points_per_decade=points_per_decade,
        )[0]  # fmt: skip  (P, J)
        ratio = np.ones_like(zoa)
        for p in range(zoa.shape[0]):
            modes = [ModalParameters(fn[0, p, j], k[0, p, j], zeta[0, p, j])
                     for j in range(fn.shape[2])]  # fmt: skip
            mx = [m for m, f in zip(modes, in_feed, strict=True) if f]
            my = [m for m, f in zip(modes, in_feed, strict=True) if not f]
            sdm = np.asarray(sdm_lobes(mx, my, tool, conditions, coefficients, rpm).a_lim_m)
            ok = np.isfinite(sdm) & np.isfinite(zoa[p]) & (sdm > 0)
            ratio[p, ok] = sdm[ok] / zoa[p, ok]
        return ratio


def _ndtri(p):
    from scipy.special import ndtri

    return ndtri(p)


def _checked_poses(poses) -> np.ndarray:
    x = np.atleast_2d(np.asarray(poses, float))
    if x.ndim != 2 or x.shape[1] != 3:
        raise ValueError(f"poses must be (n, 3) x_mm, y_mm, rz_deg; got shape {x.shape}")
    if not np.all(np.isfinite(x)):
        raise ValueError("poses contain NaN or inf")
    return x


def sample_structures(
    model,
    n_samples: int = 64,
    *,
    correlation_length: tuple[float, float, float] = (300.0, 450.0, 45.0),
    process_factor: tuple[float, float] = (0.5, 1.5),
    n_features: int = 64,
    shared_fraction: float = 0.0,
    rng=0,
) -> StructureSamples:
    """Draw structures of a pose model over the workspace (module docs).

    Parameters
    ----------
    model
        A fitted pose model with ``predictive(X)`` (:class:`robovib.gp.PoseModalModel`,
        dominant or multi-mode) and inputs x_mm, y_mm, rz_deg.
    n_samples : int
        Structures drawn.
    correlation_length : (x [mm], y [mm], Rz [deg])
        Correlation lengths of the fields over the pose.
    process_factor : (low, high)
        Range of the log-uniform factor on the linear limit (``(1, 1)``: linear theory as is).
    n_features : int
        Random Fourier features per field.
    shared_fraction : float
        Share ``rho`` in [0, 1) of each field's variance that is one workspace-wide deviation
        per structure and output (``z = sqrt(1 - rho) field(u) + sqrt(rho) g``: marginals
        unchanged; a pose model biased as a whole, which test cuts anywhere can learn).
    rng : int or numpy.random.Generator
        Seed.

    Returns
    -------
    StructureSamples
        With uniform (prior) weights.
    """
    if not hasattr(model, "predictive"):
        raise TypeError(f"{type(model).__name__} has no predictive(X): not a pose model")
    names = getattr(model, "input_names", None)
    if names is not None and tuple(names) != ("x_mm", "y_mm", "rz_deg"):
        raise ValueError(f"the pose model's inputs must be x_mm, y_mm, rz_deg; got {names}")
    n = int(n_samples)
    if n < 2:
        raise ValueError(f"n_samples must be >= 2, got {n_samples}")
    lo, hi = (float(v) for v in process_factor)
    if not 0 < lo <= hi:
        raise ValueError(f"process_factor must be 0 < low <= high, got {process_factor}")
    length = tuple(float(v) for v in correlation_length)
    if len(length) != 3 or not all(np.isfinite(v) and v > 0 for v in length):
        raise ValueError(f"correlation_length must be 3 positive numbers, got {correlation_length}")
    gen = np.random.default_rng(rng)
    probe = model.predictive(np.array([[2400.0, 0.0, 90.0]]))
    n_fields = len(probe.output_names) + len(set(probe.directions))
    kf = int(n_features)
    freq = gen.normal(size=(n_fields, kf, 3))
    phase = gen.uniform(0, 2 * np.pi, size=(n_fields, kf))
    amp = gen.normal(size=(n, n_fields, kf))
    factor = np.exp(gen.uniform(np.log(lo), np.log(hi), n))
    rho = float(shared_fraction)
    if not 0.0 <= rho < 1.0:
        raise ValueError(f"shared_fraction must be in [0, 1), got {shared_fraction!r}")
    # drawn after the rest, so that rho = 0 leaves every other draw of a seed as it was
    shared = gen.normal(size=(n, n_fields)) if rho > 0 else None
    return StructureSamples(
        model, np.full(n, 1.0 / n), factor, length, freq, phase, amp,
        {"n_samples": n, "n_features": kf, "correlation_length_mm_mm_deg": list(length),
         "process_factor_range": [lo, hi], "seed": rng if isinstance(rng, int) else None,
         "sampling": "random-Fourier-feature fields over the pose through the calibrated "
                     "latent predictive quantiles (Student-t, mode mixture)",
         "shared_fraction": rho},
        shared, rho,
    )  # fmt: skip


def zoa_limits(
    fn_hz,
    stiffness_n_per_m,
    damping_ratio,
    in_feed,
    spindle_rpm,
    tool: MillingTool,
    conditions: CuttingConditions,
    coefficients: CuttingCoefficients,
    *,
    points_per_decade: float = 250.0,
    chunk: int = 256,
    depth_cap_m: float = np.inf,
) -> np.ndarray:
    """Zero-order critical depths [m] of many structures at many speeds (module docs).

    Parameters
    ----------
    fn_hz, stiffness_n_per_m, damping_ratio : array_like
        (..., M) modes of each structure (batch axes first).
    in_feed : array_like
        (M,) bool: the mode is along the feed (x of the zero-order method), else normal (y).
    spindle_rpm : array_like
        (J,) speeds [rpm].
    tool, conditions, coefficients
        Cutter, engagement and cutting coefficients.
    points_per_decade : float
        Chatter frequencies per decade of a fixed log grid, from half the lowest to twice the
        highest mode (250: < 1.5 % from the converged limit).
    chunk : int
        Structures per NumPy batch (memory).
    depth_cap_m : float
        Depths above this are not searched (reported as inf): a planner that never cuts deeper
        skips most of the frequency grid.

    Returns
    -------
    numpy.ndarray
        (..., J) critical depths [m], inf where no lobe reaches the speed.
    """
    fn = np.asarray(fn_hz, float)
    kk = np.broadcast_to(np.asarray(stiffness_n_per_m, float), fn.shape)
    zz = np.broadcast_to(np.asarray(damping_ratio, float), fn.shape)
    feed = np.asarray(in_feed, bool)
    if feed.shape != fn.shape[-1:]:
        raise ValueError(f"in_feed must be ({fn.shape[-1]},), got {feed.shape}")
    if not (np.all(fn > 0) and np.all(kk > 0) and np.all((zz > 0) & (zz < 1))):
        raise ValueError("modes must have fn > 0, k > 0 and 0 < zeta < 1")
    rpm = np.atleast_1d(np.asarray(spindle_rpm, float))
    if np.any(~np.isfinite(rpm)) or np.any(rpm <= 0):
        raise ValueError("spindle_rpm must be positive speeds")
    batch = fn.shape[:-1]
    m = fn.shape[-1]
    fn2, k2, z2 = fn.reshape(-1, m), kk.reshape(-1, m), zz.reshape(-1, m)
    phi_st, phi_ex = engagement_angles(tool, conditions)
    axx, axy, ayx, ayy = directional_coefficients(
        phi_st, phi_ex, coefficients.krc / coefficients.ktc
    )
    n_fl = int(tool.n_flutes)
    # a fixed log grid (points at 10^(i / points_per_decade) Hz): any batch of structures sees
    # the same frequencies, so a limit does not depend on what else was computed with it
    ppd = float(points_per_decade)
    if not ppd >= 10:
        raise ValueError(f"points_per_decade must be >= 10, got {points_per_decade!r}")
    i0 = np.floor(ppd * np.log10(0.5 * fn2.min()))
    i1 = np.ceil(ppd * np.log10(2.0 * fn2.max()))
    f = 10.0 ** (np.arange(i0, i1 + 1) / ppd)
    out = np.empty((fn2.shape[0], rpm.size))
    turns = 60.0 * f[None, :] / (n_fl * rpm[:, None])  # (J, F) tooth periods per chatter period
    for a in range(0, fn2.shape[0], int(chunk)):
        sl = slice(a, a + int(chunk))
        r = f[None, None, :] / fn2[sl, :, None]  # (B, M, F)
        g = 1.0 / (k2[sl, :, None] * (1 - r**2 + 2j * z2[sl, :, None] * r))
        gxx = np.where(feed[None, :, None], g, 0).sum(axis=1)
        gyy = np.where(feed[None, :, None], 0, g).sum(axis=1)
        a0 = gxx * gyy * (axx * ayy - axy * ayx)
        a1 = axx * gxx + ayy * gyy
        with np.errstate(divide="ignore", invalid="ignore"):
            disc = np.sqrt(a1**2 - 4 * a0)
            small = np.abs(a0) < 1e-300
            lam = np.stack(
                [
                    np.where(small, -1.0 / a1, -(a1 + disc) / (2 * a0)),
                    np.where(small, np.nan, -(a1 - disc) / (2 * a0)),
                ]
            )  # fmt: skip  (2, B, F)
            lr, li = lam.real, lam.imag
            kappa = li / lr
            depth = -2 * np.pi * lr * (1 + kappa**2) / (n_fl * coefficients.ktc)
            eps = np.pi - 2 * np.arctan(kappa)
        valid = np.isfinite(depth) & (depth > 0) & (depth < depth_cap_m)
        # only the frequencies where some structure of the chunk has a lobe below the cap
        cols = np.flatnonzero(valid.any(axis=(0, 1)))
        if cols.size < 2:
            out[sl] = np.inf
            continue
        cols = np.arange(cols[0], cols[-1] + 1)
        valid, depth, eps = valid[..., cols], depth[..., cols], eps[..., cols]
        tn = turns[:, cols]
        # single precision for the (branch, structure, speed, frequency) search: ~2x faster,
        # 1e-7 relative, far below the frequency grid's error (< 1.5 % at 250 per decade)
        u = (
            tn.astype(np.float32)[None, None]
            - (eps / (2 * np.pi)).astype(np.float32)[:, :, None, :]
        )  # (2, B, J, F)
        lobe = np.floor(u)
        hi_l, lo_l = lobe[..., 1:], lobe[..., :-1]
        ok = (hi_l != lo_l) & (valid[..., 1:] & valid[..., :-1])[:, :, None, :]
        target = np.maximum(hi_l, lo_l)
        ok &= target >= 0  # lobe k = 0, 1, ...: 60 f / (N n) = k + eps / 2 pi
        du = u[..., 1:] - u[..., :-1]
        with np.errstate(divide="ignore", invalid="ignore"):
            w = np.clip((target - u[..., :-1]) / du, 0, 1)
        d0 = depth[:, :, :-1].astype(np.float32)[:, :, None, :]
        dd = np.diff(depth, axis=-1).astype(np.float32)[:, :, None, :]
        at = np.where(ok, d0 + w * dd, np.float32(np.inf))
        out[sl] = at.min(axis=(0, 3))
    return out.reshape(*batch, rpm.size)
