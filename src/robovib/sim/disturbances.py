"""What a real cut adds to the ideal simulated one: the disturbances of the closed-loop runs.

:class:`CutDisturbances` collects them, every one off (0) by default and in a physical unit:

* ``speed_error_pct`` — the spindle turns this much faster than its nominal speed [%];
* ``speed_drift_pct`` — and drifts linearly by this much more over the cut [%];
* ``runout_um`` — radial tooth runout [µm] (:attr:`~robovib.milling.MillingTool.runout_m`):
  the teeth cut unequal chips, adding a once-per-revolution force component;
* ``nonperiodic_rel`` — a random force component low-pass filtered below ``nonperiodic_band_hz``
  (it excites the structural modes), std relative to the force's std per direction;
* ``engagement_pct`` — the radial engagement changes along the path: the force is scaled by
  ``1 + engagement_pct/100 * sin(2 pi t / T_cut)``, with the tool entering and leaving over one
  revolution each (linear ramps of the force);
* ``force_noise_n`` / ``force_bias_n`` — extra force-sensor white noise (std) and bias [N];
* ``actuator_gain_pct`` — the robot applies ``1 + actuator_gain_pct/100`` x the commanded
  correction (:attr:`~robovib.sim.CommandChannel.gain`);
* ``delay_error_ms`` — the true transport delay is the nominal one plus this [ms]; the
  controllers are designed for the nominal delay.

:data:`REALISTIC_LEVELS` holds one realistic level per disturbance (sources in its comment).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields, replace

import numpy as np
from scipy import signal

from ..milling.forces import CuttingCoefficients, CuttingConditions, MillingTool, milling_forces
from .plant import CommandChannel

__all__ = ["DISTURBANCE_UNITS", "REALISTIC_LEVELS", "CutDisturbances"]

#: Unit of every disturbance field (the CLI's ``--disturbance NAME=VALUE``).
DISTURBANCE_UNITS = {
    "speed_error_pct": "% of the nominal spindle speed",
    "speed_drift_pct": "% of the nominal spindle speed, change over the cut",
    "runout_um": "µm radial tooth runout",
    "nonperiodic_rel": "std relative to the cutting force's std",
    "engagement_pct": "% change of the force along the cut (+ entry/exit ramps)",
    "force_noise_n": "N std, force-sensor white noise (on top of 0.5 N)",
    "force_bias_n": "N, force-sensor bias (all directions)",
    "actuator_gain_pct": "% error of the actuator gain",
    "delay_error_ms": "ms of transport delay the controller does not know",
}


@dataclass(frozen=True)
class CutDisturbances:
    """Disturbances of a simulated cut; all 0 (off) by default (units: :data:`DISTURBANCE_UNITS`).

    Attributes
    ----------
    speed_error_pct
        The spindle turns this much faster than its nominal speed [%], in (-50, 50).
    speed_drift_pct
        Further linear change of the spindle speed over the cut [% of nominal], in (-50, 50).
    runout_um
        Extra radial tooth runout [µm] (>= 0), added to the tool's
        :attr:`~robovib.milling.MillingTool.runout_m`.
    nonperiodic_rel
        Std of the random, low-pass filtered force component relative to the cutting force's
        std per direction (>= 0; 0.3: 30 %).
    engagement_pct
        Amplitude of the change of the force along the cut [%] (>= 0), with entry and exit
        ramps of one revolution each.
    force_noise_n
        Extra force-sensor white noise, std [N] (>= 0).
    force_bias_n
        Force-sensor bias [N] (all directions).
    actuator_gain_pct
        Error of the actuator gain [%] (> -100): the robot applies ``1 + actuator_gain_pct/100``
        x the commanded correction.
    delay_error_ms
        True transport delay minus the nominal one [ms], unknown to the controllers.
    nonperiodic_band_hz
        Cut-off frequency of the low-pass filter of the non-periodic force [Hz] (> 0).
    """

    speed_error_pct: float = 0.0
    speed_drift_pct: float = 0.0
    runout_um: float = 0.0
    nonperiodic_rel: float = 0.0
    engagement_pct: float = 0.0
    force_noise_n: float = 0.0
    force_bias_n: float = 0.0
    actuator_gain_pct: float = 0.0
    delay_error_ms: float = 0.0
    nonperiodic_band_hz: float = 40.0

    def __post_init__(self) -> None:
        for f in fields(self):
            v = getattr(self, f.name)
            if not math.isfinite(v):
                raise ValueError(f"{f.name} must be finite, got {v!r}")
        for name in ("runout_um", "nonperiodic_rel", "force_noise_n", "engagement_pct"):
            if getattr(self, name) < 0:
                raise ValueError(f"{name} must be >= 0, got {getattr(self, name)!r}")
        if not -50 < self.speed_error_pct < 50 or not -50 < self.speed_drift_pct < 50:
            raise ValueError("speed_error_pct and speed_drift_pct must lie in (-50, 50) [%]")
        if not self.actuator_gain_pct > -100:
            raise ValueError(
                f"actuator_gain_pct must be > -100 [%], got {self.actuator_gain_pct!r}"
            )
        if not self.nonperiodic_band_hz > 0:
            raise ValueError("nonperiodic_band_hz must be > 0 [Hz]")

    @classmethod
    def parse(cls, items) -> CutDisturbances:
        """From ``["NAME=VALUE", ...]`` (names of :data:`DISTURBANCE_UNITS`; ``all=F``: every
        disturbance at ``F`` x its realistic level).

        Parameters
        ----------
        items
            Iterable of ``"NAME=VALUE"`` strings, VALUE in the unit of
            :data:`DISTURBANCE_UNITS` (``-`` in NAME is read as ``_``); later items override
            earlier ones.

        Returns
        -------
        CutDisturbances
            The disturbances, the ones not named off (0).

        Raises
        ------
        ValueError
            Unknown name or a value that is not a number.
        """
        out = cls()
        for item in items:
            name, sep, value = str(item).partition("=")
            name = name.strip().replace("-", "_")
            if not sep:
                raise ValueError(f"disturbance {item!r}: expected NAME=VALUE")
            try:
                v = float(value)
            except ValueError:
                raise ValueError(f"disturbance {item!r}: {value!r} is not a number") from None
            if name == "all":
                out = replace(
                    out, **{k: getattr(REALISTIC_LEVELS, k) * v for k in DISTURBANCE_UNITS}
                )
            elif name in DISTURBANCE_UNITS:
                out = replace(out, **{name: v})
            else:
                raise ValueError(
                    f"unknown disturbance {name!r}; expected one of {sorted(DISTURBANCE_UNITS)} or all"
                )
        return out

    def active(self) -> dict[str, float]:
        """The disturbances that are on (name -> value).

        Returns
        -------
        dict of str to float
            Name -> value (unit of :data:`DISTURBANCE_UNITS`) of every nonzero disturbance.
        """
        return {k: getattr(self, k) for k in DISTURBANCE_UNITS if getattr(self, k) != 0}

    def to_dict(self) -> dict:
        return {f.name: getattr(self, f.name) for f in fields(self)}

    def spindle_time(self, t_s) -> np.ndarray:
        """Time at the nominal speed that turns the spindle as far as the true speed by ``t_s``.

        ``∫ (1 + e + d tau / T) dtau`` with ``e`` the speed error, ``d`` the drift over the cut.

        Parameters
        ----------
        t_s
            (n,) increasing sample times [s]; the cut runs from ``t_s[0]`` to ``t_s[-1]``.

        Returns
        -------
        numpy.ndarray
            (n,) times [s] at which a spindle at the nominal speed has turned as far as the true
            spindle at ``t_s`` (equal to ``t_s`` without speed error or drift).
        """
        t = np.asarray(t_s, float)
        dur = max(float(t[-1] - t[0]), 1e-12) if t.size else 1.0
        e, d = self.speed_error_pct / 100, self.speed_drift_pct / 100
        tau = t - t[0] if t.size else t
        return t[0] + (1 + e) * tau + d * tau**2 / (2 * dur) if t.size else t

    def cutting_force(
        self,
        t_s,
        tool: MillingTool,
        cond: CuttingConditions,
        coefficients: CuttingCoefficients,
        rng=None,
    ) -> np.ndarray:
        """Cutting force (n, 3) in the tool frame [N] with the force-side disturbances.

        The force-side disturbances are the speed error and drift, runout, engagement and the
        non-periodic component (the sensor noise and bias are added by the simulation).

        Parameters
        ----------
        t_s
            (n,) increasing sample times [s].
        tool : MillingTool
            The cutter (this object's ``runout_um`` is added to its runout).
        cond : CuttingConditions
            Spindle speed, feed per tooth and depths of cut of the nominal cut.
        coefficients : CuttingCoefficients
            Cutting force coefficients of the material.
        rng
            Seed or :class:`numpy.random.Generator` of the non-periodic force component.

        Returns
        -------
        numpy.ndarray
            (n, 3) cutting force [N] in the tool frame.
        """
        t = np.asarray(t_s, float)
        if self.runout_um > 0:
            tool = replace(tool, runout_m=tool.runout_m + self.runout_um * 1e-6)
        force = milling_forces(self.spindle_time(t), tool, cond, coefficients)
        if self.engagement_pct > 0 and t.size > 1:
            dur = t[-1] - t[0]
            env = 1 + self.engagement_pct / 100 * np.sin(2 * np.pi * (t - t[0]) / dur)
            rev = 60.0 / cond.spindle_rpm
            env *= np.clip((t - t[0]) / rev, 0, 1) * np.clip((t[-1] - t) / rev, 0, 1)
            force = force * env[:, None]
        if self.nonperiodic_rel > 0 and t.size > 16:
            gen = np.random.default_rng(rng)
            fs = 1.0 / float(np.median(np.diff(t)))
            b, a = signal.butter(2, min(self.nonperiodic_band_hz / (fs / 2), 0.99))
            w = signal.lfilter(b, a, gen.normal(size=force.shape), axis=0)
            w /= np.maximum(w.std(axis=0), 1e-30)
            force = force + self.nonperiodic_rel * force.std(axis=0) * w
        return force

    def channel(self, nominal: CommandChannel) -> CommandChannel:
        """The true command channel: ``nominal`` with the delay and gain errors.

        Parameters
        ----------
        nominal : CommandChannel
            The channel the controllers are designed for.

        Returns
        -------
        CommandChannel
            ``nominal`` with ``delay_error_ms`` added to its delay and its gain times
            ``1 + actuator_gain_pct/100``.

        Raises
        ------
        ValueError
            ``delay_error_ms`` makes the delay negative.
        """
        delay = nominal.delay_s + self.delay_error_ms * 1e-3
        if delay < 0:
            raise ValueError(f"delay_error_ms makes the delay negative ({delay * 1e3:.1f} ms)")
        return replace(
            nominal, delay_s=delay, gain=nominal.gain * (1 + self.actuator_gain_pct / 100)
        )

    def scaled(self, factor: float) -> CutDisturbances:
        """Every disturbance times ``factor`` (the 2x levels of the robustness table).

        Parameters
        ----------
        factor
            Multiplier of every disturbance level (``nonperiodic_band_hz`` is kept).

        Returns
        -------
        CutDisturbances
            The scaled disturbances.
        """
        return replace(self, **{k: getattr(self, k) * factor for k in DISTURBANCE_UNITS})


#: Realistic levels (one disturbance each; see the robustness note for the sources):
#: spindle speed 2 % off nominal (asynchronous spindle slip under load, 1-3 %) and 1 % drift
#: over a cut (thermal / load change); 10 µm runout (collet/holder TIR 5-20 µm); a non-periodic
#: force 30 % of the force's std (material inhomogeneity, chip breakage: on top of the 15 %
#: white background of the studies); engagement 10 % along the path; force sensor 2 N noise and
#: 5 N bias (dynamometer drift over a cut); actuator gain 10 %; delay 8 ms (the 24-40 ms range
#: around the thesis' 32 ms).
REALISTIC_LEVELS = CutDisturbances(
    speed_error_pct=2.0,
    speed_drift_pct=1.0,
    runout_um=10.0,
    nonperiodic_rel=0.3,
    engagement_pct=10.0,
    force_noise_n=2.0,
    force_bias_n=5.0,
    actuator_gain_pct=10.0,
    delay_error_ms=8.0,
)
