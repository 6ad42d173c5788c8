"""The fits of every FRF of a file: dominant mode and, optionally, every mode of a band.

What ``robovib modal fit`` runs (the CLI only reads the file and renders the result).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from ..frf.core import FRF
from .lscf import MultiModeFit
from .sdof import ModalFit

__all__ = ["FRFFits", "fit_frfs"]


@dataclass(frozen=True)
class FRFFits:
    """One FRF with its dominant-mode fit and, if asked for, its multi-mode fit.

    Attributes
    ----------
    frf
        The FRF fitted.
    dominant
        Its dominant mode (:func:`robovib.modal.fit_dominant_mode`).
    modes
        Every mode of the band (:func:`robovib.modal.fit_modes`), or None.
    """

    frf: FRF
    dominant: ModalFit
    modes: MultiModeFit | None = None

    @property
    def flags(self) -> tuple[str, ...]:
        """Reasons not to trust the fits: the dominant fit's, then the multi-mode fit's.

        Returns
        -------
        tuple of str
            Empty when no fit is flagged.
        """
        return (*self.dominant.flags, *(self.modes.flags if self.modes is not None else ()))

    @property
    def flagged(self) -> bool:
        """Whether either fit is flagged.

        Returns
        -------
        bool
            True when a fit says it should not be trusted.
        """
        return self.dominant.flagged or (self.modes is not None and self.modes.flagged)

    def to_dict(self, index: int) -> dict:
        """JSON document of the fits (``modal fit --json``, one entry of ``frfs``).

        Parameters
        ----------
        index : int
            Position of the FRF in its file.

        Returns
        -------
        dict
            ``index``, ``direction``, ``pose_m_deg``, ``dominant_mode`` and, with a multi-mode
            fit, ``modes`` and ``modes_flags``.
        """
        doc = {
            "index": index,
            "direction": self.frf.direction,
            "pose_m_deg": self.frf.pose,
            "dominant_mode": self.dominant.to_dict(),
        }
        if self.modes is not None:
            doc["modes"] = [m.to_dict() for m in self.modes.modes]
            doc["modes_flags"] = list(self.modes.flags)
        return doc


def fit_frfs(
    frfs: Sequence[FRF],
    band_hz: tuple[float, float] | None = None,
    *,
    all_modes: bool = False,
    max_order: int = 30,
) -> list[FRFFits]:
    """Dominant-mode fit (and optionally an LSCF + LSFD fit of every mode) of each FRF.

    Parameters
    ----------
    frfs : sequence of FRF
        Compliance FRFs [m/N] (e.g. :func:`robovib.io.read_frfs`).
    band_hz : (float, float), optional
        Fit band [Hz]; default: around each FRF's dominant peak.
    all_modes : bool
        Also identify every mode of the band (:func:`robovib.modal.fit_modes`).
    max_order : int
        Highest LSCF model order with ``all_modes``.

    Returns
    -------
    list of FRFFits
        One per FRF, in order. Flagged fits are returned, not raised: see ``flags``.

    Raises
    ------
    ValueError
        A fit that fails, prefixed with the FRF's position (``"FRF 2: ..."``).

    Examples
    --------
    >>> import numpy as np
    >>> from robovib.frf import FRF
    >>> from robovib.modal import ModalParameters
    >>> f = np.linspace(5.0, 40.0, 351)
    >>> mode = ModalParameters(20.0, 2e6, 0.04)
    >>> (fits,) = fit_frfs([FRF(f, mode.compliance(f))])
    >>> round(fits.dominant.parameters.natural_frequency_hz, 2), fits.modes is None
    (20.0, True)
    """
    from .lscf import fit_modes
    from .sdof import fit_dominant_mode

    out = []
    for i, frf in enumerate(frfs):
        try:
            dom = fit_dominant_mode(frf, band_hz)
            multi = fit_modes(frf, band_hz, max_order=max_order) if all_modes else None
        except (ValueError, RuntimeError) as exc:
            raise ValueError(f"FRF {i}: {exc}") from exc
        out.append(FRFFits(frf, dom, multi))
    return out
