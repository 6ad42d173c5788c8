"""The predictive distribution of a pose model at a pose: latent and measurement, mode mixture.

A pose model answers two different questions, and its bands must say which (issue 24):

* **latent** — where is the robot's modal parameter at this pose (the GP's posterior of the
  function, thesis Eq. 10)? This is what the stability lobes, the controller design and the
  next-pose choice need.
* **measurement** — where will the next hammer test at this pose land (latent plus the
  test-to-test scatter, the GP's noise variance)? This is what a held-out measurement checks.

Each output is a mixture of at most two components (the low and the high mode of a direction
with a mode switch, weights ``1 − p`` and ``p``; one component elsewhere), each a location-scale
Student-t (Gaussian for ``dof = inf``) with

    scale_latent      = c · σ_ref^(1−γ) · σ_latent^γ
    scale_measurement = √(scale_latent² + σ_noise²)

where ``c``, ``γ`` (with the reference std ``σ_ref``) and ``dof`` are the calibration of that
output and mode, estimated from grouped cross-validation (:mod:`robovib.gp.calibration`);
``c = 1, γ = 1, dof = inf`` is the plain GP. The
calibration scales the latent part only: the test-to-test scatter ``σ_noise`` is what replicated
tests measure directly, the GP's overconfidence is about the pose dependence between them.

The ``level`` set of a mixture is its highest-density region: one interval where the modes
overlap or one dominates, two where the prediction is genuinely bimodal
(:meth:`ModalPredictive.intervals`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["ModalPredictive"]

_KINDS = ("latent", "measurement")
# Below this weight a component does not change a 95 % set by more than the grid resolution.
_NEGLIGIBLE = 1e-4


_lgamma = np.vectorize(math.lgamma, otypes=[float])
_erf = np.vectorize(math.erf, otypes=[float])


def _t_logpdf(z: np.ndarray, dof: np.ndarray) -> np.ndarray:
    """Log density of the standard Student-t (Gaussian where ``dof = inf``); NumPy only."""
    z = np.asarray(z, float)
    dof = np.broadcast_to(np.asarray(dof, float), z.shape)
    gauss = -0.5 * z * z - 0.5 * np.log(2.0 * np.pi)
    finite = np.isfinite(dof)
    if not finite.any():
        return gauss
    v = np.where(finite, dof, 1.0)
    uniq, inv = np.unique(v, return_inverse=True)
    norm = (_lgamma(0.5 * (uniq + 1.0)) - _lgamma(0.5 * uniq) - 0.5 * np.log(uniq * np.pi))[
        inv.reshape(v.shape)
    ]
    t = norm - 0.5 * (v + 1.0) * np.log1p(z * z / v)
    return np.where(finite, t, gauss)


def _t_cdf_integer(z: np.ndarray, dof: int) -> np.ndarray:
    """Student-t CDF for an integer ``dof`` in closed form (Abramowitz & Stegun 26.7.3-4)."""
    theta = np.arctan(z / math.sqrt(dof))
    c2 = np.cos(theta) ** 2
    s = np.sin(theta)
    if dof % 2 == 1:
        term, acc = np.cos(theta), np.zeros_like(z)
        if dof > 1:
            acc = term.copy()
            for k in range(3, dof - 1, 2):  # 2/3 cos³, (2·4)/(3·5) cos⁵, ...
                term = term * c2 * (k - 1) / k
                acc = acc + term
        a = (2.0 / math.pi) * (theta + s * acc)
    else:
        term = np.ones_like(z)
        acc = term.copy()
        for k in range(2, dof - 1, 2):  # 1/2 cos², (1·3)/(2·4) cos⁴, ...
            term = term * c2 * (k - 1) / k
            acc = acc + term
        a = s * acc
    return 0.5 + 0.5 * a  # a carries the sign of z (sin θ, θ odd in z)


def _t_cdf(z: np.ndarray, dof: np.ndarray) -> np.ndarray:
    """Standard Student-t CDF (Gaussian for ``dof = inf``); NumPy only for integer dof."""
    z = np.asarray(z, float)
    dof = np.broadcast_to(np.asarray(dof, float), z.shape)
    out = np.empty(z.shape)
    gauss = ~np.isfinite(dof)
    out[gauss] = 0.5 * (1.0 + _erf(z[gauss] / math.sqrt(2.0)))
    for v in np.unique(dof[~gauss], return_inverse=True)[0]:  # plain unique imports numpy.ma
        sel = dof == v
        if float(v).is_integer() and v >= 1:
            out[sel] = _t_cdf_integer(z[sel], int(v))
        else:  # non-integer tails: SciPy's incomplete beta
            from scipy.special import stdtr

            out[sel] = stdtr(v, z[sel])
    return out


def t_quantile(q: float, dof) -> np.ndarray:
    """Standard Student-t quantile (Gaussian for ``dof = inf``), by Newton's method on
    :func:`_t_cdf`.

    Each distinct ``dof`` once: for ``q > 1/2`` Newton's iteration starts at 0 and, the CDF
    being concave on the positive half-line, climbs monotonically to the root (no overshoot,
    so no bracket is needed); ``q < 1/2`` by symmetry.

    Parameters
    ----------
    q
        Probability in (0, 1).
    dof
        Degrees of freedom (array; ``inf`` = Gaussian).

    Returns
    -------
    ndarray
        Quantiles, shape of ``dof``, to ~1e-13 relative.
    """
    dof = np.asarray(dof, float)
    q = float(q)
    uniq, inv = np.unique(dof, return_inverse=True)
    p = max(q, 1.0 - q)
    x = np.zeros(uniq.shape)
    if p > 0.5:
        for _ in range(200):
            step = (p - _t_cdf(x, uniq)) / np.exp(_t_logpdf(x, uniq))
            x = x + np.maximum(step, 0.0)  # below the root: the step is >= 0 (rounding aside)
            if np.all(step <= 1e-14 * (1.0 + x)):
                break
    return (x if q >= 0.5 else -x)[inv.reshape(dof.shape)]


def recalibrated_probability(p: np.ndarray, mode_logit: np.ndarray) -> np.ndarray:
    """``σ(a logit p + b)`` per output column (``mode_logit`` (n_outputs, 2); NaN: unchanged)."""
    p = np.asarray(p, float)
    a, b = mode_logit[:, 0], mode_logit[:, 1]
    keep = ~np.isfinite(a)
    q = np.clip(p, 1e-12, 1 - 1e-12)
    z = np.where(keep, 0.0, a) * np.log(q / (1 - q)) + np.where(keep, 0.0, b)
    return np.where(keep, p, 1.0 / (1.0 + np.exp(-z)))


def calibrated_mode_probability(p: np.ndarray, calibration) -> np.ndarray:
    """(n, n_directions) high-mode probabilities after the calibration's Platt scaling (the
    direction's first output row of ``calibration.mode_logit``); unchanged without one."""
    logit = None if calibration is None else getattr(calibration, "mode_logit", None)
    if logit is None:
        return p
    return recalibrated_probability(p, np.asarray(logit, float)[0::3])


@dataclass(frozen=True)
class ModalPredictive:
    """Predictive distribution of ``n_outputs`` modal outputs at ``n`` poses.

    Attributes
    ----------
    output_names, output_units
        Names (``"x_fn_hz"``, ...) and unit labels of the outputs.
    directions
        Direction of each output (outputs of one direction share the mode indicator).
    high_probability
        (n, n_outputs) weight of the high-mode component (0 where no switch is modelled).
    mean, latent_std, noise_std
        (n, n_outputs, 2) per component [low, high] (SI); the high component repeats the low
        one where no switch is modelled.
    scale, dof
        (n_outputs, 2) calibration factor ``c`` of the latent std and Student-t degrees of
        freedom per component.
    gamma, ref_std
        (n_outputs, 2) or None: how much of the GP's pose-to-pose variation of the latent std
        the calibrated band keeps, ``σ → ref^(1-γ) σ^γ`` (None: ``γ = 1``).
    """

    output_names: tuple[str, ...]
    output_units: tuple[str, ...]
    directions: tuple[str, ...]
    high_probability: np.ndarray
    mean: np.ndarray
    latent_std: np.ndarray
    noise_std: np.ndarray
    scale: np.ndarray
    dof: np.ndarray
    gamma: np.ndarray | None = None
    ref_std: np.ndarray | None = None

    def with_calibration(
        self, scale, dof, gamma=None, ref_std=None, mode_logit=None
    ) -> ModalPredictive:
        """The same components with another calibration ((n_outputs, 2) arrays; ``gamma`` and
        ``ref_std`` default to the plain GP's shape of the band, ``gamma = 1``).

        ``mode_logit`` (n_outputs, 2) ``(a, b)`` recalibrates the classifier's probability of the
        high mode, ``p → σ(a logit p + b)`` (Platt scaling; NaN rows: unchanged).

        Parameters
        ----------
        scale, dof : array_like
            (n_outputs, 2) calibration factor and Student-t dof per component.
        gamma, ref_std : array_like, optional
            (n_outputs, 2) shape of the band and its reference latent std.
        mode_logit : array_like, optional
            (n_outputs, 2) Platt scaling of the high-mode probability.

        Returns
        -------
        ModalPredictive
            The recalibrated predictive.
        """
        from dataclasses import replace

        p = self.high_probability
        if mode_logit is not None:
            p = recalibrated_probability(p, np.asarray(mode_logit, float))
        return replace(
            self,
            high_probability=p,
            scale=np.asarray(scale, float),
            dof=np.asarray(dof, float),
            gamma=None if gamma is None else np.asarray(gamma, float),
            ref_std=None if ref_std is None else np.asarray(ref_std, float),
        )

    def shaped_latent_std(self) -> np.ndarray:
        """(n, n_outputs, 2) ``ref^(1-γ) σ_latent^γ``: the GP's latent std with the pose
        dependence of its band tempered by ``γ`` (1: the GP's own; 0: the same at every pose).

        Returns
        -------
        numpy.ndarray
            (n, n_outputs, 2) shaped latent std, SI.
        """
        if self.gamma is None:
            return self.latent_std
        ref = self.ref_std[None]
        g = self.gamma[None]
        return ref * (np.maximum(self.latent_std, 1e-300) / ref) ** g

    # ------------------------------------------------------------------ components
    def _check_kind(self, kind: str) -> None:
        if kind not in _KINDS:
            raise ValueError(f"unknown band kind {kind!r}; expected 'latent' or 'measurement'")

    def component_scale(self, kind: str = "measurement") -> np.ndarray:
        """(n, n_outputs, 2) calibrated scale of each component (SI).

        Parameters
        ----------
        kind : {"measurement", "latent"}
            Band of a new measurement or of the latent value.

        Returns
        -------
        numpy.ndarray
            (n, n_outputs, 2) scales.
        """
        self._check_kind(kind)
        latent = self.scale[None] * self.shaped_latent_std()
        return latent if kind == "latent" else np.hypot(latent, self.noise_std)

    @property
    def weights(self) -> np.ndarray:
        """(n, n_outputs, 2) component weights [1 − p, p]."""
        p = self.high_probability
        return np.stack([1.0 - p, p], axis=-1)

    def point(self) -> np.ndarray:
        """(n, n_outputs) the more probable component's mean (never a blend of two modes).

        Returns
        -------
        numpy.ndarray
            (n, n_outputs) point predictions, SI.
        """
        hi = self.high_probability > 0.5
        return np.where(hi, self.mean[..., 1], self.mean[..., 0])

    def point_std(self, kind: str = "latent") -> np.ndarray:
        """(n, n_outputs) calibrated standard deviation of the more probable component.

        For ``dof`` <= 2 the Student-t variance is infinite; the scale is returned then.

        Parameters
        ----------
        kind : {"measurement", "latent"}
            Band of a new measurement or of the latent value.

        Returns
        -------
        numpy.ndarray
            (n, n_outputs) standard deviations, SI.
        """
        s = self.component_scale(kind)
        dof = np.broadcast_to(self.dof[None], s.shape)
        heavy = np.isfinite(dof) & (dof > 2)
        factor = np.ones_like(s)
        factor[heavy] = np.sqrt(dof[heavy] / (dof[heavy] - 2.0))
        s = s * factor
        hi = self.high_probability > 0.5
        return np.where(hi, s[..., 1], s[..., 0])

    # ------------------------------------------------------------------ densities
    def logpdf(self, Y, kind: str = "measurement") -> np.ndarray:
        """(n, n_outputs) log predictive density of ``Y`` (SI, NaN stays NaN).

        Parameters
        ----------
        Y : array_like
            (n, n_outputs) values, SI.
        kind : {"measurement", "latent"}
            Band of a new measurement or of the latent value.

        Returns
        -------
        numpy.ndarray
            (n, n_outputs) log densities.
        """
        Y = self._check_Y(Y)
        s = self.component_scale(kind)
        z = (Y[..., None] - self.mean) / s
        lp = _t_logpdf(z, np.broadcast_to(self.dof[None], z.shape)) - np.log(s)
        with np.errstate(divide="ignore"):
            lw = np.log(self.weights)
        return np.logaddexp(lw[..., 0] + lp[..., 0], lw[..., 1] + lp[..., 1])

    def cdf(self, Y, kind: str = "measurement") -> np.ndarray:
        """(n, n_outputs) predictive CDF at ``Y``: the PIT value of an observation.

        Parameters
        ----------
        Y : array_like
            (n, n_outputs) values, SI.
        kind : {"measurement", "latent"}
            Band of a new measurement or of the latent value.

        Returns
        -------
        numpy.ndarray
            (n, n_outputs) CDF values.
        """
        Y = self._check_Y(Y)
        s = self.component_scale(kind)
        z = (Y[..., None] - self.mean) / s
        c = _t_cdf(z, np.broadcast_to(self.dof[None], z.shape))
        return np.sum(self.weights * c, axis=-1)

    def _check_Y(self, Y) -> np.ndarray:
        Y = np.asarray(Y, float)
        if Y.ndim == 1:
            Y = Y[None]
        if Y.shape != self.high_probability.shape:
            raise ValueError(
                f"Y must have shape {self.high_probability.shape} (poses, outputs), got {Y.shape}"
            )
        return Y

    # ------------------------------------------------------------------ sets
    def intervals(self, level: float = 0.95, kind: str = "measurement") -> list[list[list]]:
        """The ``level`` highest-density set of every output at every pose.

        Parameters
        ----------
        level
            Probability content, in (0, 1).
        kind
            ``"measurement"`` (a new hammer test) or ``"latent"`` (the modal parameter).

        Returns
        -------
        list (n) of list (n_outputs) of list of ``(low, high)`` intervals, SI: one interval, or
        two where the prediction is bimodal (a mode switch the model is unsure of).

        Raises
        ------
        ValueError
            ``level`` outside (0, 1) or an unknown ``kind``.
        """
        if not 0.0 < level < 1.0:
            raise ValueError(f"level must be in (0, 1), got {level}")
        s = self.component_scale(kind)
        w = self.weights
        q = t_quantile(0.5 + 0.5 * level, self.dof)  # (n_out, 2)
        q_wide = t_quantile(1.0 - 1e-4, self.dof)
        out = []
        for i in range(w.shape[0]):
            row = []
            for j in range(w.shape[1]):
                comps = [c for c in (0, 1) if w[i, j, c] > _NEGLIGIBLE]
                if len(comps) == 1 or (
                    np.isclose(self.mean[i, j, 0], self.mean[i, j, 1])
                    and np.isclose(s[i, j, 0], s[i, j, 1])
                ):
                    c = comps[0] if len(comps) == 1 else 0
                    half = q[j, c] * s[i, j, c]
                    row.append(
                        [(float(self.mean[i, j, c] - half), float(self.mean[i, j, c] + half))]
                    )
                else:
                    row.append(self._hpd(i, j, level, s[i, j], q_wide[j]))
            out.append(row)
        return out

    def _hpd(self, i: int, j: int, level: float, s: np.ndarray, q_wide: np.ndarray) -> list:
        mu = self.mean[i, j]
        lo = float(np.min(mu - 1.5 * q_wide * s))
        hi = float(np.max(mu + 1.5 * q_wide * s))
        grid = np.linspace(lo, hi, 8001)
        z = (grid[:, None] - mu) / s
        dens = np.sum(
            self.weights[i, j] * np.exp(_t_logpdf(z, np.broadcast_to(self.dof[j], z.shape))) / s,
            axis=1,
        )
        order = np.argsort(dens)[::-1]
        mass = np.cumsum(dens[order]) * (grid[1] - grid[0])
        cut = dens[order][min(np.searchsorted(mass, level * mass[-1]), grid.size - 1)]
        inside = dens >= cut
        edges = np.flatnonzero(np.diff(np.concatenate([[0], inside.astype(int), [0]])))
        return [
            (float(grid[a]), float(grid[b - 1]))
            for a, b in zip(edges[::2], edges[1::2], strict=True)
        ]

    def contains(self, Y, level: float = 0.95, kind: str = "measurement") -> np.ndarray:
        """(n, n_outputs) bool: ``Y`` lies in the ``level`` set (NaN targets give False).

        Parameters
        ----------
        Y : array_like
            (n, n_outputs) values, SI.
        level : float
            Probability of the set.
        kind : {"measurement", "latent"}
            Band of a new measurement or of the latent value.

        Returns
        -------
        numpy.ndarray
            (n, n_outputs) bool.
        """
        Y = self._check_Y(Y)
        sets = self.intervals(level, kind)
        return np.array(
            [
                [any(a <= y <= b for a, b in iv) for y, iv in zip(yr, row, strict=True)]
                for yr, row in zip(Y, sets, strict=True)
            ],
            dtype=bool,
        )

    # ------------------------------------------------------------------ sampling
    def sample(self, n_samples: int, rng=None, kind: str = "latent") -> np.ndarray:
        """Joint draws (n_samples, n, n_outputs): the mode is drawn once per direction and pose.

        The fn, k and c of a direction come from the same mode (the only correlation the
        independent-output GPs carry); within a mode the outputs are drawn independently.

        Parameters
        ----------
        n_samples : int
            Number of draws.
        rng : int or numpy.random.Generator, optional
            Seed.
        kind : {"measurement", "latent"}
            Band of a new measurement or of the latent value.

        Returns
        -------
        numpy.ndarray
            (n_samples, n, n_outputs) draws, SI.
        """
        rng = np.random.default_rng(rng)
        s = self.component_scale(kind)
        n, n_out = self.high_probability.shape
        dirs = sorted(set(self.directions), key=self.directions.index)
        col_dir = np.array([dirs.index(d) for d in self.directions])
        u = rng.random((n_samples, n, len(dirs)))
        # One representative probability per direction (all outputs of a direction share it).
        p_dir = np.stack(
            [self.high_probability[:, col_dir == k].max(axis=1) for k in range(len(dirs))], axis=1
        )
        high = (u < p_dir[None])[:, :, col_dir]  # (S, n, n_out)
        dof = np.broadcast_to(self.dof[None, None], (n_samples, n, n_out, 2))
        t = np.where(
            np.isfinite(dof),
            rng.standard_t(np.where(np.isfinite(dof), dof, 1.0)),
            rng.standard_normal(dof.shape),
        )
        draws = self.mean[None] + s[None] * t
        return np.where(high, draws[..., 1], draws[..., 0])


def noise_std_of(hyperparameters) -> np.ndarray:
    """(B,) noise std of the first (reference) noise group, data units."""
    noise = np.asarray(hyperparameters.noise_std, float)
    return noise[:, 0] if noise.ndim == 2 else noise


#: Relative latent std given to a mode seen fewer than 3 times (no GP of its own).
UNMODELLED_MODE_RELATIVE_STD = 0.1


def assemble(
    output_names,
    output_units,
    directions,
    n: int,
    parts,
    scale=None,
    dof=None,
    gamma=None,
    ref_std=None,
    mode_logit=None,
) -> ModalPredictive:
    """Build a :class:`ModalPredictive` from per-estimator components.

    ``parts``: iterable of ``(columns, p_high or None, low, high or None)`` with ``low`` and
    ``high`` = ``(mean, latent_std, noise_std)``, arrays (n, len(columns)) or broadcastable.
    """
    n_out = len(output_names)
    p = np.zeros((n, n_out))
    mean = np.empty((n, n_out, 2))
    lat = np.empty((n, n_out, 2))
    noise = np.empty((n, n_out, 2))
    for cols, p_high, low, high in parts:
        cols = np.asarray(cols, int)
        for c, comp in ((0, low), (1, low if high is None else high)):
            m, s, e = (np.broadcast_to(np.asarray(a, float), (n, cols.size)) for a in comp)
            mean[:, cols, c], lat[:, cols, c], noise[:, cols, c] = m, s, e
        if p_high is not None:
            p[:, cols] = np.asarray(p_high, float)[:, None]
    scale = np.ones((n_out, 2)) if scale is None else np.asarray(scale, float)
    dof = np.full((n_out, 2), np.inf) if dof is None else np.asarray(dof, float)
    dirs = tuple(directions[j // 3] for j in range(n_out))
    if mode_logit is not None:
        p = recalibrated_probability(p, np.asarray(mode_logit, float))
    return ModalPredictive(
        tuple(output_names), tuple(output_units), dirs, p, mean, lat, noise, scale, dof,
        None if gamma is None else np.asarray(gamma, float),
        None if ref_std is None else np.asarray(ref_std, float),
    )  # fmt: skip
