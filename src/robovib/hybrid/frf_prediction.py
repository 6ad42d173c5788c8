"""The hybrid model on FRF objects: fitted from EMA FRFs, OMA FRFs of a milling record with
their poses, and predictions compared with a measured FRF, with their figures (thesis ch. 5)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from ..frf.core import FRF
from .frfs import INPUT_SETS, frf_pose, frfs_on_grid, frfs_on_path_grid
from .model import FRFPoseModel, frequency_grid
from .oma import oma_frfs

__all__ = [
    "INPUT_SETS",
    "FRFPrediction",
    "fit_frf_model",
    "flagged_fraction",
    "frf_pose",
    "frfs_on_grid",
    "frfs_on_path_grid",
    "oma_frfs_with_path",
    "plot_frf_prediction",
    "predict_frf_at",
]


def fit_frf_model(
    frfs: Sequence[FRF],
    inputs: str = "path",
    f_min_hz: float | None = None,
    f_max_hz: float = 40.0,
    df_hz: float = 1.953125,
) -> FRFPoseModel:
    """The initial per-bin GP model of the compliance from EMA FRFs (thesis ch. 5).

    Parameters
    ----------
    frfs
        EMA FRFs of one direction, with path coordinates (``inputs="path"``) or poses.
    inputs
        ``"path"`` (the path coordinate s [m], isotropic kernel) or ``"workspace"`` (x, y [m],
        rz [deg] from each FRF's pose, ARD kernel); see :data:`INPUT_SETS`.
    f_min_hz
        Model grid start [Hz]; default where all FRFs have data, at least 2 Hz.
    f_max_hz, df_hz
        Model grid end and step [Hz] (match the OMA resolution).

    Returns
    -------
    FRFPoseModel
        Fitted; ``last_report_`` says how many optimiser iterations it took.

    Raises
    ------
    ValueError
        Unknown ``inputs``, no FRFs, or FRFs the model refuses (mixed directions, missing poses).
    """
    if inputs not in INPUT_SETS:
        raise ValueError(f"inputs must be one of {list(INPUT_SETS)}, got {inputs!r}")
    if not frfs:
        raise ValueError("no EMA FRFs given")
    if len(frfs) < 2:  # else the GP names every frequency bin by its index
        raise ValueError(
            f"{len(frfs)} EMA FRF given: a model over the {inputs} needs FRFs at 2 or more poses"
        )
    if f_min_hz is None:  # where all EMA FRFs have data
        f_min_hz = max([2.0, *(float(f.frequency_hz[0]) for f in frfs)])
    grid = frequency_grid(f_min_hz, f_max_hz, df_hz)
    kernel = "isotropic" if inputs == "path" else "ard"
    return FRFPoseModel(grid, kernel=kernel, input_names=INPUT_SETS[inputs]).fit_frfs(frfs)


def oma_frfs_with_path(record: dict, **kwargs) -> list[FRF]:
    """OMA FRFs per path segment of a milling record, each tagged with its pose.

    Parameters
    ----------
    record
        As returned by :func:`robovib.io.read_milling_record_csv`: ``path_s_m`` (n,) [m], or
        ``pose`` (n, 3) = (x [m], y [m], rz [deg]) for a cut in the workspace.
    **kwargs
        Passed to :func:`robovib.hybrid.oma_frfs` (direction, segment_length_m, nperseg, ...).

    Returns
    -------
    list of FRF
        ``meta = {"path_s_m": segment middle [m] (distance travelled for workspace cuts),
        "flagged": bool per bin}``; workspace cuts also set ``pose`` = (x, y, NaN, NaN, NaN, rz).
    """
    where = record["pose"] if "pose" in record else record["path_s_m"]
    segs = oma_frfs(record["time_s"], record["force_n"], record["displacement_m"], where, **kwargs)
    out = []
    for sg in segs:
        pose = None
        if sg.pose_mid:
            x, y, rz = sg.pose_mid[:3]
            pose = (x, y, float("nan"), float("nan"), float("nan"), rz)
        out.append(replace(sg.frf, pose=pose, meta={"path_s_m": sg.s_mid_m, "flagged": sg.flagged}))
    return out


def flagged_fraction(frfs: list[FRF]) -> float:
    """Mean fraction of flagged bins (``meta["flagged"]``, 0 where absent) over FRFs.

    Parameters
    ----------
    frfs
        FRFs, e.g. from :func:`oma_frfs_with_path`.

    Returns
    -------
    float
        Mean over the FRFs of the fraction of their bins flagged, in [0, 1].

    Raises
    ------
    ValueError
        No FRFs, or a ``flagged`` array whose length is not the FRF's number of bins.
    """
    if not frfs:
        raise ValueError("no FRFs given")
    fractions = []
    for i, f in enumerate(frfs):
        fl = np.asarray(f.meta.get("flagged", np.zeros(f.frequency_hz.size, bool)), bool)
        if fl.shape != f.frequency_hz.shape:
            raise ValueError(
                f"FRF {i}: flagged has {fl.size} entries for {f.frequency_hz.size} bins"
            )
        fractions.append(fl.mean())
    return float(np.mean(fractions))


@dataclass(frozen=True)
class FRFPrediction:
    """Predicted compliance FRF at a pose (optionally with a measurement).

    Attributes
    ----------
    s_m
        The path coordinate [m] (NaN for workspace models).
    frequency_hz
        (n_f,) model grid [Hz].
    compliance_m_per_n
        (n_f,) complex predicted compliance, the posterior mean (thesis Eq. 9) [m/N].
    std_m_per_n
        (n_f,) latent predictive std ``sqrt(var Re + var Im)`` (Eq. 10) [m/N].
    extrapolating
        Whether the pose is outside the calibrated range.
    measured_m_per_n
        (n_f,) complex measured compliance on the model grid [m/N], or None.
    pose
        The pose in the model's ``input_names`` units.
    input_names
        The model's pose inputs.
    """

    s_m: float
    frequency_hz: np.ndarray  #: (n_f,) [Hz]
    compliance_m_per_n: np.ndarray  #: (n_f,) complex [m/N]
    std_m_per_n: np.ndarray  #: (n_f,) [m/N]
    extrapolating: bool
    measured_m_per_n: np.ndarray | None = None  #: (n_f,) complex, on the model grid
    pose: tuple[float, ...] = ()  #: the pose in the model's input units
    input_names: tuple[str, ...] = ("s_m",)

    @property
    def rmse_um_per_n(self) -> float | None:
        """RMS of |predicted - measured| over the grid [um/N], None without a measurement."""
        if self.measured_m_per_n is None:
            return None
        return float(
            1e6 * np.sqrt(np.mean(np.abs(self.compliance_m_per_n - self.measured_m_per_n) ** 2))
        )

    def peak(self) -> tuple[float, complex, float]:
        """The largest predicted compliance magnitude.

        Returns
        -------
        frequency_hz : float
            Frequency of the peak [Hz].
        compliance_m_per_n : complex
            Predicted compliance there [m/N].
        std_m_per_n : float
            Its predictive standard deviation [m/N].
        """
        i = int(np.argmax(np.abs(self.compliance_m_per_n)))
        return (float(self.frequency_hz[i]), complex(self.compliance_m_per_n[i]),
                float(self.std_m_per_n[i]))  # fmt: skip

    def to_dict(self) -> dict:
        """JSON-friendly summary (magnitudes in um/N).

        Returns
        -------
        dict
            ``s_m``, the pose by input name, ``extrapolating``, ``frequency_hz`` [Hz],
            ``compliance_abs_um_per_n`` and ``std_um_per_n`` [um/N], and ``rmse_um_per_n``
            with a measurement.
        """
        doc = {
            "s_m": self.s_m,
            **dict(zip(self.input_names, self.pose, strict=False)),
            "extrapolating": self.extrapolating,
            "frequency_hz": self.frequency_hz,
            "compliance_abs_um_per_n": 1e6 * np.abs(self.compliance_m_per_n),
            "std_um_per_n": 1e6 * self.std_m_per_n,
        }
        if self.measured_m_per_n is not None:
            doc["rmse_um_per_n"] = self.rmse_um_per_n
        return doc


def predict_frf_at(model: FRFPoseModel, pose, measured: FRF | None = None) -> FRFPrediction:
    """Predict the compliance FRF at a pose; ``measured`` is interpolated onto the grid.

    Parameters
    ----------
    model
        A fitted :class:`FRFPoseModel`.
    pose
        The path coordinate ``s_m`` [m] (a float) or a pose in the model's ``input_names``.
    measured
        Optional compliance FRF to compare with.

    Returns
    -------
    FRFPrediction
        Mean and std on the model grid, the extrapolation flag and the measurement.

    Raises
    ------
    ValueError
        A pose of the wrong length, ``measured`` not a compliance FRF or not covering the grid.
    """
    p = np.atleast_1d(np.asarray(pose, float))
    h, sd = model.predict(p[None, :], return_std=True)
    meas = None
    if measured is not None:
        if measured.quantity != "compliance":
            raise ValueError(f"measured FRF is {measured.quantity}, expected compliance")
        meas = measured.interpolate(model.frequency_hz).values
    names = tuple(model.input_names)
    s_m = float(p[0]) if names == ("s_m",) else float("nan")
    return FRFPrediction(
        s_m, np.asarray(model.frequency_hz, float), h[0], sd[0],
        bool(model.extrapolating(p[None, :])[0]), meas, tuple(float(v) for v in p), names,
    )  # fmt: skip


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
    where = ", ".join(f"{n} = {v:g}" for n, v in zip(result.input_names, result.pose, strict=False))
    title = f"prediction at {where or f's_m = {result.s_m:g}'}"
    if result.extrapolating:
        title += " (EXTRAPOLATION)"
    return plot_frf(main, ax, view=view, overlays=overlays, title=title, coherence=False)
