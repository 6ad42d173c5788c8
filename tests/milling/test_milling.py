"""Milling vibration prediction and stability against closed forms, SciPy and the virtual robot."""

import json

import numpy as np
import pytest
from scipy import signal
from typer.testing import CliRunner

from robovib.cli import app
from robovib.frf import FRF
from robovib.milling import (
    ALUMINIUM_7075,
    CuttingCoefficients,
    CuttingConditions,
    MillingTool,
    milling_forces,
)
from robovib.milling.prediction import convolve_force, peak_to_valley_per_revolution, resample_force
from robovib.milling.stability import directional_coefficients, stability_lobes
from robovib.modal import ModalParameters

FS = 1000.0
MODES = [ModalParameters(9.5, 1.2e6, 0.15), ModalParameters(25.0, 4e6, 0.05)]


def _lsim(force, modes):
    out = np.zeros_like(force)
    t = np.arange(force.size) / FS
    for m in modes:
        sys = signal.lti([1.0], [m.mass_kg, m.damping_ns_per_m, m.stiffness_n_per_m])
        out += signal.lsim(sys, force, t, interp=True)[1]
    return out


def test_mean_slotting_forces_match_altintas_closed_form():
    tool, cond, k = MillingTool(), CuttingConditions(1750, 0.058e-3, 3e-3, 25.4e-3), ALUMINIUM_7075
    t = np.arange(0, 60 / 1750 * 4, 1 / 20000)
    mean = milling_forces(t, tool, cond, k, n_slices=40, n_angles=None).mean(axis=0)
    n, a, fz = 2, 3e-3, 0.058e-3
    expected = [-n * a * k.krc * fz / 4 - n * a * k.kre / np.pi, n * a * k.ktc * fz / 4 + n * a * k.kte / np.pi,
                n * a / (2 * np.pi) * (2 * k.kac * fz + k.kae * np.pi)]  # fmt: skip
    np.testing.assert_allclose(mean, expected, rtol=2e-3)


def test_convolution_matches_ode_and_static_deflection():
    tool, cond = MillingTool(), CuttingConditions(1750, 0.058e-3, 3e-3, 25.4e-3)
    t = np.arange(0, 4.0, 1 / FS)
    force = milling_forces(t, tool, cond, ALUMINIUM_7075)[:, 1]
    x = convolve_force(force, FS, MODES)
    ref = _lsim(force, MODES)
    assert np.max(np.abs(x - ref)) / np.max(np.abs(ref)) < 0.01
    static = convolve_force(np.full(20000, 100.0), FS, MODES)
    assert static[-1] == pytest.approx(100.0 / 1.2e6 + 100.0 / 4e6, rel=1e-3)
    # Same result from a sampled compliance FRF of the same modes.
    f = np.arange(0.0, 500.0, 0.01)
    frf = FRF(f, sum(m.compliance(f) for m in MODES), source="model", estimator="model")
    x_frf = convolve_force(force, FS, frf=frf)
    assert np.max(np.abs(x_frf - ref)) / np.max(np.abs(ref)) < 0.02


def test_peak_to_valley_of_a_known_signal():
    rpm = 1750.0
    t = np.arange(0, 2.0, 1 / 10000.0)
    x = 0.3 + 0.05 * np.sin(2 * np.pi * rpm / 60 * t)
    pv = peak_to_valley_per_revolution(x, 10000.0, rpm)
    np.testing.assert_allclose(pv, 0.1, rtol=1e-3)
    with pytest.raises(ValueError, match="shorter than one spindle revolution"):
        peak_to_valley_per_revolution(x[:100], 10000.0, rpm)


def test_single_direction_lobes_match_classical_minimum():
    """Gxx = 0, slotting: a_yy = -K_r pi, a_lim,min = 2 pi / (N K_tc a_yy min Re G)."""
    mode = ModalParameters(922.0, 1.34e6, 0.011)
    coeffs = CuttingCoefficients(6e8, 2e8, 0.0)
    tool = MillingTool(diameter_m=0.02, n_flutes=2, helix_deg=0.0)
    cond = CuttingConditions(10000, 1e-4, 1e-3, 0.02)
    *_, ayy = directional_coefficients(0.0, np.pi, 2e8 / 6e8)
    assert ayy == pytest.approx(-np.pi / 3)
    f = np.linspace(800, 1100, 200001)
    r = f / 922.0
    re_min = np.min((1 / (1.34e6 * (1 - r**2 + 2j * 0.011 * r))).real)
    expected = 2 * np.pi / (2 * 6e8 * ayy * re_min)
    lobes = stability_lobes([], [mode], tool, cond, coeffs, n_frequencies=20001)
    assert lobes.minimum_depth_m == pytest.approx(expected, rel=1e-3)


def test_resample_and_bad_input():
    t = np.arange(0, 1, 1 / 3000.0)
    f = np.column_stack([np.sin(2 * np.pi * 5 * t)] * 3)
    out = resample_force(t, f, 1000.0)
    assert out.shape == (1000, 3)
    np.testing.assert_allclose(
        out[100:-100, 0], np.sin(2 * np.pi * 5 * np.arange(1000) / 1000.0)[100:-100], atol=1e-3
    )
    bad_t = t.copy()
    bad_t[5] += 1e-4
    with pytest.raises(ValueError, match="not uniformly sampled"):
        resample_force(bad_t, f, 1000.0)
    with pytest.raises(ValueError, match="exactly one"):
        convolve_force(np.ones(10), FS)
    with pytest.raises(ValueError, match="flexible"):
        stability_lobes(
            [], [], MillingTool(), CuttingConditions(1000, 1e-4, 1e-3, 1e-3), ALUMINIUM_7075
        )
    with pytest.raises(ValueError, match="exceeds the tool diameter"):
        stability_lobes(
            [], MODES, MillingTool(), CuttingConditions(1000, 1e-4, 1e-3, 0.03), ALUMINIUM_7075
        )


def test_virtual_robot_peak_to_valley_near_the_63_hz_mode():
    """Thesis §3.5 cut at a pose where the ~63 Hz X mode meets the 58.3 Hz tooth passing:
    the GP-based prediction (dominant mode only) vs the virtual robot's tracker record."""
    from robovib.gp import load_chapter3_model
    from robovib.milling.at_pose import predict_at_pose
    from robovib.milling.prediction import summarise_vibration
    from robovib.sim import LinearMove, VirtualRobot, simulate_milling

    cond = CuttingConditions(1750, 0.058e-3, 3e-3, 25.4e-3)
    move = LinearMove("workspace", (2.7, -0.005, 0.0), (2.7, 0.005, 0.0))
    run = simulate_milling(VirtualRobot(), move, MillingTool(), cond, ALUMINIUM_7075, rng=1)
    pred = predict_at_pose(
        load_chapter3_model(), 2700, 0, 0, cond, forces_n=run.force_n, n_samples=10
    )
    measured = summarise_vibration(run.displacement_m[:, 0], 1000.0, 1750, skip_s=0.5)
    assert pred[0].peak_to_valley_m == pytest.approx(measured.peak_to_valley_m, rel=0.25)
    assert pred[0].peak_to_valley_m > 10 * pred[2].peak_to_valley_m  # X dominates, as in the thesis


def test_mill_cli(tmp_path):
    runner = CliRunner()
    res = runner.invoke(
        app,
        ["mill", "predict", "--x", "2400", "--y", "300", "--rz", "90", "--samples", "5", "--json"],
    )
    assert res.exit_code == 0, res.output
    rows = json.loads(res.output)["predictions"]
    assert [r["direction"] for r in rows] == ["x", "y", "z"]
    assert all(r["peak_to_valley_band_mm"][0] <= r["peak_to_valley_band_mm"][1] for r in rows)
    res = runner.invoke(app, ["mill", "lobes", "--x", "2400", "--y", "0", "--rz", "45", "--json"])
    assert res.exit_code == 0 and json.loads(res.output)["minimum_depth_m"] > 0
    res = runner.invoke(
        app, ["mill", "predict", "--x", "2400", "--y", "0", "--rz", "0", "--material", "wood"]
    )
    assert res.exit_code == 1


def test_zoa_envelope_of_several_modes_never_lies_above_its_own_lobes():
    # With several modes per direction a lobe branch turns back in speed and has gaps in its
    # chatter-frequency scan; the envelope must follow the lobe points, not interpolate across.
    from robovib.milling.lobes import zoa_envelope
    from robovib.modal import ModalParameters

    mx = [ModalParameters(16.5, 4.2e6, 0.10), ModalParameters(43.0, 2.0e7, 0.05),
          ModalParameters(63.5, 1.5e7, 0.04)]  # fmt: skip
    my = [ModalParameters(8.4, 9.0e5, 0.15), ModalParameters(22.0, 6.0e6, 0.06)]
    cond = CuttingConditions(1750.0, 0.058e-3, 1e-3, 6e-3)
    lobes = stability_lobes(mx, my, MillingTool(), cond, ALUMINIUM_7075, n_lobes=20)
    pts_rpm = np.concatenate(lobes.spindle_rpm)
    pts_depth = np.concatenate(lobes.depth_m)
    grid = np.linspace(1000.0, 3000.0, 400)
    env = zoa_envelope(lobes, grid).a_lim_m
    checked = 0
    for g, a in zip(grid, env, strict=True):
        near = np.abs(pts_rpm - g) < 2.0
        if near.any():
            checked += 1
            assert a <= 1.02 * pts_depth[near].min()
    assert checked > 100
