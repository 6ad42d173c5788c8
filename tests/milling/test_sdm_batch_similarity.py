"""SDM batched over structures, and the exact similarity laws of the milling DDE (issue 37).

The laws are exact properties of the delay equation ``M x'' + C x' + K x = -a H(t) (x - x(t - tau))``
(independent of the solver): all stiffnesses times ``s`` at fixed natural frequencies and damping
ratios scale the modal masses by ``s`` as well, so ``a / s`` solves the same equation; all natural
frequencies times ``s`` at fixed stiffnesses and damping ratios is the time rescaling
``t -> t / s``, which maps speed ``n`` onto ``s n``. A stability chart that does not obey them
has a bug in its discretisation or depth search.
"""

import numpy as np
import pytest

from robovib.milling import ALUMINIUM_7075, CuttingConditions, MillingTool
from robovib.milling.forces import engagement_angles
from robovib.milling.sdm import critical_depths, milling_force_matrices, sdm_lobes
from robovib.modal import ModalParameters

TOOL = MillingTool(diameter_m=0.0254, n_flutes=2, helix_deg=30.0)


def _cond(radial_m: float, down: bool) -> CuttingConditions:
    return CuttingConditions(2000.0, 1e-4, 1e-3, radial_m, down_milling=down)


def _scaled(modes, f_scale=1.0, k_scale=1.0):
    return [
        ModalParameters.from_fn_k_c(
            m.natural_frequency_hz * f_scale,
            m.stiffness_n_per_m * k_scale,
            m.damping_ratio
            * m.stiffness_n_per_m
            * k_scale
            / (np.pi * m.natural_frequency_hz * f_scale),
        )
        for m in modes
    ]


# The chapter-3-like 2-DOF structure (heavily damped) and a 3-mode one.
TWO_DOF = ([ModalParameters(16.4, 4.2e6, 0.114)], [ModalParameters(8.5, 9.4e5, 0.19)])
THREE_MODES = (
    [ModalParameters(16.4, 4.2e6, 0.11), ModalParameters(42.0, 2.0e7, 0.05)],
    [ModalParameters(21.9, 1.0e7, 0.06)],
)
CASES = [
    (TWO_DOF, 6e-3, True),
    (TWO_DOF, 2.5e-3, False),  # low immersion, up-milling: flip lobes
    (THREE_MODES, 6e-3, True),
]


@pytest.mark.parametrize(("structure", "radial_m", "down"), CASES)
def test_stiffness_scaling_scales_the_dense_sdm_limit(structure, radial_m, down):
    rpm = np.linspace(300.0, 3000.0, 9)
    mx, my = structure
    dense = {"warm_start": False, "rtol": 1e-7}
    base = sdm_lobes(mx, my, TOOL, _cond(radial_m, down), ALUMINIUM_7075, rpm, **dense).a_lim_m
    for s in (0.8, 1.3):
        scaled = sdm_lobes(_scaled(mx, k_scale=s), _scaled(my, k_scale=s), TOOL,
                           _cond(radial_m, down), ALUMINIUM_7075, rpm, **dense).a_lim_m  # fmt: skip
        np.testing.assert_allclose(scaled, s * base, rtol=1e-5)


@pytest.mark.parametrize(("structure", "radial_m", "down"), CASES)
def test_frequency_scaling_maps_the_dense_sdm_chart_along_the_speeds(structure, radial_m, down):
    rpm = np.linspace(300.0, 3000.0, 9)
    mx, my = structure
    dense = {"warm_start": False, "rtol": 1e-7}
    base = sdm_lobes(mx, my, TOOL, _cond(radial_m, down), ALUMINIUM_7075, rpm, **dense).a_lim_m
    for s in (0.9, 1.15):
        moved = sdm_lobes(_scaled(mx, f_scale=s), _scaled(my, f_scale=s), TOOL,
                          _cond(radial_m, down), ALUMINIUM_7075, s * rpm, **dense).a_lim_m  # fmt: skip
        np.testing.assert_allclose(moved, base, rtol=1e-5)
        # ... and the chart is not invariant at the same speeds (the test can fail).
        same = sdm_lobes(_scaled(mx, f_scale=s), _scaled(my, f_scale=s), TOOL,
                         _cond(radial_m, down), ALUMINIUM_7075, rpm, **dense).a_lim_m  # fmt: skip
        assert np.max(np.abs(same / base - 1)) > 0.02


def test_critical_depths_batched_over_structures_matches_one_at_a_time():
    cond = _cond(6e-3, True)
    phi_st, phi_ex = engagement_angles(TOOL, cond)
    hmat, frac = milling_force_matrices(TOOL.n_flutes, phi_st, phi_ex, ALUMINIUM_7075, 40)
    rpm = np.array([700.0, 1500.0, 2600.0])
    delay = 60.0 / (TOOL.n_flutes * rpm)
    structures = [
        TWO_DOF,
        ([ModalParameters(17.5, 3.6e6, 0.10)], [ModalParameters(8.1, 1.1e6, 0.16)]),
        ([ModalParameters(15.2, 4.9e6, 0.13)], [ModalParameters(9.3, 8.0e5, 0.21)]),
    ]
    rng_m = (2e-4, 0.2)
    one = np.concatenate(
        [
            critical_depths(mx, my, hmat, frac, delay, depth_range_m=rng_m)[0]
            for mx, my in structures
        ]
    )
    modes = [list(mx) + list(my) for mx, my in structures]
    wn = np.repeat([[m.omega_n for m in s] for s in modes], rpm.size, axis=0)
    zeta = np.repeat([[m.damping_ratio for m in s] for s in modes], rpm.size, axis=0)
    mass = np.repeat([[m.mass_kg for m in s] for s in modes], rpm.size, axis=0)
    batch = critical_depths(
        *TWO_DOF, hmat, frac, np.tile(delay, len(structures)), depth_range_m=rng_m,
        batch_modes=(wn, zeta, mass),
    )[0]  # fmt: skip
    np.testing.assert_allclose(batch, one, rtol=1e-9)
    assert np.ptp(one.reshape(3, -1), axis=0).min() > 0  # the structures differ
    with pytest.raises(ValueError, match="batch_modes"):
        critical_depths(*TWO_DOF, hmat, frac, delay, batch_modes=(wn, zeta, mass))
