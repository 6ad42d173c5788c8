"""The time-domain margin in one batched pass (issue 37 item 2): the compiled loop against the
numpy stepping, the top-down walk against every factor and against single simulated cuts."""

import itertools
from dataclasses import replace

import numpy as np
import pytest

from robovib.milling import ALUMINIUM_7075, CuttingConditions, MillingTool, time_domain
from robovib.milling.sdm import sdm_lobes
from robovib.milling.time_domain import simulate_regenerative_cut, time_domain_limit_ratios
from robovib.milling.uncertainty import ModeDistribution, stability_probability
from robovib.modal import ModalParameters

TOOL = MillingTool()  # 25.4 mm, 2 flutes
COND = CuttingConditions(1750.0, 0.058e-3, 3e-3, 6e-3)
# Every mode of a pose of the virtual robot (as in test_margin_above.py), and its dominant pair.
MX = [ModalParameters(15.615, 3.6648e6, 0.1146), ModalParameters(40.599, 36.6478e6, 0.05),
      ModalParameters(63.55, 41.919e6, 0.0548)]  # fmt: skip
MY = [ModalParameters(8.03, 0.8954e6, 0.1803), ModalParameters(20.877, 8.9536e6, 0.05)]


def _rows(sets, rpm, depth):
    """(b, n_modes) mode arrays of cuts, structure i at rpm[i] and depth[i] (padding: fn 0)."""
    nm = max(len(a) + len(b) for a, b in sets)
    fn, k, z = np.zeros((len(sets), nm)), np.ones((len(sets), nm)), np.full((len(sets), nm), 0.5)
    feed = np.zeros((len(sets), nm), bool)
    for i, (mx, my) in enumerate(sets):
        modes = [*mx, *my]
        fn[i, : len(modes)] = [m.natural_frequency_hz for m in modes]
        k[i, : len(modes)] = [m.stiffness_n_per_m for m in modes]
        z[i, : len(modes)] = [m.damping_ratio for m in modes]
        feed[i, : len(mx)] = True
    return fn, k, z, feed, np.asarray(rpm, float), np.asarray(depth, float)


@pytest.mark.parametrize(
    ("entry", "down", "flutes", "radial_m", "steps"),
    [
        (0, True, 2, 6e-3, 40),
        (7, True, 2, 6e-3, 40),
        (7, False, 2, 6e-3, 40),
        (3, True, 4, 25.4e-3, 40),
        # 45 steps: the free-vibration run is 8 + 8 + 8 + 4 + 1 steps (every path of the loop).
        (0, True, 2, 6e-3, 45),
    ],
)
def test_the_compiled_loop_gives_the_numpy_samples_bit_for_bit(
    entry, down, flutes, radial_m, steps
):
    # Structures with 1 to 5 modes, feed or normal modes only, at different speeds and depths
    # from stable to saturated chatter; up-milling (no flute cuts at the period's end) and a
    # 4-flute tool slotting (two flutes in the cut at once).
    three = ([MX[0], MX[1]], [MY[0]])
    sets = [(MX, MY), (MX[:1], MY[:1]), (MX[:2], []), ([], MY), three, (MX[:1], MY), (MX, MY)]
    rpm = [1750.0, 2600.0, 900.0, 3100.0, 1200.0, 2000.0, 2900.0]
    depth = [0.5e-3, 4e-3, 2e-3, 1e-3, 8e-3, 3e-3, 2.2e-3]
    fn, k, z, feed, rpm, depth = _rows(sets, rpm, depth)
    # One row lists its normal mode first: only the order within a direction counts.
    order = [2, 0, 1, 3, 4]
    fn[4], k[4], z[4], feed[4] = fn[4, order], k[4, order], z[4, order], feed[4, order]
    sim = dict(steps_per_tooth=steps, n_tooth_periods=60, entry_tooth_periods=entry)
    tool = MillingTool(n_flutes=flutes)
    cond = replace(COND, down_milling=down, radial_depth_m=radial_m)
    if flutes == 4:  # slotting: much larger forces, shallower cuts
        depth = depth / 2
    ref = time_domain._step_rows(fn, k, z, feed, rpm, depth, tool, cond, ALUMINIUM_7075,
                                 record="poincare", **sim)  # fmt: skip
    for chunk in (3, 128):
        got = time_domain._poincare_rows(fn, k, z, feed, rpm, depth, tool, cond, ALUMINIUM_7075,
                                         chunk=chunk, **sim)  # fmt: skip
        np.testing.assert_array_equal(got, ref)
    # The record covers chatter and stable cuts alike (not a trivial agreement).
    growth, rate, amp = time_domain._poincare_indicators(ref)
    chat = time_domain._is_chatter(growth, rate, amp, 0.1, COND.feed_per_tooth_m)
    assert chat.any() and not chat.all()
    # And the full simulation of one of them samples the same motion.
    one = simulate_regenerative_cut(MX, MY, tool, replace(cond, spindle_rpm=rpm[0]),
                                    ALUMINIUM_7075, depth[:1], **sim)  # fmt: skip
    n_ramp = sim["steps_per_tooth"] * entry
    np.testing.assert_array_equal(one.displacement_m[0, n_ramp + steps - 1 :: steps], ref[0])


def _persistent(pattern: str, factors, above):
    """Reference bracket of one planted verdict pattern over factors + above (the rule of the
    docs: above the linear limit only where the last factor is stable; the onset is the first
    factor of the chattering run that reaches the top), by a plain loop."""
    grid = list(factors) + list(above)
    chat = [c == "X" for c in pattern]
    if chat[len(factors) - 1]:
        chat[len(factors) :] = [True] * len(above)
    for j in range(len(grid)):
        if all(chat[j:]):
            return (0.5 * grid[0], grid[0]) if j == 0 else (grid[j - 1], grid[j])
    top = max(1.0, grid[-1])
    return top, top


def test_the_top_down_walk_gives_every_factors_brackets_for_every_pattern(monkeypatch):
    # Every chatter pattern over 4 factors and 2 above (64 structures, islands included),
    # planted as the verdicts of the cuts: the walk's brackets are the plain rule's, and it
    # simulates the chattering run from the top plus one stable cut, not every factor.
    factors, above = (0.7, 0.8, 0.9, 1.0), (1.1, 1.3)
    grid = factors + above
    patterns = ["".join(p) for p in itertools.product("-X", repeat=len(grid))]
    fns = {float(10 + i): p for i, p in enumerate(patterns)}
    simulated = []

    def planted(fn, k, z, feed, rpm, depth, *args, **kwargs):
        simulated.append(depth.size)
        return np.array([fns[f][grid.index(round(d, 6))] == "X"
                         for f, d in zip(fn[:, 0], depth, strict=True)])  # fmt: skip

    monkeypatch.setattr(time_domain, "_chatter_of_rows", planted)
    sets = [([ModalParameters(f, 1e6, 0.05)], []) for f in fns]
    lim = np.ones((len(sets), 1))
    args = (sets, TOOL, COND, ALUMINIUM_7075, [1750.0], lim)
    expected = np.array([_persistent(p, factors, above) for p in patterns])
    for search in ("top-down", "grid"):
        simulated.clear()
        low, high = time_domain_limit_ratios(*args, factors=factors, above=above, search=search)
        np.testing.assert_array_equal(low[:, 0], expected[:, 0])
        np.testing.assert_array_equal(high[:, 0], expected[:, 1])
        n_cuts = sum(simulated)
        if search == "top-down":
            # per pattern: the trailing chattering run of the factors plus the stable one
            # below; where the last factor is stable, the same walk from the top of above.
            def walk(part):
                run = len(part) - len(part.rstrip("X"))
                return min(run + 1, len(part))

            want = sum(walk(p[: len(factors)]) + (walk(p[len(factors) :])
                       if p[len(factors) - 1] == "-" else 0) for p in patterns)  # fmt: skip
            assert n_cuts == want < len(patterns) * len(grid) * 0.6
    # Without factors above the limit as well (the cap at 1).
    low, high = time_domain_limit_ratios(*args, factors=factors)
    capped = np.array([_persistent(p[: len(factors)], factors, ()) for p in patterns])
    np.testing.assert_array_equal(np.c_[low[:, 0], high[:, 0]], capped)
    with pytest.raises(ValueError, match="search"):
        time_domain_limit_ratios(*args, factors=factors, search="bisect")


def test_batched_brackets_match_single_simulated_cuts():
    # Structures with 2 and 5 modes at their own SDM limits, 3 speeds, with an entry ramp:
    # the brackets of the batched pass (compiled, top-down) are those read off single
    # simulate_regenerative_cut runs at every factor (numpy stepping, full records).
    sets = [(MX, MY), (MX[:1], MY[:1])]
    rpm = np.array([1750.0, 2600.0, 3100.0])
    factors, above = (0.6, 0.8, 0.9, 0.95, 1.0), (1.1, 1.25, 1.45)
    sim = dict(steps_per_tooth=60, n_tooth_periods=120, entry_tooth_periods=5)
    lim = np.array([sdm_lobes(a, b, TOOL, COND, ALUMINIUM_7075, rpm).a_lim_m for a, b in sets])
    low, high = time_domain_limit_ratios(sets, TOOL, COND, ALUMINIUM_7075, rpm, lim,
                                         factors=factors, above=above, **sim)  # fmt: skip
    grid = np.array([*factors, *above])
    for s, (mx, my) in enumerate(sets):
        for r, speed in enumerate(rpm):
            chat = simulate_regenerative_cut(mx, my, TOOL, replace(COND, spindle_rpm=speed),
                                             ALUMINIUM_7075, lim[s, r] * grid, **sim).chatter  # fmt: skip
            pattern = "".join("X" if c else "-" for c in chat)
            assert (low[s, r], high[s, r]) == pytest.approx(_persistent(pattern, factors, above))
    # Neither all stable nor all chattering at the linear limit: both walks are exercised.
    assert np.any(high > 1) and np.any(high <= 1)


def test_stability_probability_with_the_margin_is_that_of_the_numpy_grid(monkeypatch):
    # The P(stable) chart with the time-domain margin is the same, sample for sample, with the
    # compiled top-down pass as with the numpy stepping of every factor (the form before).
    dist = {"x": ModeDistribution(15.6, 3.66e6, 2 * 0.115 * 3.66e6 / (2 * np.pi * 15.6),
                                  0.6, 0.2e6, 2e3),
            "y": ModeDistribution(8.0, 0.9e6, 2 * 0.18 * 0.9e6 / (2 * np.pi * 8.0),
                                  0.3, 0.05e6, 500.0)}  # fmt: skip
    kw = dict(n_samples=8, method="zoa", time_domain_margin=True, margin_samples=3,
              method_error=False, fit_bias=0.0, rng=3)  # fmt: skip
    rpm = [1750.0, 2900.0]
    fast = stability_probability(dist, TOOL, COND, ALUMINIUM_7075, rpm, **kw)
    grid = time_domain.time_domain_limit_ratios

    def numpy_grid(*args, **kwargs):
        return grid(*args, search="grid", **kwargs)

    monkeypatch.setattr(time_domain, "time_domain_limit_ratios", numpy_grid)
    monkeypatch.setitem(time_domain._COMPILED, "loop", None)  # numba absent: numpy stepping
    slow = stability_probability(dist, TOOL, COND, ALUMINIUM_7075, rpm, **kw)
    np.testing.assert_array_equal(fast.a_lim_samples_m, slow.a_lim_samples_m)
    assert fast.settings["time_domain_ratio"] == slow.settings["time_domain_ratio"]
    assert not np.allclose(fast.a_lim_samples_m[0] / fast.mean.a_lim_m, 1.0)  # a margin applied


def test_slow_speeds_take_enough_steps_for_the_stiffest_mode():
    # At 100 rpm a tooth period is 0.3 s: 120 steps give the 63.55 Hz mode 6 steps per period
    # (simulate_regenerative_cut refuses). The batched pass takes floor(10 fn tau) + 1 = 191
    # there and keeps 120 at 1750 rpm: its brackets are those of single cuts at those steps.
    rpm = np.array([100.0, 1750.0])
    lim = sdm_lobes(MX, MY, TOOL, COND, ALUMINIUM_7075, rpm).a_lim_m[None, :]
    factors, sim = (0.6, 0.8, 0.9, 1.0), dict(n_tooth_periods=40)
    with pytest.raises(ValueError, match="steps per period"):
        simulate_regenerative_cut(MX, MY, TOOL, replace(COND, spindle_rpm=100.0),
                                  ALUMINIUM_7075, lim[0, :1], **sim)  # fmt: skip
    low, high = time_domain_limit_ratios([(MX, MY)], TOOL, COND, ALUMINIUM_7075, rpm, lim,
                                         factors=factors, **sim)  # fmt: skip
    for r, (speed, steps) in enumerate(zip(rpm, (191, 120), strict=True)):
        chat = simulate_regenerative_cut(MX, MY, TOOL, replace(COND, spindle_rpm=speed),
                                         ALUMINIUM_7075, lim[0, r] * np.array(factors),
                                         steps_per_tooth=steps, **sim).chatter  # fmt: skip
        pattern = "".join("X" if c else "-" for c in chat)
        assert (low[0, r], high[0, r]) == pytest.approx(_persistent(pattern, factors, ()))


def test_simulated_stability_limit_bisects_as_single_cuts_do():
    # The compiled verdicts in the bisection are simulate_regenerative_cut's: replaying the
    # same rounds with single cuts gives the same bracket.
    from robovib.milling.time_domain import simulated_stability_limit

    cond = replace(COND, spindle_rpm=2600.0)
    sim = dict(steps_per_tooth=40, n_tooth_periods=80)
    a_lim = sdm_lobes(MX[:1], MY[:1], TOOL, cond, ALUMINIUM_7075, [2600.0]).a_lim_m[0]
    lo, hi = 0.5 * a_lim, 2.0 * a_lim
    got = simulated_stability_limit(MX[:1], MY[:1], TOOL, cond, ALUMINIUM_7075, (lo, hi),
                                    n_bisections=4, n_parallel=2, **sim)  # fmt: skip
    for _ in range(4):
        trial = np.linspace(lo, hi, 4)[1:-1]
        chat = simulate_regenerative_cut(MX[:1], MY[:1], TOOL, cond, ALUMINIUM_7075, trial,
                                         **sim).chatter  # fmt: skip
        lo = max([lo, *trial[~chat]])
        hi = min([hi, *trial[chat]])
    assert got == (lo, hi)
    assert 0.5 * a_lim < got[0] < got[1] < 2.0 * a_lim
