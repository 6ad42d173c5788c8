"""The time-domain margin above the linear limit (issue 36), against single simulated cuts."""

import numpy as np
import pytest

from robovib.milling import ALUMINIUM_7075, CuttingConditions, MillingTool
from robovib.milling.lobes import zoa_envelope
from robovib.milling.stability import stability_lobes
from robovib.milling.time_domain import simulate_regenerative_cut, time_domain_limit_ratios
from robovib.milling.uncertainty import ModeDistribution, stability_probability
from robovib.modal import ModalParameters

TOOL = MillingTool()
# Every mode of one pose of the virtual robot (fn [Hz], k [N/m], zeta): a dominant mode, a weak
# lightly damped one at 2.6 fn, and in X the ~63 Hz mode. Written out so that the test does
# not move with the virtual robot.
MX = [ModalParameters(15.615, 3.6648e6, 0.1146), ModalParameters(40.599, 36.6478e6, 0.05),
      ModalParameters(63.55, 41.919e6, 0.0548)]  # fmt: skip
MY = [ModalParameters(8.03, 0.8954e6, 0.1803), ModalParameters(20.877, 8.9536e6, 0.05)]
RPM = 3100.0
ABOVE = (1.05, 1.1, 1.15, 1.2, 1.3, 1.45)


def _zoa_limit(mx, my, rpm):
    cond = CuttingConditions(float(rpm[0]), 0.058e-3, 1e-3, 6e-3)
    lobes = stability_lobes(mx, my, TOOL, cond, ALUMINIUM_7075, n_lobes=20)
    return zoa_envelope(lobes, rpm).a_lim_m


def _chatter(mx, my, rpm, depths):
    cond = CuttingConditions(float(rpm), 0.058e-3, float(depths[0]), 6e-3)
    return simulate_regenerative_cut(mx, my, TOOL, cond, ALUMINIUM_7075, depths).chatter


def test_a_time_domain_limit_above_the_linear_one_is_bracketed_as_single_cuts_see_it():
    lim = _zoa_limit(MX, MY, [RPM])
    cond = CuttingConditions(RPM, 0.058e-3, 1e-3, 6e-3)
    low, high = time_domain_limit_ratios([(MX, MY)], TOOL, cond, ALUMINIUM_7075, [RPM],
                                         lim[None, :], above=ABOVE)  # fmt: skip
    capped = time_domain_limit_ratios([(MX, MY)], TOOL, cond, ALUMINIUM_7075, [RPM],
                                      lim[None, :])  # fmt: skip
    # Capped, the bracket says "at the linear limit or above": (1, 1).
    np.testing.assert_array_equal(capped, (np.ones((1, 1)), np.ones((1, 1))))
    assert 1.0 < low[0, 0] < high[0, 0]
    # The reference: each depth simulated on its own, from the linear limit up to the onset.
    grid = np.array([1.0, *[f for f in ABOVE if f <= high[0, 0]]])
    chat = _chatter(MX, MY, RPM, lim[0] * grid)
    assert not chat[:-1].any() and chat[-1]
    assert grid[-2] == pytest.approx(low[0, 0]) and grid[-1] == pytest.approx(high[0, 0])


def test_structures_that_chatter_at_the_linear_limit_are_not_changed():
    # The dominant modes alone chatter at (or below) their linear limit: the factors above are
    # never simulated for them, and their brackets are bit for bit those without them.
    sets = [(MX[:1], MY[:1]), (MX, MY)]
    rpm = np.array([1750.0, RPM])
    lim = np.array([_zoa_limit(a, b, rpm) for a, b in sets])
    cond = CuttingConditions(RPM, 0.058e-3, 1e-3, 6e-3)
    sim = dict(n_tooth_periods=200)
    low0, high0 = time_domain_limit_ratios(sets, TOOL, cond, ALUMINIUM_7075, rpm, lim, **sim)
    low, high = time_domain_limit_ratios(sets, TOOL, cond, ALUMINIUM_7075, rpm, lim,
                                         above=ABOVE, max_batch=4, **sim)  # fmt: skip
    closed = low0 < 1  # chatter found at or below the linear limit
    assert closed.any()
    np.testing.assert_array_equal(low[closed], low0[closed])
    np.testing.assert_array_equal(high[closed], high0[closed])
    for s, r in zip(*np.nonzero(~closed), strict=True):  # the open ones, cut by cut
        cc = CuttingConditions(float(rpm[r]), 0.058e-3, 1e-3, 6e-3)
        f = np.array([1.0, *ABOVE])
        chat = simulate_regenerative_cut(*sets[s], TOOL, cc, ALUMINIUM_7075, lim[s, r] * f,
                                         **sim).chatter  # fmt: skip
        persistent = np.flip(np.logical_and.accumulate(np.flip(chat)))
        if persistent.any():
            j = int(np.argmax(persistent))
            assert (low[s, r], high[s, r]) == pytest.approx((f[j - 1], f[j]))
        else:
            assert low[s, r] == high[s, r] == pytest.approx(ABOVE[-1])


@pytest.mark.parametrize("above", [(1.1, 1.05), (1.0, 1.2), (0.9,), (1.1, np.nan)])
def test_bad_factors_above_are_refused(above):
    cond = CuttingConditions(RPM, 0.058e-3, 1e-3, 6e-3)
    with pytest.raises(ValueError, match="above must increase"):
        time_domain_limit_ratios([(MX, MY)], TOOL, cond, ALUMINIUM_7075, [RPM], [[1e-2]],
                                 above=above)  # fmt: skip


def test_p_stable_of_a_certain_structure_steps_at_its_simulated_limit():
    # A distribution without spread: every sample is the structure above, so P(stable) is 1
    # below its simulated limit and 0 above it; capped at 1 the step sat at the linear limit.
    dist = {"x": [ModeDistribution(m.natural_frequency_hz, m.stiffness_n_per_m,
                                   m.damping_ns_per_m) for m in MX],
            "y": [ModeDistribution(m.natural_frequency_hz, m.stiffness_n_per_m,
                                   m.damping_ns_per_m) for m in MY]}  # fmt: skip
    cond = CuttingConditions(RPM, 0.058e-3, 1e-3, 6e-3)
    lim = _zoa_limit(MX, MY, [RPM])[0]
    kw = dict(n_samples=3, method="zoa", time_domain_margin=True, margin_samples=1,
              method_error=False, fit_bias=0.0, rng=0)  # fmt: skip
    depth = lim * np.array([0.99, 1.04])
    prob = stability_probability(dist, TOOL, cond, ALUMINIUM_7075, [RPM], depth, **kw)
    capped = stability_probability(dist, TOOL, cond, ALUMINIUM_7075, [RPM], depth,
                                   margin_above=(), **kw)  # fmt: skip
    assert prob.settings["time_domain_ratio"][0] > 1.0 == capped.settings["time_domain_ratio"][0]
    np.testing.assert_array_equal(prob.p_stable[0], [1.0, 1.0])
    np.testing.assert_array_equal(capped.p_stable[0], [1.0, 0.0])
