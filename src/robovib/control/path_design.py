"""A path through any pose model, with the modes along it computed once (thesis ch. 4).

:class:`ControlPath` is the tool path: a polyline of poses in the model's input units (a line
from ``--start`` to ``--end``, or the rows of a path CSV), measured by the tool-tip travel
``s`` [m] (the inputs ``x_mm``, ``y_mm``, ``z_mm``; or the input ``s_m`` of a path model).
:class:`PathDesign` asks the pose model for the modes at the design points in one call
(``model.modes(poses)``, the public :class:`~robovib.gp.PoseModalModel` API) and answers the
controller designs of :mod:`robovib.control.design` as a path model over ``s_m`` would.

A multi-mode model (directions ``x1, x2, ..., z1``) has several modes per direction; the one
that matters for control is the one with the largest peak compliance ``1 / (2 zeta k)``
(median over the path), and it is named in :attr:`PathDesign.mode_names`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..modal.parameters import ModalParameters

__all__ = ["ControlPath", "PathDesign", "control_mode_names"]

_POSITION_INPUTS = ("x_mm", "y_mm", "z_mm")


@dataclass(frozen=True)
class ControlPath:
    """A tool path through a pose model's inputs, measured by the tool-tip travel.

    Attributes
    ----------
    input_names
        The model's input names (e.g. ``("x_mm", "y_mm", "rz_deg")`` or ``("s_m",)``).
    vertices
        (n, n_inputs) poses of the polyline in those units (n >= 2).
    s_m
        (n,) travel from the first vertex [m], strictly increasing.
    """

    input_names: tuple[str, ...]
    vertices: np.ndarray
    s_m: np.ndarray

    @classmethod
    def through(cls, input_names, vertices) -> ControlPath:
        """The polyline through ``vertices`` (n, n_inputs), in the model's input units.

        Parameters
        ----------
        input_names : sequence of str
            The model's inputs.
        vertices : array_like
            (n, n_inputs) poses, n >= 2.

        Returns
        -------
        ControlPath

        Raises
        ------
        ValueError
            Wrong shape, non-finite poses, no position input to measure the travel in, or two
            consecutive vertices at the same position.
        """
        names = tuple(input_names)
        v = np.atleast_2d(np.asarray(vertices, float))
        if v.ndim != 2 or v.shape[1] != len(names) or v.shape[0] < 2:
            raise ValueError(f"a path needs at least 2 poses of {len(names)} coordinates "
                             f"({', '.join(names)}), got shape {v.shape}")  # fmt: skip
        if not np.all(np.isfinite(v)):
            raise ValueError("path poses must be finite")
        if "s_m" in names:
            pos, to_m = [names.index("s_m")], 1.0
        else:
            pos, to_m = [names.index(n) for n in _POSITION_INPUTS if n in names], 1e-3
        if not pos:
            raise ValueError(f"the model's inputs ({', '.join(names)}) have no position "
                             "(x_mm, y_mm, z_mm or s_m) to measure the path in")  # fmt: skip
        step = np.linalg.norm(np.diff(v[:, pos], axis=0), axis=1) * to_m
        if np.any(step <= 0):
            i = int(np.flatnonzero(step <= 0)[0])
            raise ValueError(f"path poses {i} and {i + 1} are at the same position: no travel")
        if "s_m" in names and v[-1, pos[0]] < v[0, pos[0]]:
            v = v[::-1]  # a path model: the travel is its input, increasing
        s = np.concatenate([[0.0], np.cumsum(step)])
        if "s_m" in names:
            s = v[:, pos[0]].copy()
            if np.any(np.diff(s) <= 0):
                raise ValueError("the s_m of a path model's path must be monotonic")
        return cls(names, v, s)

    @property
    def length_m(self) -> float:
        """Tool-tip travel from the first to the last pose [m]."""
        return float(self.s_m[-1] - self.s_m[0])

    def poses_at(self, s_m) -> np.ndarray:
        """Poses (n, n_inputs) at travels ``s_m`` (n,) [m] (held at the ends).

        Parameters
        ----------
        s_m : array_like
            Travels [m].

        Returns
        -------
        numpy.ndarray
            (n, n_inputs) poses in the model's input units.
        """
        s = np.atleast_1d(np.asarray(s_m, float))
        return np.column_stack([np.interp(s, self.s_m, self.vertices[:, j])
                                for j in range(self.vertices.shape[1])])  # fmt: skip

    def coordinate(self, poses) -> np.ndarray:
        """Travel [m] of the nearest point of the path to each pose (n, n_inputs).

        Parameters
        ----------
        poses : array_like
            (n, n_inputs) poses in the model's input units (or (n,) of a path model).

        Returns
        -------
        numpy.ndarray
            (n,) travels [m].
        """
        p = np.asarray(poses, float)
        if self.input_names == ("s_m",):
            return np.clip(p.reshape(-1), self.s_m[0], self.s_m[-1])
        p = np.atleast_2d(p)
        pos = [self.input_names.index(n) for n in _POSITION_INPUTS if n in self.input_names]
        xy = p[:, pos]
        best_d = np.full(xy.shape[0], np.inf)
        best_s = np.zeros(xy.shape[0])
        for i in range(self.vertices.shape[0] - 1):
            a, b = self.vertices[i, pos], self.vertices[i + 1, pos]
            ab = b - a
            t = np.clip((xy - a) @ ab / (ab @ ab), 0.0, 1.0)
            d = np.linalg.norm(xy - (a + t[:, None] * ab), axis=1)
            better = d < best_d
            best_d[better] = d[better]
            best_s[better] = self.s_m[i] + t[better] * (self.s_m[i + 1] - self.s_m[i])
        return best_s

    def to_dict(self) -> dict:
        """JSON-ready: input names, vertices (model input units) and travels [m].

        Returns
        -------
        dict
        """
        return {"input_names": list(self.input_names), "vertices": self.vertices.tolist(),
                "s_m": self.s_m.tolist()}  # fmt: skip

    @classmethod
    def from_dict(cls, doc: dict) -> ControlPath:
        """The path of :meth:`to_dict` (checked again).

        Parameters
        ----------
        doc : dict
            From :meth:`to_dict`.

        Returns
        -------
        ControlPath
        """
        return cls.through(doc["input_names"], doc["vertices"])


def _peak_compliance(p: ModalParameters) -> float:
    return 1.0 / (2.0 * p.damping_ratio * p.stiffness_n_per_m)


def control_mode_names(rows: list[dict], direction: str) -> str:
    """The model output that is ``direction``'s mode for control at these poses.

    A dominant-mode model has ``direction`` itself; a multi-mode model (``x1, x2, ...``) gives
    the mode of the largest median peak compliance ``1 / (2 zeta k)`` along the rows.

    Parameters
    ----------
    rows : list of dict
        ``model.modes(poses)``.
    direction : str
        ``x``, ``y`` or ``z``.

    Returns
    -------
    str
        The model output's name.

    Raises
    ------
    ValueError
        The model has no mode in that direction.
    """
    keys = list(rows[0])
    if direction in keys:
        return direction
    cands = [k for k in keys if k.rstrip("0123456789") == direction and k != direction]
    if not cands:
        raise ValueError(f"the model has no {direction} mode (outputs: {', '.join(keys)})")
    return max(cands, key=lambda k: np.median([_peak_compliance(r[k].parameters) for r in rows]))


class PathDesign:
    """The pose model along a :class:`ControlPath`: modes at the design points, computed once.

    It answers ``modes(X)`` for ``X`` of shape (n, 1) in path distance ``s_m`` [m], as a path
    model does, so every design of :mod:`robovib.control.design` runs on it unchanged; the
    direction keys are ``x``, ``y``, ``z`` (the chosen mode of a multi-mode model).

    Parameters
    ----------
    model
        A fitted pose model with ``modes(X)`` and ``input_names`` (dominant or multi-mode).
    path
        The tool path in the model's inputs.
    directions
        The controlled directions (``x``, ``y``, ``z``).
    n_points
        Design points along the path (>= 5).
    """

    input_names = ("s_m",)

    def __init__(self, model, path: ControlPath, directions=("x", "z"), n_points: int = 21):
        if int(n_points) != n_points or n_points < 5:
            raise ValueError(f"n_points must be a whole number >= 5, got {n_points!r}")
        if tuple(getattr(model, "input_names", ())) != path.input_names:
            raise ValueError(f"the path is in {path.input_names} but the model's inputs are "
                             f"{tuple(getattr(model, 'input_names', ()))}")  # fmt: skip
        self.model = model
        self.path = path
        self.grid_s_m = np.linspace(path.s_m[0], path.s_m[-1], int(n_points))
        self.poses = path.poses_at(self.grid_s_m)
        rows = model.modes(self.poses)  # the one model call of the design
        self.mode_names = {d: control_mode_names(rows, d) for d in directions}
        self.directions_ = tuple(directions)
        self._cache = {float(s): {d: r[self.mode_names[d]] for d in directions}
                       for s, r in zip(self.grid_s_m, rows, strict=True)}  # fmt: skip
        self.extrapolating = np.array(
            [any(bool(r[self.mode_names[d]].extrapolating) for d in directions) for r in rows]
        )

    def modes(self, X) -> list[dict]:
        """``{direction: PoseMode}`` at path distances ``X`` (n, 1) [m].

        Parameters
        ----------
        X : array_like
            (n, 1) path distances [m].

        Returns
        -------
        list of dict
            One ``{direction: PoseMode}`` per row (the design points from the cache, any other
            distance from one model call).
        """
        s = np.asarray(X, float).reshape(-1)
        missing = [v for v in s.tolist() if v not in self._cache]
        if missing:
            rows = self.model.modes(self.path.poses_at(missing))
            for v, r in zip(missing, rows, strict=True):
                self._cache[v] = {d: r[self.mode_names[d]] for d in self.directions_}
        return [self._cache[v] for v in s.tolist()]

    def provenance(self) -> dict:
        """What the design came from: model type, inputs, chosen modes, its provenance.

        Returns
        -------
        dict
            ``model_type``, ``input_names``, ``control_modes``, ``model_provenance`` and
            ``extrapolating_points``.
        """
        prov = getattr(self.model, "provenance_", None) or {}
        return {"model_type": type(self.model).__name__,
                "input_names": list(self.path.input_names),
                "control_modes": dict(self.mode_names),
                "model_provenance": {str(k): (v if isinstance(v, int | float | str | bool) else str(v))
                                     for k, v in dict(prov).items()},
                "extrapolating_points": int(np.sum(self.extrapolating))}  # fmt: skip
