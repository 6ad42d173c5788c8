"""The dominant mode per direction at a pose (:class:`PoseMode`), NumPy only.

:meth:`robovib.gp.PoseModalModel.modes` and the scikit-learn-free
:meth:`robovib.gp.saved_model.PosePredictor.modes` both answer through :func:`modes_at`, so a
command that reads modes from a saved model (milling, control) gets the same numbers from
either without importing scikit-learn.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..modal.parameters import ModalParameters

__all__ = ["PoseMode", "modes_at"]


@dataclass(frozen=True)
class PoseMode:
    """The dominant mode of one direction at one pose, with its predictive uncertainty.

    Attributes
    ----------
    parameters
        Mean prediction as :class:`~robovib.modal.ModalParameters` (SI).
    fn_std_hz, stiffness_std_n_per_m, damping_std_ns_per_m
        Standard deviations of the *latent* fn, k and c (the modal parameters themselves) of
        the more probable mode, calibrated where the model is (``calibration_``).
    measurement_std
        The same for a new *measurement* (latent plus test-to-test scatter), or None.
    intervals_95
        Per (fn, k, c) the 95 % set of a new measurement: one ``(low, high)`` interval, or two
        where the mode is uncertain (a mixture of the low and the high mode), or None.
    extrapolating
        The pose is outside the calibrated inputs (see :meth:`PoseModalModel.extrapolating`).
    high_mode_probability
        Probability that the high mode dominates, where a mode switch was modelled in this
        direction; ``None`` otherwise.
    """

    parameters: ModalParameters
    fn_std_hz: float
    stiffness_std_n_per_m: float
    damping_std_ns_per_m: float
    extrapolating: bool
    high_mode_probability: float | None
    measurement_std: tuple[float, float, float] | None = None
    intervals_95: tuple | None = None

    def to_dict(self) -> dict:
        """JSON-ready, units in the keys (fn, k, c, ζ with the std of fn, k, c).

        Returns
        -------
        dict
            The mode, its latent and measurement std and the mode-switch probability.
        """
        p = self.parameters
        extra = {}
        if self.measurement_std is not None:
            extra["measurement_std"] = dict(
                zip(
                    ("fn_hz", "stiffness_n_per_m", "damping_ns_per_m"),
                    self.measurement_std,
                    strict=True,
                )
            )
        if self.intervals_95 is not None:
            extra["intervals_95"] = dict(
                zip(
                    ("fn_hz", "stiffness_n_per_m", "damping_ns_per_m"),
                    [[list(iv) for iv in ivs] for ivs in self.intervals_95],
                    strict=True,
                )
            )
        return extra | {
            "fn_hz": p.natural_frequency_hz,
            "fn_std_hz": self.fn_std_hz,
            "stiffness_n_per_m": p.stiffness_n_per_m,
            "stiffness_std_n_per_m": self.stiffness_std_n_per_m,
            "damping_ns_per_m": p.damping_ns_per_m,
            "damping_std_ns_per_m": self.damping_std_ns_per_m,
            "damping_ratio": p.damping_ratio,
            "extrapolating": self.extrapolating,
            "high_mode_probability": self.high_mode_probability,
        }


def modes_at(model, X: np.ndarray) -> list[dict[str, PoseMode]]:
    """The dominant mode of each direction at each (checked) pose row of ``X``.

    ``model`` offers ``predictive``, ``extrapolating``, ``mode_switch_probability``,
    ``directions_`` and ``input_names_`` (a fitted :class:`~robovib.gp.PoseModalModel` or a
    :class:`~robovib.gp.saved_model.PosePredictor`); see :meth:`PoseModalModel.modes`.

    Parameters
    ----------
    model : PoseModalModel or PosePredictor
        The fitted pose model.
    X : numpy.ndarray (n, d)
        Checked poses in the units of ``model.input_names_``.

    Returns
    -------
    list of dict
        One ``{direction: PoseMode}`` per row of ``X``.

    Raises
    ------
    ValueError
        A predicted mean that is not a physical mode (fn or k <= 0, c < 0).
    """
    pred = model.predictive(X)
    mean = pred.point()
    std = pred.point_std("latent")
    std_meas = pred.point_std("measurement")
    sets = pred.intervals(0.95, "measurement")
    extrap = model.extrapolating(X)
    p = model.mode_switch_probability(X)
    out = []
    for r in range(X.shape[0]):
        row = {}
        for i, d in enumerate(model.directions_):
            fn, k, c = mean[r, 3 * i : 3 * i + 3]
            if not (fn > 0 and k > 0 and c >= 0):
                raise ValueError(
                    f"predicted {d} mode at {dict(zip(model.input_names_, X[r], strict=True))} "
                    f"is not physical (fn = {fn:.4g} Hz, k = {k:.4g} N/m, c = {c:.4g} N*s/m): "
                    "far outside the calibrated workspace"
                )
            prob = None if p is None or np.isnan(p[r, i]) else float(p[r, i])
            row[d] = PoseMode(
                ModalParameters.from_fn_k_c(fn, k, c),
                float(std[r, 3 * i]),
                float(std[r, 3 * i + 1]),
                float(std[r, 3 * i + 2]),
                bool(extrap[r]),
                prob,
                tuple(float(v) for v in std_meas[r, 3 * i : 3 * i + 3]),
                tuple(tuple(sets[r][3 * i + j]) for j in range(3)),
            )
        out.append(row)
    return out
