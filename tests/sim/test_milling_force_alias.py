"""simulate_milling's records have no aliased tooth lines (issue 39).

A 2-flute cut at 1750 rpm has its 17th tooth harmonic at 991.67 Hz, which a 1 kHz simulation
would fold to 8.33 Hz. A single-mode robot with its Y mode on 8.33 Hz makes that alias as
loud as it can be. The reference is the closed form: the cutting force is periodic at the
tooth-passing frequency (its Fourier coefficients from ``milling_forces`` on a fine grid over
one period, not from the simulation), so the steady displacement is the sum of its harmonics
through the SDOF receptance ``1 / (k (1 - r^2 + 2 j zeta r))`` and has no line at 8.33 Hz.
"""

from __future__ import annotations

import numpy as np
import pytest

from robovib.milling import ALUMINIUM_7075, CuttingConditions, MillingTool
from robovib.milling.forces import milling_forces
from robovib.sim import ConstantModesRobot, LinearMove, simulate_milling
from robovib.sim.truth import ModeSet

TOOL = MillingTool()
COND = CuttingConditions(1750.0, 0.058e-3, 1e-3, 6e-3)
FS = 1000.0
F_TOOTH = 2 * 1750.0 / 60.0  # 58.33 Hz
F_ALIAS = 17 * F_TOOTH - FS  # the 17th harmonic folded: -8.33 Hz -> 8.33 Hz
FN, K, ZETA = abs(F_ALIAS), 1.0e6, 0.05


def _line(x, f):
    """Amplitude of the line at f [Hz] (a whole number of its periods in x)."""
    t = np.arange(x.size) / FS
    return 2.0 / x.size * abs(np.sum(x * np.exp(-2j * np.pi * f * t)))


def _receptance(f):
    r = f / FN
    return 1.0 / (K * (1 - r**2 + 2j * ZETA * r))


@pytest.fixture(scope="module")
def records():
    # the path feeds along -Y: the feed-normal force acts along base X, where the mode is
    robot = ConstantModesRobot({"x": ModeSet(np.array([[FN]]), np.array([[K]]),
                                             np.array([[ZETA]]))})  # fmt: skip
    move = LinearMove("path", (1.0,), (1.02,))
    kw = dict(background_noise_rel=0.0, force_noise_n=0.0, tracker_noise_m=0.0,
              tracker_resolution_m=0.0, rng=0)  # fmt: skip
    new = simulate_milling(robot, move, TOOL, COND, ALUMINIUM_7075, **kw)
    old = simulate_milling(robot, move, TOOL, COND, ALUMINIUM_7075, force_oversampling=1, **kw)
    return new, old, move


def _expected_line(move, harmonic):
    """|F_h G(h f_tooth)| sinc(h f_tooth / fs): the base-X force's h-th Fourier coefficient
    through the SDOF, times the droop of the force held over a step (its amplitude response;
    the mid-step sample takes out its half-step delay)."""
    feed = move.feed_direction()
    normal = np.array([-feed[1], feed[0], 0.0])
    n = 4096
    t = np.arange(n) / (n * F_TOOTH)  # one tooth period, fine
    local = milling_forces(t, TOOL, COND, ALUMINIUM_7075)
    fx = local[:, 0] * feed[0] + local[:, 1] * normal[0]
    coef = 2.0 / n * np.fft.rfft(fx)[harmonic]
    return abs(coef * _receptance(harmonic * F_TOOTH)) * np.sinc(harmonic * F_TOOTH / FS)


def test_no_alias_line_where_the_closed_form_has_none(records):
    new, old, move = records
    # steady state (the mode decays in 1 / (zeta omega) = 0.38 s), 120 samples = 7 tooth
    # periods = 1 period of the alias: both lines on the DFT grid
    x_new = new.displacement_m[3000:, 0]
    x_new = x_new[: x_new.size // 120 * 120]
    x_old = old.displacement_m[3000:, 0][: x_new.size]
    expect_1 = _expected_line(move, 1)
    # the genuine tooth lines: the closed form (the FIR passes them flat)
    assert _line(x_new, F_TOOTH) == pytest.approx(expect_1, rel=0.01)
    for h in (2, 3):
        assert _line(x_new, h * F_TOOTH) == pytest.approx(_expected_line(move, h), rel=0.01)
    # no line at the alias of the 17th harmonic: the closed form has nothing there
    assert _line(x_new, FN) < 0.01 * expect_1
    # the held 1 kHz force (the old records) puts one there, larger than the tooth line
    assert _line(x_old, FN) > 3 * expect_1
    # and the force record has none either (its own tooth line for scale)
    f_new = new.force_n[3000:, 0][: x_new.size]
    f_old = old.force_n[3000:, 0][: x_new.size]
    assert _line(f_new, FN) < 1e-3 * _line(f_new, F_TOOTH)
    assert _line(f_old, FN) > 0.02 * _line(f_old, F_TOOTH)


def test_force_oversampling_is_checked():
    robot = ConstantModesRobot({})
    move = LinearMove("path", (1.0,), (1.01,))
    for bad in (0, 2.5, True):
        with pytest.raises(ValueError, match="force_oversampling"):
            simulate_milling(robot, move, TOOL, COND, ALUMINIUM_7075, force_oversampling=bad)
