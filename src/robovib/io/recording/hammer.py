"""A hammer recording in memory: the hits of one response channel, how they were read, and
the sensor sensitivities of voltage channels."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["HammerRecording", "ReadReport", "Sensitivity"]

_SPEC_TO_QUANTITY = {8: "displacement", 11: "velocity", 12: "acceleration"}
_QUANTITY_TO_SPEC = {v: k for k, v in _SPEC_TO_QUANTITY.items()}
_SI_LABEL = {"acceleration": "m/s^2", "velocity": "m/s", "displacement": "m"}
_DIR_CODE = {"x": 1, "y": 2, "z": 3}
_CODE_DIR = {1: "x", 2: "y", 3: "z"}
_SEGMENT = ("auto", "always", "never")


@dataclass(frozen=True)
class ReadReport:
    """What a reader did with a file.

    Attributes
    ----------
    path
        The file read.
    layout
        ``"paired"`` (one record per hit and channel) or ``"continuous"`` (cut at the impacts).
    records_read
        Data records (UFF datasets 58 or CSV hit blocks / channels) read.
    hits_formed
        Hits returned.
    hits_rejected
        ``(hit label, reason)`` of hits that were found but not formed.
    channels
        Response channels found, e.g. ``("acceleration x node 1", ...)``.
    notes
        Anything else changed on the way (negated records, truncations).
    """

    path: str
    layout: str
    records_read: int
    hits_formed: int
    hits_rejected: tuple[tuple[str, str], ...] = ()
    channels: tuple[str, ...] = ()
    notes: tuple[str, ...] = ()

    def to_dict(self) -> dict:
        return {
            "path": self.path,
            "layout": self.layout,
            "records_read": self.records_read,
            "hits_formed": self.hits_formed,
            "hits_rejected": [{"hit": h, "reason": r} for h, r in self.hits_rejected],
            "channels": list(self.channels),
            "notes": list(self.notes),
        }


@dataclass(frozen=True)
class HammerRecording:
    """Hits of one hammer test, SI units: forces [N], responses [m, m/s or m/s²].

    ``direction`` is the response direction, ``reference_direction`` the force direction
    (None where the file does not say); a recording with both set and different is a cross
    measurement. ``report`` says how the reader formed the hits.

    Attributes
    ----------
    forces
        (n_hits, n) forces [N].
    responses
        (n_hits, n) responses in SI of ``response_quantity``.
    sample_rate_hz
        Sample rate [Hz].
    response_quantity
        ``"acceleration"``, ``"velocity"`` or ``"displacement"``.
    direction, reference_direction
        Response and force directions (None: not in the file).
    pose
        (X, Y, Z [m], Rx, Ry, Rz [deg]) when the file gives it.
    response_node
        Response node of a multi-channel file.
    report
        How the reader formed the hits.
    """

    forces: np.ndarray  #: (n_hits, n_samples)
    responses: np.ndarray  #: (n_hits, n_samples)
    sample_rate_hz: float
    response_quantity: str
    direction: str | None = None
    pose: tuple[float, ...] | None = None
    reference_direction: str | None = None
    response_node: int | None = None
    report: ReadReport | None = field(default=None, compare=False)

    def __post_init__(self) -> None:
        f = np.atleast_2d(np.asarray(self.forces, float))
        r = np.atleast_2d(np.asarray(self.responses, float))
        if f.shape != r.shape:
            raise ValueError(f"forces {f.shape} and responses {r.shape} must have the same shape")
        if not (np.all(np.isfinite(f)) and np.all(np.isfinite(r))):
            raise ValueError("recording contains NaN or inf samples")
        if not self.sample_rate_hz > 0:
            raise ValueError(f"sample_rate_hz must be positive, got {self.sample_rate_hz!r}")
        if self.response_quantity not in _QUANTITY_TO_SPEC:
            raise ValueError(f"unknown response quantity {self.response_quantity!r}")
        for name in ("direction", "reference_direction"):
            v = getattr(self, name)
            if v is not None and v not in _DIR_CODE:
                raise ValueError(f"unknown {name} {v!r}; expected x, y or z")
        object.__setattr__(self, "forces", f)
        object.__setattr__(self, "responses", r)

    @property
    def n_hits(self) -> int:
        return self.forces.shape[0]

    @property
    def is_cross(self) -> bool:
        """True when the response and force directions are both known and differ."""
        return (
            self.direction is not None
            and self.reference_direction is not None
            and self.direction != self.reference_direction
        )


@dataclass(frozen=True)
class Sensitivity:
    """A sensor sensitivity for voltage channels: ``mv_per_unit`` millivolts per ``unit``.

    E.g. ``Sensitivity(2.25, "N")`` for a PCB 086D05 hammer, ``Sensitivity(10.0, "g")`` for an
    accelerometer.

    Attributes
    ----------
    mv_per_unit
        Millivolts per ``unit``.
    unit
        The physical unit (``"N"``, ``"g"``, ``"m/s^2"``, ``"m/s"``, ``"m"``).
    """

    mv_per_unit: float
    unit: str
