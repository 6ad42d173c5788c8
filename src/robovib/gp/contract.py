"""The pose-model contract: what every pose model gives at a pose, and the one loader (NumPy only).

Every kind of pose model robovib makes answers through the same interface, :class:`PoseModel`:

* the chapter-3 model of Table A1 (shipped, dominant mode per direction ``x, y, z``);
* a campaign's dominant-mode model (``model fit modal.csv``; a mode switch modelled where found);
* a campaign's multi-mode model (``model fit modes.csv``: "directions" are mode ids
  ``x1, x2, y1, ...`` of :func:`robovib.campaign.fit_multimode_pose_model`).

Each is a :class:`robovib.gp.PoseModalModel` (fit, update, save) or its read-only, SciPy-free
:class:`robovib.gp.saved_model.PosePredictor` (the same file, the same numbers). Both take their
whole prediction side from :class:`PosePredictionSide` here, so neither re-implements the other;
they differ only in where the GP posteriors come from (scikit-learn estimators, or NumPy
rebuilt from the stored hyperparameters).

At a pose a model gives (:class:`PoseModel`):

* :meth:`~PosePredictionSide.mode_set` — the modes per physical direction, each with its id,
  presence (fraction of the campaign's recordings that showed it; 1 for a dominant mode) and
  mixture weights (low/high mode where a switch of the dominant mode is modelled);
* :meth:`~PosePredictionSide.predict` — the point value (the more probable mode, never a
  blend) and its latent std; :meth:`~PosePredictionSide.samples` — joint draws;
  :meth:`~PosePredictionSide.bands` — latent or measurement sets;
* :meth:`~PosePredictionSide.extrapolating`, :attr:`~PosePredictionSide.calibrated`,
  :attr:`~PosePredictionSide.provenance` and :attr:`~PosePredictionSide.kind`.

A command that needs one mode per direction (a single-DOF controller) asks
:func:`pick_mode`, which names the mode it picked and why (the largest compliance peak at the
pose) instead of failing on a multi-mode model.

:func:`robovib.gp.loader.load_pose_model` is the one loader of a pose-model file.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np

from .._threads import single_blas_thread
from ..modal.parameters import ModalParameters
from .bands import ModalPredictive, assemble, calibrated_mode_probability
from .dominant_modes import PoseMode, modes_at

__all__ = [
    "DOMINANT",
    "MULTIMODE",
    "ModeAtPose",
    "PickedMode",
    "PoseModel",
    "PosePredictionSide",
    "physical_direction",
    "pick_mode",
]

#: :attr:`PoseModel.kind` of a model with one (dominant) mode per direction.
DOMINANT = "dominant-mode"
#: :attr:`PoseModel.kind` of a model of every tracked mode (directions are mode ids).
MULTIMODE = "multi-mode"


def physical_direction(mode_id: str) -> str:
    """The physical direction of a model direction: ``"x2"`` -> ``"x"``, ``"x"`` -> ``"x"``.

    Parameters
    ----------
    mode_id : str
        A direction (``x``) or a mode id (direction letters and a number, ``x2``).

    Returns
    -------
    str
        The direction letters.
    """
    return str(mode_id).rstrip("0123456789") or str(mode_id)


@dataclass(frozen=True)
class ModeAtPose:
    """One mode of one direction at one pose, as every pose model gives it.

    Attributes
    ----------
    mode_id
        The model's direction name: ``"x"`` (dominant mode) or a mode id (``"x2"``).
    direction
        Physical direction (``"x"``).
    mode
        Point prediction (the more probable mode) with its latent/measurement std and bands,
        the extrapolation flag and the high-mode probability.
    presence
        Probability that the mode is there at all (fraction of the campaign's recordings that
        showed it; 1 for a dominant mode).
    weights
        Mixture weights ``(low, high)`` of the mode's two components where a switch of the
        dominant mode is modelled, else ``(1.0, 0.0)``.
    """

    mode_id: str
    direction: str
    mode: PoseMode
    presence: float = 1.0
    weights: tuple[float, float] = (1.0, 0.0)

    @property
    def parameters(self) -> ModalParameters:
        """The point prediction as :class:`~robovib.modal.ModalParameters` (SI)."""
        return self.mode.parameters

    @property
    def compliance_peak_m_per_n(self) -> float:
        """Peak of the mode's driving-point compliance, ``1 / (2 ζ √(1 - ζ²) k)`` [m/N]."""
        p = self.mode.parameters
        z = min(float(p.damping_ratio), 0.999)
        return 1.0 / (2.0 * max(z, 1e-12) * math.sqrt(1.0 - z * z) * p.stiffness_n_per_m)

    def to_dict(self) -> dict:
        """JSON-ready: the mode (:meth:`PoseMode.to_dict`) with id, direction, presence, weights.

        Returns
        -------
        dict
            Plain JSON types, units in the keys.
        """
        return {
            "mode_id": self.mode_id,
            "direction": self.direction,
            "presence": self.presence,
            "mixture_weights": list(self.weights),
            "compliance_peak_m_per_n": self.compliance_peak_m_per_n,
            **self.mode.to_dict(),
        }


@runtime_checkable
class PoseModel(Protocol):
    """What every pose model gives (module docstring); honoured by
    :class:`robovib.gp.PoseModalModel` and :class:`robovib.gp.saved_model.PosePredictor`.

    Inputs ``X`` are (n, n_inputs) poses in the units of ``input_names`` (``x_mm``, ``rz_deg``);
    every output is SI.
    """

    input_names: tuple[str, ...]
    directions_: tuple[str, ...]
    output_names_: tuple[str, ...]
    output_units_: tuple[str, ...]

    @property
    def kind(self) -> str: ...  # DOMINANT or MULTIMODE

    @property
    def calibrated(self) -> bool: ...

    @property
    def provenance(self) -> dict: ...

    def predict(self, X, return_std: bool = False): ...

    def predictive(self, X) -> ModalPredictive: ...

    def modes(self, X) -> list[dict[str, PoseMode]]: ...

    def mode_set(self, X) -> list[dict[str, tuple[ModeAtPose, ...]]]: ...

    def samples(self, X, n_samples: int, rng=None, kind: str = "latent") -> np.ndarray: ...

    def bands(self, X, level: float = 0.95, kind: str = "latent") -> list[list[list]]: ...

    def extrapolating(self, X) -> np.ndarray: ...

    def outside_inputs(self, X) -> np.ndarray: ...

    def input_range(self) -> dict[str, tuple[float, float]]: ...

    def mode_switch_probability(self, X) -> np.ndarray | None: ...


class PosePredictionSide:
    """The one prediction side of a pose model (:class:`PoseModel`), shared by
    :class:`~robovib.gp.PoseModalModel` and :class:`~robovib.gp.saved_model.PosePredictor`.

    A subclass provides :meth:`_prediction_parts` — ``(estimator, columns)`` pairs whose
    estimator has ``switches_mode`` (bool), ``predict(X) -> (mean, std)`` and either ``noise_std``
    (a smooth GP group) or ``components(X)`` and ``high_mode_probability(X)`` (a mode switch)
    — and the fitted attributes ``input_names_``, ``directions_``, ``output_names_``,
    ``output_units_``, ``n_outputs_``, ``region_``, ``calibration_`` and (optionally)
    ``provenance_``.
    """

    def _prediction_parts(self) -> list:  # pragma: no cover - the subclasses define it
        raise NotImplementedError

    def _require_fitted(self) -> None:
        """Raise where the model cannot predict yet (the fitted model overrides it)."""

    def _check_X(self, X) -> np.ndarray:
        self._require_fitted()
        X = np.asarray(X, float)
        n_in = len(self.input_names_)
        if X.ndim == 1:
            X = X[:, None] if n_in == 1 else X[None, :]
        if X.ndim != 2 or X.shape[1] != n_in:
            raise ValueError(
                f"X must be (n, {n_in}) with columns {list(self.input_names_)}, got shape {X.shape}"
            )
        if not np.all(np.isfinite(X)):
            raise ValueError(f"X contains NaN or inf (columns {list(self.input_names_)})")
        return X

    # ------------------------------------------------------------------ point and bands
    def predict(self, X, return_std: bool = False):
        """Posterior mean (thesis Eq. 9) and optionally latent std (Eq. 10) of every output.

        Parameters
        ----------
        X : array_like (n, n_inputs)
            Poses in the units of ``input_names``.
        return_std : bool
            Also return the latent standard deviation.

        Returns
        -------
        mean : numpy.ndarray (n, 3 * n_directions)
            SI, columns ``output_names_``; in a direction with a mode switch, the values of the
            more probable mode (never a blend).
        std : numpy.ndarray (n, 3 * n_directions), if ``return_std``

        Raises
        ------
        ValueError
            Wrong shape or NaN in ``X``.

        Examples
        --------
        >>> from robovib.gp import load_chapter3_model
        >>> mean, std = load_chapter3_model().predict([[2400.0, 0.0, 45.0]], return_std=True)
        >>> mean.shape == std.shape == (1, 9)
        True
        """
        X = self._check_X(X)
        mean = np.empty((X.shape[0], self.n_outputs_))
        std = np.empty_like(mean)
        with single_blas_thread():  # many small matrices: threads only contend
            for est, cols in self._prediction_parts():
                mean[:, cols], std[:, cols] = est.predict(X)
        return (mean, std) if return_std else mean

    def _raw_predictive(self, X) -> ModalPredictive:
        """The GP posterior as a :class:`ModalPredictive`, before calibration."""
        X = self._check_X(X)
        parts = []
        with single_blas_thread():
            for est, cols in self._prediction_parts():
                if est.switches_mode:
                    parts.append((cols, *est.components(X)))
                else:
                    m, s = est.predict(X)
                    parts.append((cols, None, (m, s, est.noise_std), None))
        return assemble(self.output_names_, self.output_units_, self.directions_, X.shape[0], parts)

    def predictive(self, X) -> ModalPredictive:
        """Calibrated predictive distribution of every output (latent and measurement, modes).

        See :mod:`robovib.gp.bands` and ``docs/bands.md``.

        Parameters
        ----------
        X : array_like (n, n_inputs)
            Poses in the units named by ``input_names``.

        Returns
        -------
        ModalPredictive
            Per output a mixture of the low and high mode (where a switch is modelled) with
            the calibration of ``calibration_`` (none: the plain GP).

        Examples
        --------
        >>> from robovib.gp import load_chapter3_model
        >>> pred = load_chapter3_model().predictive([[2400.0, 0.0, 45.0]])
        >>> len(pred.intervals(0.95)[0]) == 9
        True
        """
        raw = self._raw_predictive(X)
        cal = getattr(self, "calibration_", None)
        if cal is None:
            return raw
        return raw.with_calibration(cal.scale, cal.dof, cal.gamma, cal.ref_std, cal.mode_logit)

    def samples(self, X, n_samples: int, rng=None, kind: str = "latent") -> np.ndarray:
        """Joint draws of every output (:meth:`ModalPredictive.sample`), SI.

        Parameters
        ----------
        X : array_like (n, n_inputs)
            Poses.
        n_samples : int
            Number of draws.
        rng : int or numpy.random.Generator, optional
            Seed.
        kind : {"latent", "measurement"}
            The modal parameters themselves, or a new hammer test.

        Returns
        -------
        numpy.ndarray (n_samples, n, n_outputs)
            The mode of a direction is drawn once per pose, so fn, k, c belong to one mode.
        """
        return self.predictive(X).sample(int(n_samples), rng, kind=kind)

    def bands(self, X, level: float = 0.95, kind: str = "latent") -> list[list[list]]:
        """Per pose and output the ``level`` set: one ``[low, high]`` interval, or two at an
        uncertain mode switch (:meth:`ModalPredictive.intervals`), SI.

        Parameters
        ----------
        X : array_like (n, n_inputs)
            Poses.
        level : float
            Probability of the set.
        kind : {"latent", "measurement"}
            Band of the modal parameter, or of a new measurement.

        Returns
        -------
        list
            ``[pose][output] -> list of [low, high]``.
        """
        return self.predictive(X).intervals(level, kind)

    # ------------------------------------------------------------------ modes
    def modes(self, X) -> list[dict[str, PoseMode]]:
        """The mode of each model direction at each pose (one dict per row of ``X``).

        See ``docs/methods.md`` section 3 (GP pose models).

        Parameters
        ----------
        X : array_like (n, n_inputs)
            Poses in the units named by ``input_names`` (e.g. x [mm], y [mm], rz [deg]).

        Returns
        -------
        list of dict
            One ``{direction: PoseMode}`` per pose: the mean :class:`~robovib.modal.ModalParameters`
            (SI), the std of fn [Hz], k [N/m] and c [N s/m], the extrapolation flag and the
            mode-switch probability (or None).

        Raises
        ------
        ValueError
            If a predicted mean is not a physical mode (fn or k <= 0, c < 0), which happens only
            far outside the calibrated workspace; wrong shape or NaN in ``X``.

        Examples
        --------
        >>> from robovib.gp import load_chapter3_model
        >>> mode = load_chapter3_model().modes([[2400.0, 0.0, 45.0]])[0]["x"]
        >>> mode.parameters.natural_frequency_hz > 0
        True
        """
        return modes_at(self, self._check_X(X))

    def mode_set(self, X) -> list[dict[str, tuple[ModeAtPose, ...]]]:
        """Every modelled mode per *physical* direction at each pose (the contract's modes).

        A dominant-mode model gives one mode per direction (ids ``x, y, z``); a multi-mode
        model every tracked mode (ids ``x1, x2, ...``, sorted), each with the presence of the
        campaign's provenance.

        Parameters
        ----------
        X : array_like (n, n_inputs)
            Poses in the units named by ``input_names``.

        Returns
        -------
        list of dict
            One ``{direction: (ModeAtPose, ...)}`` per pose.

        Examples
        --------
        >>> from robovib.gp import load_chapter3_model
        >>> s = load_chapter3_model().mode_set([[2400.0, 0.0, 45.0]])[0]
        >>> [m.mode_id for m in s["x"]], s["x"][0].presence
        (['x'], 1.0)
        """
        rows = self.modes(X)
        presence = self._mode_presence()
        out = []
        for row in rows:
            per: dict[str, list[ModeAtPose]] = {}
            for k, pm in row.items():
                p = pm.high_mode_probability
                weights = (1.0, 0.0) if p is None else (1.0 - float(p), float(p))
                per.setdefault(physical_direction(k), []).append(
                    ModeAtPose(k, physical_direction(k), pm, presence.get(k, 1.0), weights)
                )
            out.append({d: tuple(v) for d, v in per.items()})
        return out

    def _mode_presence(self) -> dict[str, float]:
        prov = self.provenance
        if "mode_presence" not in prov:
            return {}
        table = json.loads(str(prov["mode_presence"]))
        return {k: float(v.get("presence", 1.0)) for k, v in table.items()}

    # ------------------------------------------------------------------ region, switches
    def outside_inputs(self, X) -> np.ndarray:
        """(n, n_inputs) bool: an input value outside the training range of that input.

        Parameters
        ----------
        X : array_like (n, n_inputs)
            Poses in the units of ``input_names``.

        Returns
        -------
        numpy.ndarray
            True where an input value is below the smallest or above the largest training
            value of that input.
        """
        return self.region_.outside_inputs(self._check_X(X))

    def extrapolating(self, X) -> np.ndarray:
        """(n,) bool: the pose is outside the calibrated inputs.

        Outside means outside the box of the training inputs (per input) or, for two or more
        inputs, outside the convex hull of the training poses (inside the box but off the
        measured workspace); one rule for every pose model:
        :class:`robovib.gp.extrapolation.TrainingRegion`.

        Parameters
        ----------
        X : array_like (n, n_inputs)
            Poses in the units of ``input_names``.

        Returns
        -------
        numpy.ndarray
            True where the pose is outside the calibrated region.
        """
        return self.region_.extrapolating(self._check_X(X))

    def mode_switch_probability(self, X) -> np.ndarray | None:
        """(n, n_directions) probability that the high mode dominates; None without switches.

        Columns of directions without a modelled switch are NaN. Where the model is calibrated,
        the classifier's probability recalibrated on the grouped CV (Platt scaling).

        Parameters
        ----------
        X : array_like (n, n_inputs)
            Poses in the units of ``input_names``.

        Returns
        -------
        numpy.ndarray or None
            Probability in [0, 1] that the high mode dominates, per direction (columns
            ``directions_``); None when no direction has a modelled mode switch.
        """
        X = self._check_X(X)
        parts = [(e, c) for e, c in self._prediction_parts() if e.switches_mode]
        if not parts:
            return None
        p = np.full((X.shape[0], len(self.directions_)), np.nan)
        for est, cols in parts:
            p[:, cols[0] // 3] = est.high_mode_probability(X)
        return calibrated_mode_probability(p, getattr(self, "calibration_", None))

    def input_range(self) -> dict[str, tuple[float, float]]:
        """The training range of every input, ``{name: (min, max)}`` in the input's units.

        Returns
        -------
        dict
            E.g. ``{"x_mm": (2100.0, 2550.0), ...}``: where the model interpolates.
        """
        self._require_fitted()
        lo, hi = self.region_.lo, self.region_.hi
        return {n: (float(a), float(b)) for n, a, b in zip(self.input_names_, lo, hi, strict=True)}

    # ------------------------------------------------------------------ what it is
    @property
    def kind(self) -> str:
        """:data:`MULTIMODE` where the directions are mode ids (``x1``), else :data:`DOMINANT`."""
        dirs = tuple(getattr(self, "directions_", None) or self.directions)
        return MULTIMODE if any(physical_direction(d) != d for d in dirs) else DOMINANT

    @property
    def calibrated(self) -> bool:
        """Whether the bands are calibrated by grouped cross-validation (``calibration_``)."""
        return getattr(self, "calibration_", None) is not None

    @property
    def provenance(self) -> dict:
        """Where the model came from (data source, command, mode presence ...); may be empty."""
        return dict(getattr(self, "provenance_", None) or {})


# -------------------------------------------------------------------------- one mode
@dataclass(frozen=True)
class PickedMode:
    """The one mode a single-mode command uses in a direction, and why.

    Attributes
    ----------
    mode
        The mode picked.
    candidates
        Every mode of the direction at the pose.
    reason
        One sentence saying how it was picked (empty where the direction has one mode).
    """

    mode: ModeAtPose
    candidates: tuple[ModeAtPose, ...]
    reason: str = ""


def pick_mode(model: PoseModel, pose, direction: str) -> PickedMode:
    """The mode of ``direction`` with the largest compliance peak at ``pose``, and why.

    A dominant-mode model has one mode per direction (no choice, no reason). In a multi-mode
    model the mode that moves the tool most under a force at its resonance,
    ``max 1 / (2 ζ √(1 - ζ²) k)``, is the one a single-mode design (an LQR gain, a
    single-DOF schedule) must control; the others are named in the reason.

    Parameters
    ----------
    model : PoseModel
        Any pose model.
    pose : array_like (n_inputs,)
        One pose in the units of ``model.input_names``.
    direction : str
        Physical direction (``x``, ``y``, ``z``).

    Returns
    -------
    PickedMode

    Raises
    ------
    ValueError
        The model has no mode in ``direction`` (the message lists those it has).

    Examples
    --------
    >>> from robovib.gp import load_chapter3_model
    >>> pick_mode(load_chapter3_model(), [2400.0, 0.0, 45.0], "x").mode.mode_id
    'x'
    """
    row = model.mode_set(np.asarray(pose, float).reshape(1, -1))[0]
    if direction not in row:
        raise ValueError(
            f"unknown direction {direction!r}: the model has modes in "
            f"{', '.join(sorted(row))} (mode ids {', '.join(model.directions_)})"
        )
    cands = row[direction]
    if len(cands) == 1:
        return PickedMode(cands[0], cands)
    best = max(cands, key=lambda m: m.compliance_peak_m_per_n)
    others = ", ".join(
        f"{m.mode_id} {m.parameters.natural_frequency_hz:.1f} Hz "
        f"{m.compliance_peak_m_per_n * 1e6:.3g} µm/N"
        for m in cands
        if m is not best
    )
    reason = (
        f"{direction}: the model has {len(cands)} modes; using {best.mode_id} "
        f"({best.parameters.natural_frequency_hz:.1f} Hz), the largest compliance peak at this "
        f"pose ({best.compliance_peak_m_per_n * 1e6:.3g} µm/N; {others})"
    )
    return PickedMode(best, cands, reason)
