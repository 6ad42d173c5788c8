"""The labelled frequency response function and conversions between FRF forms (thesis Eq. 3-5)."""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Literal

import numpy as np

__all__ = ["FRF", "RESPONSE_TO_QUANTITY", "FRFQuantity", "to_compliance"]

FRFQuantity = Literal["compliance", "mobility", "accelerance"]
#: FRF form obtained from each kind of response signal over force.
RESPONSE_TO_QUANTITY: dict[str, FRFQuantity] = {
    "displacement": "compliance",
    "velocity": "mobility",
    "acceleration": "accelerance",
}
_DIRECTIONS = ("x", "y", "z")
_SOURCES = ("EMA", "OMA", "model")
_ESTIMATORS = ("H1", "H2", "model")


def to_compliance(
    frequency_hz: np.ndarray,
    values: np.ndarray,
    quantity: FRFQuantity,
    min_frequency_hz: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Convert an FRF to compliance (receptance, m/N) and drop bins below ``min_frequency_hz``.

    Accelerance is divided by ``-(2 pi f)^2`` and mobility by ``i 2 pi f``. Both blow up noise
    toward 0 Hz, hence the explicit low-frequency limit (the returned frequency axis starts at
    the first bin >= ``min_frequency_hz``; nothing is clipped silently).

    Parameters
    ----------
    frequency_hz : numpy.ndarray
        (n,) frequency axis [Hz].
    values : numpy.ndarray
        (..., n) complex FRF of ``quantity`` (SI: m/N, m/s/N or m/s²/N).
    quantity : {"compliance", "mobility", "accelerance"}
        What ``values`` is.
    min_frequency_hz : float
        Lowest frequency kept [Hz] (> 0 for mobility and accelerance).

    Returns
    -------
    frequency_hz : numpy.ndarray
        The kept frequencies [Hz].
    compliance : numpy.ndarray
        The FRF as compliance [m/N] at those frequencies.
    """
    if quantity not in ("compliance", "mobility", "accelerance"):
        raise ValueError(
            f"unknown FRF quantity {quantity!r}; expected compliance, mobility or accelerance"
        )
    f = np.asarray(frequency_hz, float)
    min_frequency_hz = float(min_frequency_hz)
    if not np.isfinite(min_frequency_hz) or min_frequency_hz < 0:
        raise ValueError(
            f"min_frequency_hz must be a finite number >= 0 Hz, got {min_frequency_hz}"
        )
    keep = f >= min_frequency_hz
    if f.size and keep.sum() < 2:
        raise ValueError(
            f"min_frequency_hz={min_frequency_hz:g} Hz leaves fewer than 2 bins of the measured "
            f"band {f[0]:.3g}-{f[-1]:.3g} Hz (fmin must be below fmax)"
        )
    if quantity != "compliance" and not np.all(f[keep] > 0):
        raise ValueError(
            "min_frequency_hz must be > 0 to convert mobility or accelerance to compliance"
        )
    w = 2 * np.pi * f[keep]
    v = np.asarray(values)[..., keep]
    if quantity == "accelerance":
        v = v / -(w**2)
    elif quantity == "mobility":
        v = v / (1j * w)
    return f[keep], v


@dataclass(frozen=True)
class FRF:
    """One measured or predicted FRF with its context.

    Attributes
    ----------
    frequency_hz
        (n_f,) frequency axis [Hz].
    values
        (n_f,) complex FRF in the unit of ``quantity`` (SI: m/N, m/s/N or m/s²/N).
    coherence
        (n_f,) ordinary coherence, or None (e.g. for model FRFs).
    quantity
        ``"compliance"`` (receptance), ``"mobility"`` or ``"accelerance"``.
    direction
        ``"x"``, ``"y"`` or ``"z"`` (robot base frame) or None.
    pose
        Tool-tip pose (X, Y, Z [m], Rx, Ry, Rz [deg]) or None.
    source
        ``"EMA"`` (hammer), ``"OMA"`` (operational) or ``"model"``.
    n_averages
        Hits or Welch segments averaged.
    exp_window_tau_s
        Time constant of the exponential window applied to both channels, if any: fitted
        damping must be corrected for it (see :func:`robovib.modal.remove_exponential_window_damping`).
    estimator
        ``"H1"``, ``"H2"`` or ``"model"``.
    meta
        Free-form extra metadata (str -> str/float).
    """

    frequency_hz: np.ndarray
    values: np.ndarray
    coherence: np.ndarray | None = None
    quantity: FRFQuantity = "compliance"
    direction: str | None = None
    pose: tuple[float, ...] | None = None
    source: str = "EMA"
    n_averages: int = 1
    exp_window_tau_s: float | None = None
    estimator: str = "H1"
    meta: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        f = np.asarray(self.frequency_hz, float)
        v = np.asarray(self.values, complex)
        if f.ndim != 1 or v.shape != f.shape:
            raise ValueError(
                f"frequency_hz {f.shape} and values {v.shape} must be 1-D of equal length"
            )
        if not (np.all(np.isfinite(f)) and np.all(np.isfinite(v))):
            raise ValueError("FRF frequency axis or values contain NaN or inf")
        if f.size > 1 and np.any(np.diff(f) <= 0):
            raise ValueError("frequency_hz must be strictly increasing")
        if self.coherence is not None:
            coh = np.asarray(self.coherence, float)
            if coh.shape != f.shape:
                raise ValueError("coherence must have the same shape as frequency_hz")
            if not np.all(np.isfinite(coh)):
                raise ValueError("FRF coherence contains NaN or inf (dimensionless, 0..1)")
            bad = (coh < -1e-9) | (coh > 1 + 1e-9)
            if np.any(bad):
                i = int(np.argmax(bad))
                raise ValueError(
                    f"FRF coherence must lie in [0, 1] (dimensionless), got {coh[i]:g} at "
                    f"{f[i]:g} Hz"
                )
        if self.quantity not in ("compliance", "mobility", "accelerance"):
            raise ValueError(f"unknown FRF quantity {self.quantity!r}")
        if self.direction is not None and self.direction not in _DIRECTIONS:
            raise ValueError(f"unknown direction {self.direction!r}; expected one of {_DIRECTIONS}")
        if self.source not in _SOURCES:
            raise ValueError(f"unknown source {self.source!r}; expected one of {_SOURCES}")
        if self.estimator not in _ESTIMATORS:
            raise ValueError(f"unknown estimator {self.estimator!r}; expected one of {_ESTIMATORS}")
        if self.exp_window_tau_s is not None and not (
            np.isfinite(self.exp_window_tau_s) and self.exp_window_tau_s > 0
        ):
            raise ValueError(
                f"exp_window_tau_s must be a positive time in s or None, got {self.exp_window_tau_s}"
            )
        if self.pose is not None and len(self.pose) != 6:
            raise ValueError("pose must be (X, Y, Z [m], Rx, Ry, Rz [deg])")
        object.__setattr__(self, "frequency_hz", f)
        object.__setattr__(self, "values", v)
        if self.coherence is not None:
            object.__setattr__(self, "coherence", np.asarray(self.coherence, float))

    @property
    def df_hz(self) -> float:
        return (
            float(self.frequency_hz[1] - self.frequency_hz[0])
            if self.frequency_hz.size > 1
            else np.nan
        )

    def to_compliance(self, min_frequency_hz: float = 1.0) -> FRF:
        """This FRF as compliance [m/N], bins below ``min_frequency_hz`` dropped.

        Parameters
        ----------
        min_frequency_hz : float
            Lowest frequency kept [Hz] (see :func:`to_compliance`).

        Returns
        -------
        FRF
            A compliance FRF (coherence kept on the same bins).
        """
        f, v = to_compliance(self.frequency_hz, self.values, self.quantity, min_frequency_hz)
        keep = self.frequency_hz >= min_frequency_hz
        coh = None if self.coherence is None else self.coherence[keep]
        return replace(self, frequency_hz=f, values=v, coherence=coh, quantity="compliance")

    def interpolate(
        self,
        grid_hz,
        *,
        outside: Literal["raise", "hold", "zero"]
        | tuple[Literal["hold", "zero"], Literal["hold", "zero"]] = "raise",
        tolerance_hz: float = 1e-3,
    ) -> FRF:
        """This FRF linearly interpolated (real and imaginary parts) on another frequency grid.

        Parameters
        ----------
        grid_hz
            (n_g,) strictly increasing frequencies [Hz].
        outside
            ``"raise"``: a grid point more than ``tolerance_hz`` outside this FRF's range is an
            error; ``"hold"``: points outside the range take the value of the nearest end bin
            (callers mask them); ``"zero"``: points outside the range are 0 (values and
            coherence), e.g. an FRF applied to a wider FFT grid. A pair ``(below, above)`` of
            ``"hold"``/``"zero"`` treats the two ends differently (``("hold", "zero")``: the
            first bin held down to 0 Hz, nothing above the measured band).
        tolerance_hz
            Slack [Hz] at both ends of the range before a point counts as outside
            (``outside="raise"`` only).

        Returns
        -------
        FRF
            Same metadata, ``frequency_hz = grid_hz``; coherence interpolated too.

        Raises
        ------
        ValueError
            Grid not 1-D, not finite or not increasing; or (``outside="raise"``) outside the
            range; unknown ``outside``.
        """
        g = np.asarray(grid_hz, float)
        if g.ndim != 1 or g.size == 0 or not np.all(np.isfinite(g)):
            raise ValueError("grid_hz must be a non-empty 1-D array of finite frequencies [Hz]")
        if g.size > 1 and np.any(np.diff(g) <= 0):
            raise ValueError("grid_hz must be strictly increasing [Hz]")
        sides = ("hold", "zero")
        if isinstance(outside, tuple):
            if len(outside) != 2 or any(o not in sides for o in outside):
                raise ValueError(
                    f"unknown outside={outside!r}; a pair must be (below, above) of 'hold'/'zero'"
                )
            below, above = outside
        elif outside in ("raise", *sides):
            below = above = "hold" if outside == "raise" else outside
        else:
            raise ValueError(f"unknown outside={outside!r}; expected 'raise', 'hold' or 'zero'")
        f = self.frequency_hz
        beyond = (g < f[0] - tolerance_hz) | (g > f[-1] + tolerance_hz)
        if outside == "raise" and np.any(beyond):
            raise ValueError(
                f"FRF covers {f[0]:g}-{f[-1]:g} Hz, not the grid {g[0]:g}-{g[-1]:g} Hz"
            )
        lo = {"left": 0.0} if below == "zero" else {}
        hi = {"right": 0.0} if above == "zero" else {}

        def interp(y):
            return np.interp(g, f, y, **lo, **hi)

        v = interp(self.values.real) + 1j * interp(self.values.imag)
        coh = None if self.coherence is None else interp(self.coherence)
        return replace(self, frequency_hz=g, values=v, coherence=coh)

    def band(self, f_min_hz: float, f_max_hz: float) -> FRF:
        """The bins with ``f_min_hz <= f <= f_max_hz``.

        Parameters
        ----------
        f_min_hz, f_max_hz : float
            The band [Hz], finite, ``f_min_hz < f_max_hz``; it must hold 2 bins or more.

        Returns
        -------
        FRF
            The FRF on those bins (coherence kept).
        """
        if not (np.isfinite(f_min_hz) and np.isfinite(f_max_hz)):
            raise ValueError(f"band limits must be finite (Hz), got {f_min_hz}-{f_max_hz}")
        if f_min_hz >= f_max_hz:
            raise ValueError(f"empty band: f_min_hz={f_min_hz} Hz >= f_max_hz={f_max_hz} Hz")
        keep = (self.frequency_hz >= f_min_hz) & (self.frequency_hz <= f_max_hz)
        if keep.sum() < 2:
            raise ValueError(
                f"band {f_min_hz}-{f_max_hz} Hz holds fewer than 2 bins of this FRF "
                f"({self.frequency_hz[0]:.3g}-{self.frequency_hz[-1]:.3g} Hz)"
            )
        coh = None if self.coherence is None else self.coherence[keep]
        return replace(
            self, frequency_hz=self.frequency_hz[keep], values=self.values[keep], coherence=coh
        )
