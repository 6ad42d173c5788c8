"""Regenerative milling on the virtual robot against the semi-discretization's predictions."""

import numpy as np
import pytest

from robovib.milling import ALUMINIUM_7075, CuttingCoefficients, CuttingConditions, MillingTool
from robovib.milling.sdm import floquet_multipliers, sdm_lobes
from robovib.milling.time_domain import time_domain_limit_ratio
from robovib.modal import ModalParameters
from robovib.sim import VirtualRobot, simulate_regenerative_cut, simulated_stability_limit

# Cutting coefficients of Al 7075 without edge forces: the tool stays in the cut below the limit,
# so the linear theory applies (see the module docs of robovib.sim.regenerative).
AL_NO_EDGE = CuttingCoefficients(ktc=796e6, krc=168e6, kac=0.0)
TOOL = MillingTool()  # 25.4 mm, 2 flutes
POSES = [(2.4, 0.0, 45.0), (2.2, 0.4, 0.0)]
RPM = 1750.0


def _pose_modes(pose):
    ws = VirtualRobot().workspace
    return ws.modes([pose], "x").at(0), ws.modes([pose], "y").at(0)


@pytest.mark.parametrize("pose", POSES)
def test_simulated_cut_chatters_above_the_sdm_limit_and_not_below(pose):
    mx, my = _pose_modes(pose)
    cond = CuttingConditions(RPM, 0.058e-3, 3e-3, 6e-3, down_milling=True)
    a_lim = sdm_lobes(mx, my, TOOL, cond, AL_NO_EDGE, [RPM]).a_lim_m[0]
    depths = a_lim * np.array([0.8, 1.25])
    cut = simulate_regenerative_cut(mx, my, TOOL, cond, AL_NO_EDGE, depths,
                                    n_tooth_periods=300, steps_per_tooth=60)  # fmt: skip
    assert not cut.chatter[0] and cut.chatter[1]
    assert cut.growth[0] < 1e-2
    # Energy away from the tooth-passing harmonics: none when stable, most of it in chatter.
    assert cut.off_harmonic_fraction[0] < 0.01 < 0.5 < cut.off_harmonic_fraction[1]
    # The stable cut's transient decays at the rate of the predicted Floquet multiplier.
    mu = floquet_multipliers(mx, my, TOOL, cond, AL_NO_EDGE, [RPM], depths[:1])
    assert cut.decay_rate_per_period[0] == pytest.approx(np.log(np.abs(mu[0])), rel=0.1)


def test_simulation_shows_the_flip_lobe_the_zero_order_method_misses():
    mode = ModalParameters(922.0, 1.34e6, 0.011)
    tool = MillingTool(diameter_m=0.02, n_flutes=2, helix_deg=0.0)
    cond = CuttingConditions(17000, 1e-4, 1e-3, 0.001, down_milling=True)
    coef = CuttingCoefficients(6e8, 2e8, 0.0)
    env = sdm_lobes([mode], [], tool, cond, coef, [17000.0])
    assert env.kind[0] == "flip"
    cut = simulate_regenerative_cut([mode], [], tool, cond, coef, env.a_lim_m[0] * np.array([0.9, 1.1]),
                                    n_tooth_periods=300, steps_per_tooth=80)  # fmt: skip
    assert list(cut.chatter) == [False, True]
    # Period doubling: chatter at an odd multiple of half the tooth-passing frequency.
    ratio = cut.chatter_hz[1] / cut.tooth_passing_hz
    assert abs(ratio - 0.5 - round(ratio - 0.5)) < 0.02


def test_regenerative_input_errors():
    mx, my = _pose_modes(POSES[0])
    cond = CuttingConditions(RPM, 0.058e-3, 3e-3, 6e-3)
    with pytest.raises(ValueError, match="depth_m"):
        simulate_regenerative_cut(mx, my, TOOL, cond, AL_NO_EDGE, [-1e-3])
    with pytest.raises(ValueError, match="steps per period"):
        simulate_regenerative_cut(mx, my, TOOL, cond, AL_NO_EDGE, [1e-3], steps_per_tooth=8)
    with pytest.raises(ValueError, match="bracket"):
        simulated_stability_limit(mx, my, TOOL, cond, AL_NO_EDGE, (1e-5, 2e-5))


@pytest.mark.slow
@pytest.mark.parametrize("pose", POSES)
def test_simulated_limit_confirms_sdm_within_10_percent(pose):
    mx, my = _pose_modes(pose)
    cond = CuttingConditions(RPM, 0.058e-3, 3e-3, 6e-3, down_milling=True)
    a_lim = sdm_lobes(mx, my, TOOL, cond, AL_NO_EDGE, [RPM]).a_lim_m[0]
    lo, hi = simulated_stability_limit(mx, my, TOOL, cond, AL_NO_EDGE, (0.7 * a_lim, 1.4 * a_lim),
                                       n_bisections=3, n_tooth_periods=300, steps_per_tooth=60)  # fmt: skip
    assert abs(0.5 * (lo + hi) / a_lim - 1) < 0.10


def test_a_small_grazing_subharmonic_is_not_chatter_but_saturated_chatter_is():
    # With edge forces a flute grazes in and out of the cut at the entry angle: far below the
    # linear limit the Poincaré differences settle at ~1 % of the feed instead of decaying.
    # Linear theory (SDM) calls 0.5x its limit stable and 1.25x unstable; so must the simulation.
    mx, my = _pose_modes(POSES[0])
    cond = CuttingConditions(RPM, 0.058e-3, 3e-3, 6e-3)
    a_lim = sdm_lobes(mx, my, TOOL, cond, ALUMINIUM_7075, [RPM]).a_lim_m[0]
    cut = simulate_regenerative_cut(mx, my, TOOL, cond, ALUMINIUM_7075, a_lim * np.array([0.5, 1.25]),
                                    steps_per_tooth=60)  # fmt: skip
    assert list(cut.chatter) == [False, True]
    feed = cond.feed_per_tooth_m
    assert cut.chatter_amplitude_m[0] < 0.05 * feed < 0.5 * feed < cut.chatter_amplitude_m[1]


def test_entry_ramp_lengthens_the_record_and_keeps_a_stable_cut_stable():
    mx, my = _pose_modes(POSES[0])
    cond = CuttingConditions(RPM, 0.058e-3, 3e-3, 6e-3, down_milling=True)
    a_lim = sdm_lobes(mx, my, TOOL, cond, AL_NO_EDGE, [RPM]).a_lim_m[0]
    cut = simulate_regenerative_cut(mx, my, TOOL, cond, AL_NO_EDGE, [0.7 * a_lim],
                                    n_tooth_periods=100, steps_per_tooth=40,
                                    entry_tooth_periods=50)  # fmt: skip
    assert cut.time_s.size == 150 * 40 and cut.entry_tooth_periods == 50
    assert not cut.chatter[0]
    with pytest.raises(ValueError, match="entry_tooth_periods"):
        simulate_regenerative_cut(mx, my, TOOL, cond, AL_NO_EDGE, [1e-3], entry_tooth_periods=-1)


@pytest.mark.parametrize("down", [True, False])
def test_time_domain_limit_matches_linear_theory_without_edge_forces(down):
    # No edge forces: the tool stays in the cut below the limit, the system is the linear one
    # the semi-discretization solves, so the time-domain limit is the SDM limit (to the 5 % grid).
    mx, my = _pose_modes(POSES[1])
    cond = CuttingConditions(RPM, 0.058e-3, 3e-3, 6e-3, down_milling=down)
    lim = sdm_lobes(mx, my, TOOL, cond, AL_NO_EDGE, [RPM]).a_lim_m
    ratio = time_domain_limit_ratio(mx, my, TOOL, cond, AL_NO_EDGE, [RPM], lim, steps_per_tooth=60)
    assert 0.95 <= ratio[0] <= 1.0
    with pytest.raises(ValueError, match="factors"):
        time_domain_limit_ratio(mx, my, TOOL, cond, AL_NO_EDGE, [RPM], lim, factors=(0.9, 0.8))
    with pytest.raises(ValueError, match="shape"):
        time_domain_limit_ratio(mx, my, TOOL, cond, AL_NO_EDGE, [RPM, 2000.0], lim)


def test_stability_probability_with_the_time_domain_margin_is_never_more_optimistic():
    from robovib.milling.uncertainty import ModeDistribution, stability_probability

    mx, my = _pose_modes(POSES[0])
    dist = {
        d: ModeDistribution(m.natural_frequency_hz, m.stiffness_n_per_m, m.damping_ns_per_m,
                            0.02 * m.natural_frequency_hz, 0.05 * m.stiffness_n_per_m,
                            0.08 * m.damping_ns_per_m)
        for d, m in (("x", mx[0]), ("y", my[0]))
    }  # fmt: skip
    cond = CuttingConditions(RPM, 0.058e-3, 3e-3, 6e-3)
    rpm = [1750.0, 2400.0]
    kw = dict(n_samples=20, method="zoa", rng=3)
    lin = stability_probability(dist, TOOL, cond, ALUMINIUM_7075, rpm, **kw)
    mar = stability_probability(dist, TOOL, cond, ALUMINIUM_7075, rpm, depth_m=lin.depth_m,
                                time_domain_margin=True, **kw)  # fmt: skip
    ratio = np.asarray(mar.settings["time_domain_ratio"])
    assert ratio.shape == (2,) and np.all((ratio > 0) & (ratio <= 1))
    assert np.all(mar.p_stable <= lin.p_stable)
    assert lin.settings["time_domain_ratio"] is None


def test_mill_lobes_time_domain_margin_from_the_cli():
    import json

    from typer.testing import CliRunner

    from robovib.cli import app

    args = ["mill", "lobes", "--x", "2400", "--y", "0", "--rz", "45", "--method", "zoa",
            "--rpm-range", "1750:2400:2", "--samples", "8", "--json"]  # fmt: skip
    plain = json.loads(CliRunner().invoke(app, args).stdout)
    res = CliRunner().invoke(app, [*args, "--time-domain-margin"])
    assert res.exit_code == 0, res.output
    doc = json.loads(res.stdout)
    ratio = np.asarray(doc["probability"]["time_domain_ratio"])
    assert ratio.shape == (2,) and np.all((ratio > 0) & (ratio <= 1))
    assert plain["probability"]["time_domain_ratio"] is None
    assert any("time-domain margin" in n for n in doc["notes"])
    # The linear envelope itself is unchanged; only P(stable) moves, never upwards.
    assert doc["a_lim_m"] == plain["a_lim_m"]
    assert np.all(np.asarray(doc["probability"]["a_lim_p05_m"])
                  <= np.asarray(plain["probability"]["a_lim_p05_m"]))  # fmt: skip
    bad = CliRunner().invoke(app, [a for a in args if a not in ("--samples", "8")]
                             + ["--time-domain-margin"])  # fmt: skip
    assert bad.exit_code != 0 and "n_samples" in bad.output


def _bracket_by_single_cuts(mx, my, cond, coef, rpm, lim, factors, onset="persistent", **sim):
    """Reference: one simulate_regenerative_cut batch of depths per speed, the onset found by a
    plain loop (first: the first chattering depth; persistent: the first depth from which every
    deeper one chatters)."""
    from dataclasses import replace

    low, high = np.ones(len(rpm)), np.ones(len(rpm))
    for i, (speed, a) in enumerate(zip(rpm, lim, strict=True)):
        chat = simulate_regenerative_cut(
            mx, my, TOOL, replace(cond, spindle_rpm=speed), coef, a * np.asarray(factors), **sim
        ).chatter
        starts = [j for j in range(len(factors)) if chat[j] and (onset == "first" or all(chat[j:]))]
        if starts:
            j = starts[0]
            low[i], high[i] = (0.5 * factors[0], factors[0]) if j == 0 else factors[j - 1 : j + 1]
    return low, high


def test_limit_ratios_of_many_structures_match_one_cut_at_a_time():
    # Structures with different numbers of modes, speeds and limits in one batch give the
    # brackets that the per-structure simulation gives.
    from robovib.milling.time_domain import time_domain_limit_ratios

    mx, my = _pose_modes(POSES[0])
    sets = [
        (mx, my),  # every mode of the pose
        (mx[:1], my[:1]),  # dominant only
    ]
    shifted = ModalParameters(mx[0].natural_frequency_hz * 1.05, mx[0].stiffness_n_per_m, 0.08)
    sets.append(([shifted], my[:1]))
    rpm = [1750.0, 2600.0]
    cond = CuttingConditions(RPM, 0.058e-3, 3e-3, 6e-3)
    lim = np.array([sdm_lobes(a, b, TOOL, cond, ALUMINIUM_7075, rpm).a_lim_m for a, b in sets])
    factors = (0.5, 0.8, 0.9, 1.0)
    sim = dict(steps_per_tooth=30, n_tooth_periods=80)
    for onset in ("persistent", "first"):
        low, high = time_domain_limit_ratios(sets, TOOL, cond, ALUMINIUM_7075, rpm, lim,
                                             factors=factors, max_batch=5, onset=onset, **sim)  # fmt: skip
        for s, (a, b) in enumerate(sets):
            ref = _bracket_by_single_cuts(a, b, cond, ALUMINIUM_7075, rpm, lim[s], factors,
                                          onset=onset, **sim)  # fmt: skip
            np.testing.assert_array_equal(low[s], ref[0])
            np.testing.assert_array_equal(high[s], ref[1])
    with pytest.raises(ValueError, match="shape"):
        time_domain_limit_ratios(sets, TOOL, cond, ALUMINIUM_7075, rpm, lim[:2])
    with pytest.raises(ValueError, match="positive depth"):
        time_domain_limit_ratios(sets, TOOL, cond, ALUMINIUM_7075, rpm, lim * [[1], [-1], [1]])
    with pytest.raises(ValueError, match="empty"):
        time_domain_limit_ratios([], TOOL, cond, ALUMINIUM_7075, rpm, np.zeros((0, 2)))
    with pytest.raises(TypeError, match="unknown simulation options"):
        time_domain_limit_ratios(sets, TOOL, cond, ALUMINIUM_7075, rpm, lim, n_steps=3)


def test_an_isolated_chattering_depth_is_not_the_onset_of_chatter(monkeypatch):
    # Planted chatter patterns over the factors (one structure each): an island below the
    # persistent chatter, an island alone, chatter from the first factor, no chatter.
    from robovib.milling import time_domain

    factors = (0.6, 0.7, 0.8, 0.9, 1.0)
    patterns = {1.0: "-X-XX", 2.0: "-X---", 3.0: "XXXXX", 4.0: "-----"}

    def planted(fn, k, z, feed, rpm, depth, *args, **kwargs):
        return np.array([patterns[f][factors.index(round(d, 6))] == "X"
                         for f, d in zip(fn[:, 0], depth, strict=True)])  # fmt: skip

    monkeypatch.setattr(time_domain, "_chatter_of_rows", planted)
    sets = [([ModalParameters(f, 1e6, 0.05)], []) for f in patterns]
    lim = np.ones((len(sets), 1))
    args = (sets, TOOL, CuttingConditions(RPM, 0.058e-3, 3e-3, 6e-3), ALUMINIUM_7075, [RPM], lim)
    low, high = time_domain.time_domain_limit_ratios(*args, factors=factors)
    np.testing.assert_array_equal(low[:, 0], [0.8, 1.0, 0.3, 1.0])
    np.testing.assert_array_equal(high[:, 0], [0.9, 1.0, 0.6, 1.0])
    low, high = time_domain.time_domain_limit_ratios(*args, factors=factors, onset="first")
    np.testing.assert_array_equal(low[:, 0], [0.6, 0.6, 0.3, 1.0])
    np.testing.assert_array_equal(high[:, 0], [0.7, 0.7, 0.6, 1.0])
    with pytest.raises(ValueError, match="onset"):
        time_domain.time_domain_limit_ratios(*args, factors=factors, onset="last")


def test_margin_of_a_sharp_distribution_is_that_of_its_mean():
    # All samples equal to the mean: every sample's simulated margin is the mean's, so the
    # sampled limits are the mean envelope times a ratio inside the mean's bracket.
    from robovib.milling.time_domain import time_domain_limit_ratio
    from robovib.milling.uncertainty import ModeDistribution, stability_probability

    mx, my = _pose_modes(POSES[0])
    dist = {d: ModeDistribution(m.natural_frequency_hz, m.stiffness_n_per_m, m.damping_ns_per_m)
            for d, m in (("x", mx[0]), ("y", my[0]))}  # fmt: skip
    cond = CuttingConditions(RPM, 0.058e-3, 3e-3, 6e-3)
    rpm = [1750.0]
    prob = stability_probability(dist, TOOL, cond, ALUMINIUM_7075, rpm, n_samples=6,
                                 method="zoa", time_domain_margin=True, margin_samples=2,
                                 method_error=False, fit_bias=0.0)  # fmt: skip
    low, high = time_domain_limit_ratio(mx[:1], my[:1], TOOL, cond, ALUMINIUM_7075, rpm,
                                        prob.mean.a_lim_m, return_bracket=True)  # fmt: skip
    r = prob.a_lim_samples_m[:, 0] / prob.mean.a_lim_m[0]
    assert np.all((r >= low[0] - 1e-12) & (r <= high[0] + 1e-12))
    assert prob.settings["margin_samples"] == 2
    # margin_samples=0: the mean modes' bracket for every sample.
    mean_only = stability_probability(dist, TOOL, cond, ALUMINIUM_7075, rpm, n_samples=6,
                                      method="zoa", time_domain_margin=True, margin_samples=0,
                                      method_error=False, fit_bias=0.0)  # fmt: skip
    r0 = mean_only.a_lim_samples_m[:, 0] / mean_only.mean.a_lim_m[0]
    assert np.all((r0 >= low[0] - 1e-12) & (r0 <= high[0] + 1e-12))
    with pytest.raises(ValueError, match="margin_samples"):
        stability_probability(dist, TOOL, cond, ALUMINIUM_7075, rpm, n_samples=6, method="zoa",
                              time_domain_margin=True, margin_samples=-1)  # fmt: skip
