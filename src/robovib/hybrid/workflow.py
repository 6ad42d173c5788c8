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
    "INPUT_SETS",
    "FRFPrediction",
    "flagged_fraction",
    "frf_pose",
    "frfs_on_grid",
    "frfs_on_path_grid",
    "oma_frfs_with_path",
    "plot_frf_prediction",
    "predict_frf_at",
]


#: Pose inputs the file workflow understands: the path coordinate or the workspace pose.
INPUT_SETS = {"path": ("s_m",), "workspace": ("x_m", "y_m", "rz_deg")}


def frf_pose(frf: FRF, input_names=("s_m",)) -> tuple[float, ...]:
    """The pose of an FRF in the units of ``input_names``.

    ``("s_m",)``: ``meta["path_s_m"]``; ``("x_m", "y_m", "rz_deg")``: ``frf.pose`` =
    (x [m], y [m], z [m], rx, ry, rz [deg]) as written by ``frf compute`` / ``hybrid oma``.

    Raises
    ------
    ValueError
        The FRF carries no such pose, or unknown input names.
    """
    names = tuple(input_names)
    if names == INPUT_SETS["path"]:
        if "path_s_m" not in frf.meta:
            raise ValueError(
                "FRF has no path coordinate (write it with --path-s / from `hybrid oma`)"
            )
        return (float(frf.meta["path_s_m"]),)
    if names == INPUT_SETS["workspace"]:
        if (
            frf.pose is None
            or len(frf.pose) != 6
            or not np.all(np.isfinite(np.take(frf.pose, [0, 1, 5])))
        ):
            raise ValueError("FRF has no workspace pose (x, y, rz): record it at a workspace pose")
        return (float(frf.pose[0]), float(frf.pose[1]), float(frf.pose[5]))
    raise ValueError(f"unknown pose inputs {names}; expected one of {list(INPUT_SETS.values())}")


def frfs_on_grid(
    frfs: Sequence[FRF], grid_hz, input_names=("s_m",), partial: bool = False
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Complex compliances on ``grid_hz`` with their poses, bin masks and random errors.

    Parameters
    ----------
    frfs
        Compliance FRFs carrying their pose (see :func:`frf_pose`) and optionally
        ``meta["flagged"]`` (bool per bin, as written by ``hybrid oma``).
    grid_hz
        (n_f,) model grid [Hz].
    input_names
        The model's pose inputs.
    partial
        True: grid bins outside an FRF's range are masked (missing), not an error.

    Returns
    -------
    values
        (n, n_f) complex compliance [m/N].
    poses
        (n, n_inputs) in the units of ``input_names``.
    mask
        (n, n_f) bool, True where a bin is observed and not flagged.
    random_error
        (n, n_f) H1 random error std [m/N] from the coherence (0 where none is stored).

    Raises
    ------
    ValueError
        An FRF without that pose, not a compliance, or (``partial=False``) not covering the grid.
    """
    grid = np.asarray(grid_hz, float)
    vals, poses, masks, errs = [], [], [], []
    for i, f in enumerate(frfs):
        try:
            poses.append(frf_pose(f, input_names))
        except ValueError as exc:
            raise ValueError(f"FRF {i}: {exc}") from None
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
        if f.coherence is not None:
            coh = np.clip(np.asarray(f.coherence, float), 1e-6, 1.0)
            err = np.abs(f.values) * np.sqrt((1 - coh) / (2 * max(int(f.n_averages), 1) * coh))
            errs.append(np.interp(grid, f.frequency_hz, err))
        else:
            errs.append(np.zeros(grid.size))
    return np.array(vals), np.array(poses, float), np.array(masks), np.array(errs)


def frfs_on_path_grid(
    frfs: Sequence[FRF], grid_hz, partial: bool = False
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Complex compliances on ``grid_hz``, their path coordinates and bin masks.

    The path-coordinate case of :func:`frfs_on_grid`: returns values (n, n_f) complex [m/N],
    s_m (n,) [m], mask (n, n_f) bool.

    Raises
    ------
    ValueError
        As :func:`frfs_on_grid`.
    """
    h, p, m, _ = frfs_on_grid(frfs, grid_hz, ("s_m",), partial)
    return h, p[:, 0], m


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
    """Mean fraction of flagged bins (``meta["flagged"]``, 0 where absent) over FRFs, in [0, 1].

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

    ``s_m`` is the path coordinate (NaN for workspace models); ``pose`` the pose in the
    model's ``input_names``.
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
        """JSON-friendly summary (magnitudes in um/N)."""
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


def plot_frf_prediction(result: FRFPrediction, ax=None):
    """Predicted |FRF| with its ±2σ band (and the measured one), log scale.

    Returns
    -------
    matplotlib.figure.Figure
    """
    import matplotlib.pyplot as plt

    if ax is None:
        fig, ax = plt.subplots(figsize=(7, 4))
    else:
        fig = ax.figure
    f, h, sd = result.frequency_hz, result.compliance_m_per_n, result.std_m_per_n
    ax.semilogy(f, np.abs(h), color="C0", label="predicted")
    ax.fill_between(
        f, np.maximum(np.abs(h) - 2 * sd, 1e-12), np.abs(h) + 2 * sd, color="C0", alpha=0.2,
        label="±2σ",
    )  # fmt: skip
    if result.measured_m_per_n is not None:
        ax.semilogy(f, np.abs(result.measured_m_per_n), "k--", label="measured")
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel("|compliance| [m/N]")
    where = ", ".join(f"{n} = {v:g}" for n, v in zip(result.input_names, result.pose, strict=False))
    ax.set_title(f"prediction at {where or f's_m = {result.s_m:g}'}")
    ax.legend(fontsize=8)
    fig.tight_layout()
    return fig
