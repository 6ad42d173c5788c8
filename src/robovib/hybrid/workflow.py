"""File-based hybrid workflow steps: FRFs with path coordinates onto the model grid, predictions
compared with a measurement, and their figures (thesis ch. 5)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from ..frf.core import FRF
from .model import FRFPoseModel
from .oma import oma_frfs

__all__ = [
    "FRFPrediction",
    "frfs_on_path_grid",
    "oma_frfs_with_path",
    "plot_frf_prediction",
    "predict_frf_at",
]


def frfs_on_path_grid(
    frfs: Sequence[FRF], grid_hz, partial: bool = False
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Complex compliances on ``grid_hz``, their path coordinates and bin masks.

    Parameters
    ----------
    frfs
        Compliance FRFs with ``meta["path_s_m"]`` (and optionally ``meta["flagged"]``, a bool
        per bin of the FRF, as written by ``hybrid oma``).
    grid_hz
        (n_f,) model grid [Hz].
    partial
        True: grid bins outside an FRF's range are masked (missing), not an error.

    Returns
    -------
    values
        (n, n_f) complex compliance [m/N].
    s_m
        (n,) path coordinates [m].
    mask
        (n, n_f) bool, True where a bin is observed and not flagged.

    Raises
    ------
    ValueError
        An FRF without path coordinate, not a compliance, or (``partial=False``) not covering
        the grid.
    """
    grid = np.asarray(grid_hz, float)
    vals, s, masks = [], [], []
    for i, f in enumerate(frfs):
        if "path_s_m" not in f.meta:
            raise ValueError(
                f"FRF {i} has no path coordinate (write it with --path-s / from `hybrid oma`)"
            )
        if f.quantity != "compliance":
            raise ValueError(f"FRF {i} is {f.quantity}, expected compliance")
        try:
            on_grid = f.interpolate(grid, outside="hold" if partial else "raise")
        except ValueError as exc:
            raise ValueError(f"FRF {i}: {exc} (the model grid)") from None
        outside = (grid < f.frequency_hz[0] - 1e-3) | (grid > f.frequency_hz[-1] + 1e-3)
        flagged = np.asarray(f.meta.get("flagged", np.zeros(f.frequency_hz.size, bool)), bool)
        nearest = np.clip(np.searchsorted(f.frequency_hz, grid), 0, f.frequency_hz.size - 1)
        vals.append(on_grid.values)
        masks.append(~flagged[nearest] & ~outside)
        s.append(float(f.meta["path_s_m"]))
    return np.array(vals), np.array(s), np.array(masks)


def oma_frfs_with_path(record: dict, **kwargs) -> list[FRF]:
    """OMA FRFs per path segment of a milling record, each tagged with its path coordinate.

    Parameters
    ----------
    record
        As returned by :func:`robovib.io.read_milling_record_csv`.
    **kwargs
        Passed to :func:`robovib.hybrid.oma_frfs` (direction, segment_length_m, ...).

    Returns
    -------
    list of FRF
        ``meta = {"path_s_m": segment middle [m], "flagged": bool per bin}``.
    """
    segs = oma_frfs(
        record["time_s"], record["force_n"], record["displacement_m"], record["path_s_m"], **kwargs
    )
    return [replace(sg.frf, meta={"path_s_m": sg.s_mid_m, "flagged": sg.flagged}) for sg in segs]


@dataclass(frozen=True)
class FRFPrediction:
    """Predicted compliance FRF at a path coordinate (optionally with a measurement)."""

    s_m: float
    frequency_hz: np.ndarray  #: (n_f,) [Hz]
    compliance_m_per_n: np.ndarray  #: (n_f,) complex [m/N]
    std_m_per_n: np.ndarray  #: (n_f,) [m/N]
    extrapolating: bool
    measured_m_per_n: np.ndarray | None = None  #: (n_f,) complex, on the model grid

    @property
    def rmse_um_per_n(self) -> float | None:
        """RMS of |predicted - measured| over the grid [um/N], None without a measurement."""
        if self.measured_m_per_n is None:
            return None
        return float(
            1e6 * np.sqrt(np.mean(np.abs(self.compliance_m_per_n - self.measured_m_per_n) ** 2))
        )

    def to_dict(self) -> dict:
        """JSON-friendly summary (magnitudes in um/N)."""
        doc = {
            "s_m": self.s_m,
            "extrapolating": self.extrapolating,
            "frequency_hz": self.frequency_hz,
            "compliance_abs_um_per_n": 1e6 * np.abs(self.compliance_m_per_n),
            "std_um_per_n": 1e6 * self.std_m_per_n,
        }
        if self.measured_m_per_n is not None:
            doc["rmse_um_per_n"] = self.rmse_um_per_n
        return doc


def predict_frf_at(model: FRFPoseModel, s_m: float, measured: FRF | None = None) -> FRFPrediction:
    """Predict the compliance FRF at ``s_m`` [m]; ``measured`` is interpolated onto the grid.

    Raises
    ------
    ValueError
        ``measured`` is not a compliance FRF or does not cover the model grid.
    """
    h, sd = model.predict([s_m], return_std=True)
    meas = None
    if measured is not None:
        if measured.quantity != "compliance":
            raise ValueError(f"measured FRF is {measured.quantity}, expected compliance")
        meas = measured.interpolate(model.frequency_hz).values
    return FRFPrediction(
        float(s_m), model.frequency_hz, h[0], sd[0], bool(model.extrapolating([s_m])[0]), meas
    )


def plot_frf_prediction(result: FRFPrediction, ax=None, *, view: str = "both"):
    """Predicted compliance FRF with its ±2σ band (and the measured one).

    Magnitude and unwrapped phase, and real and imaginary parts (``view``, see
    :func:`robovib.frf.plot_frf`); extrapolation is stated in the title.

    Parameters
    ----------
    result
        A prediction from :func:`predict_frf_at`.
    ax
        Axes to draw into (2 or 4 depending on ``view``); a new figure when None.
    view
        ``"bode"``, ``"real-imag"`` or ``"both"``.

    Returns
    -------
    matplotlib.figure.Figure
    """
    from ..frf import FRF, FRFCurve, plot_frf

    f = result.frequency_hz
    main = FRF(f, result.compliance_m_per_n, source="model", estimator="model")
    overlays = [
        FRFCurve("±2σ", f, result.compliance_m_per_n, std=result.std_m_per_n, style="", color="C0")
    ]
    if result.measured_m_per_n is not None:
        overlays.append(FRFCurve("measured", f, result.measured_m_per_n, style="--", color="k"))
    title = f"prediction at s = {result.s_m:g} m"
    if result.extrapolating:
        title += " (EXTRAPOLATION)"
    return plot_frf(main, ax, view=view, overlays=overlays, title=title, coherence=False)
