"""Fit of the dominant mode of an FRF to a second-order transfer function (thesis §3.2.1, Fig. 6).

Model (compliance, m/N), with residual terms for the modes outside the band::

    H(f) = 1 / (k (1 - r^2 + 2 i zeta r)) + R + R2 r^2,   r = f / fn

``R`` (complex) is the out-of-band modes' compliance at the peak; ``R2`` (real) its rise across
the band from the stiffer modes above it: a mode ``j`` above the band adds
``1 / (k_j (1 - (f / f_j)^2)) ≈ (1 + (f / f_j)^2) / k_j`` (the upper residual's curvature).
Without ``R2`` the dominant mode absorbs that rise: on the virtual robot's exact compliance
(secondary modes 2.6-3x above the dominant one, 10x stiffer) the constant-only fit returns k
0.7-1.8 % high, zeta 0.5-1.2 % low and c 0.2-0.6 % high; with ``R2`` all within 0.1 %
(``residual="constant"`` keeps the constant-only model).

fitted by nonlinear least squares (:func:`scipy.optimize.least_squares`) to the real and
imaginary parts in a band around the peak, optionally weighted by the coherence. Initial values
come from peak picking and the half-power bandwidth. Standard errors follow from the Jacobian at
the optimum (``cov = s^2 (J^T J)^-1``), propagated to the damping coefficient.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import optimize

from ..frf.core import FRF
from .parameters import ModalParameters, remove_exponential_window_damping

__all__ = ["MAX_RELATIVE_RMS_ERROR", "ModalFit", "fit_dominant_mode", "half_power_estimate"]

#: relative RMS misfit above which a fit is flagged (a clean single mode fits to ~1e-3 - 1e-2)
MAX_RELATIVE_RMS_ERROR = 0.15
#: damping ratio above which a robot's structural mode is implausible (thesis modes: 1-10 %)
MAX_PLAUSIBLE_DAMPING_RATIO = 0.3


@dataclass(frozen=True)
class ModalFit:
    """A fitted mode with standard errors (same keys as :meth:`ModalParameters.to_dict`).

    Attributes
    ----------
    parameters
        The fitted mode.
    std
        Standard errors of the parameters (keys of :meth:`ModalParameters.to_dict`).
    band_hz
        The band fitted [Hz].
    residual_compliance
        Constant residual term of the fit [m/N] (out-of-band modes).
    residual_curvature
        Real coefficient ``R2`` [m/N] of the ``(f / fn)^2`` residual term (the rise of the
        upper modes' compliance across the band; 0 for ``residual="constant"``).
    relative_rms_error
        RMS of the fit residual over the RMS of the FRF in the band.
    exp_window_corrected
        Whether the exponential window's damping was removed.
    flags
        Reasons not to trust the fit (empty: none found).
    """

    parameters: ModalParameters
    std: dict[str, float]
    band_hz: tuple[float, float]
    residual_compliance: complex
    relative_rms_error: float
    exp_window_corrected: bool
    #: reasons not to trust the fit (empty: none found): a parameter at its bound, a large
    #: residual, an inverted sign (polarity), implausible damping
    flags: tuple[str, ...] = ()
    #: real coefficient [m/N] of the (f / fn)^2 residual term
    residual_curvature: float = 0.0

    def compliance(self, frequency_hz) -> np.ndarray:
        """The fitted model (mode and residual terms) [m/N] at ``frequency_hz`` [Hz].

        Parameters
        ----------
        frequency_hz : array_like
            Frequencies [Hz].

        Returns
        -------
        numpy.ndarray
            Complex compliance [m/N].
        """
        f = np.asarray(frequency_hz, float)
        r2 = (f / self.parameters.natural_frequency_hz) ** 2
        return (
            self.parameters.compliance(f) + self.residual_compliance + self.residual_curvature * r2
        )

    @property
    def flagged(self) -> bool:
        return bool(self.flags)

    def to_dict(self) -> dict:
        return {
            **self.parameters.to_dict(),
            "std": dict(self.std),
            "band_hz": list(self.band_hz),
            "relative_rms_error": self.relative_rms_error,
            "exp_window_corrected": self.exp_window_corrected,
            "flagged": self.flagged,
            "flags": list(self.flags),
        }


def _fit_flags(f, v, fn, zeta, k_rel, lower, upper, rel_err) -> tuple[str, ...]:
    """Reasons a dominant-mode fit should not be trusted (see :class:`ModalFit`)."""
    flags = []
    df = float(np.min(np.diff(f))) if f.size > 1 else 0.0
    if fn - lower[0] <= max(df, 1e-9 * fn) or upper[0] - fn <= max(df, 1e-9 * fn):
        flags.append(
            f"natural frequency {fn:.4g} Hz at the edge of the fit band {f[0]:.4g}-{f[-1]:.4g} Hz "
            "(no resonance found inside it)"
        )
    if zeta >= 0.99 * upper[1] or zeta <= 10 * lower[1]:
        flags.append(f"damping ratio {zeta:.3g} at its bound [{lower[1]:g}, {upper[1]:g}]")
    elif zeta > MAX_PLAUSIBLE_DAMPING_RATIO:
        flags.append(
            f"damping ratio {100 * zeta:.0f} % is implausible for a structural mode "
            f"(> {100 * MAX_PLAUSIBLE_DAMPING_RATIO:.0f} %)"
        )
    if k_rel <= 1.01 * lower[2] or k_rel >= 0.99 * upper[2]:
        flags.append("stiffness at its bound (1e-3 or 1e3 x the peak-picking estimate)")
    if rel_err > MAX_RELATIVE_RMS_ERROR:
        flags.append(
            f"large residual: relative RMS error {rel_err:.2f} > {MAX_RELATIVE_RMS_ERROR:g}"
        )
    # A driving-point compliance has Im H < 0 at resonance (H = 1/(k(1 - r^2 + 2 i zeta r))).
    i = int(np.argmax(np.abs(v)))
    if v[i].imag > 0.5 * abs(v[i]):
        flags.append(
            "inverted sign: Im H > 0 at the resonance (force or response polarity reversed, "
            "or the FRF is not a driving point)"
        )
    return tuple(flags)


def half_power_estimate(frequency_hz: np.ndarray, compliance: np.ndarray) -> ModalParameters:
    """Peak-picking estimate of the dominant mode: fn at max |H|, zeta from the half-power band.

    Parameters
    ----------
    frequency_hz : numpy.ndarray
        (n,) frequency axis [Hz].
    compliance : numpy.ndarray
        (n,) complex compliance [m/N].

    Returns
    -------
    ModalParameters
        The estimate (a starting point for the least-squares fit).
    """
    mag = np.abs(compliance)
    i = int(np.argmax(mag))
    fn = float(frequency_hz[i])
    level = mag[i] / math.sqrt(2)
    lo = i
    while lo > 0 and mag[lo] > level:
        lo -= 1
    hi = i
    while hi < mag.size - 1 and mag[hi] > level:
        hi += 1
    width = float(frequency_hz[hi] - frequency_hz[lo])
    zeta = max(width / (2 * fn), 1e-3)
    k = 1.0 / (2 * zeta * mag[i])
    return ModalParameters(fn, k, zeta)


def _require_peak(values: np.ndarray) -> None:
    """A zero or flat FRF has no mode: say so instead of the optimiser's or LAPACK's words."""
    mag = np.abs(np.asarray(values))
    top = float(np.max(mag)) if mag.size else 0.0
    if not top > 0:
        raise ValueError("the FRF is zero at every frequency: no response to fit (a dead channel?)")
    if float(np.ptp(mag)) <= 1e-9 * top:
        raise ValueError("the FRF has one magnitude at every frequency: no resonance peak to fit")


def fit_dominant_mode(
    frf: FRF,
    band_hz: tuple[float, float] | None = None,
    *,
    min_frequency_hz: float = 1.0,
    residual: bool | str = True,
    coherence_weighting: bool = True,
    correct_exp_window: bool = True,
) -> ModalFit:
    """Fit the dominant (largest-compliance) mode of an FRF.

    Parameters
    ----------
    frf
        Any FRF form; converted to compliance first (bins below ``min_frequency_hz`` dropped).
    band_hz
        Fit band [Hz]; default: the peak's half-power estimate ``fn (1 ± max(3 zeta, 0.2))``.
    min_frequency_hz
        Bins below this frequency [Hz] are dropped before integrating to compliance.
    residual
        Residual terms for the other modes (module docs): ``True`` or ``"upper"`` a complex
        constant and the upper modes' ``(f / fn)^2`` rise; ``"constant"`` the constant only;
        ``False`` none.
    coherence_weighting
        Weight residuals by the coherence (ignored if the FRF has none).
    correct_exp_window
        Remove the damping added by an exponential window recorded on the FRF.

    Returns
    -------
    ModalFit
        ``parameters`` (fn [Hz], k [N/m], zeta), their ``std``, the band, the residual
        compliance [m/N], the relative RMS error and ``flags`` (reasons not to trust the fit).

    Raises
    ------
    ValueError
        For a cross FRF (``meta["reference_direction"]`` differs from ``direction``), too few
        bins in the band.

    See ``docs/methods.md`` section 2 (modal parameters).

    Examples
    --------
    >>> import numpy as np
    >>> from robovib.frf import FRF
    >>> from robovib.modal import ModalParameters, fit_dominant_mode
    >>> f = np.linspace(5, 60, 400)
    >>> true = ModalParameters(25.0, 2e6, 0.05)
    >>> fit = fit_dominant_mode(FRF(f, true.compliance(f)))
    >>> round(fit.parameters.natural_frequency_hz, 2)
    25.0
    """
    ref = frf.meta.get("reference_direction")
    if ref and frf.direction and ref != frf.direction:
        raise ValueError(
            f"cross FRF (response {frf.direction}, force {ref}): a dominant-mode fit gives a "
            "direct (driving-point) stiffness only; use the direct FRF"
        )
    h = frf.to_compliance(min_frequency_hz)
    f_all, v_all = h.frequency_hz, h.values
    _require_peak(v_all)
    guess = half_power_estimate(f_all, v_all)
    if band_hz is None:
        half = max(3 * guess.damping_ratio, 0.2)
        band_hz = (guess.natural_frequency_hz * (1 - half), guess.natural_frequency_hz * (1 + half))
    sel = h.band(*band_hz)
    f, v = sel.frequency_hz, sel.values
    if f.size < 6:
        raise ValueError(f"the fit band {band_hz} Hz holds only {f.size} bins; need at least 6")
    if not (f[0] < guess.natural_frequency_hz < f[-1]):
        guess = half_power_estimate(f, v)
    w = np.ones_like(f)
    if coherence_weighting and sel.coherence is not None:
        w = np.sqrt(np.clip(sel.coherence, 1e-6, 1.0))
    scale = float(np.max(np.abs(v)))
    k0 = guess.stiffness_n_per_m
    f_ref = guess.natural_frequency_hz
    kinds = {True: "upper", False: "none", "upper": "upper", "constant": "constant", "none": "none"}
    if not isinstance(residual, (bool, str)) or residual not in kinds:
        raise ValueError(f"residual must be True, False, 'upper' or 'constant', got {residual!r}")
    kind = kinds[residual]
    n_res = {"none": 0, "constant": 2, "upper": 3}[kind]

    def model(x):
        fn, zeta, k_rel = x[0], x[1], x[2]
        r = f / fn
        out = 1.0 / (k_rel * k0 * (1 - r**2 + 2j * zeta * r))
        if n_res:
            out = out + (x[3] + 1j * x[4]) * scale
        if n_res == 3:
            out = out + x[5] * scale * (f / f_ref) ** 2
        return out

    def resid(x):
        d = (model(x) - v) / scale * w
        return np.concatenate([d.real, d.imag])

    x0 = [guess.natural_frequency_hz, guess.damping_ratio, 1.0] + [0.0] * n_res
    lower = [f[0], 1e-5, 1e-3] + [-np.inf] * n_res
    upper = [f[-1], 0.99, 1e3] + [np.inf] * n_res
    sol = optimize.least_squares(resid, x0, bounds=(lower, upper), x_scale="jac")
    if not sol.success:
        raise RuntimeError(f"dominant-mode fit did not converge: {sol.message}")
    fn, zeta, k = sol.x[0], sol.x[1], sol.x[2] * k0
    dof = max(2 * f.size - sol.x.size, 1)
    s2 = 2 * sol.cost / dof
    jac = sol.jac
    cov = np.linalg.pinv(jac.T @ jac) * s2
    sd = np.sqrt(np.clip(np.diag(cov), 0, None))
    # c = 2 zeta k / (2 pi fn): first-order propagation with the parameter covariance.
    grad_c = np.zeros(sol.x.size)
    c = 2 * zeta * k / (2 * math.pi * fn)
    grad_c[0], grad_c[1], grad_c[2] = -c / fn, c / zeta, c / sol.x[2]
    std = {
        "natural_frequency_hz": float(sd[0]),
        "damping_ratio": float(sd[1]),
        "stiffness_n_per_m": float(sd[2] * k0),
        "damping_ns_per_m": float(math.sqrt(max(grad_c @ cov @ grad_c, 0.0))),
    }
    params = ModalParameters(float(fn), float(k), float(zeta))
    corrected = False
    if correct_exp_window and frf.exp_window_tau_s is not None:
        params = remove_exponential_window_damping(params, frf.exp_window_tau_s)
        corrected = True
    rel_err = float(np.sqrt(np.mean(np.abs(model(sol.x) - v) ** 2)) / scale)
    res_c = complex(sol.x[3] * scale, sol.x[4] * scale) if n_res else 0j
    # The fit's (f / f_ref)^2 term written as (f / fn)^2 of the fitted fn.
    res_r2 = float(sol.x[5] * scale * (fn / f_ref) ** 2) if n_res == 3 else 0.0
    flags = _fit_flags(f, v, fn, zeta, sol.x[2], lower, upper, rel_err)
    return ModalFit(
        params, std, (float(f[0]), float(f[-1])), res_c, rel_err, corrected, flags, res_r2
    )
