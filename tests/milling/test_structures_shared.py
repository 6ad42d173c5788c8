"""Sampled structures with a workspace-wide share (issue 39): the fields' correlation between
two poses against the closed form ``rho + (1 - rho) exp(-d^2 / 2)`` (squared-exponential
kernel of the random Fourier features, distance in correlation lengths)."""

from __future__ import annotations

import numpy as np
import pytest

from robovib.milling.structures import StructureSamples


def _samples(rho: float, n: int = 6000, k: int = 400, seed: int = 0) -> StructureSamples:
    gen = np.random.default_rng(seed)
    freq = gen.normal(size=(1, k, 3))
    phase = gen.uniform(0, 2 * np.pi, size=(1, k))
    amp = gen.normal(size=(n, 1, k))
    shared = gen.normal(size=(n, 1)) if rho > 0 else None
    return StructureSamples(None, np.full(n, 1.0 / n), np.ones(n), (300.0, 450.0, 45.0), freq,
                            phase, amp, {}, shared, rho)  # fmt: skip


@pytest.mark.parametrize("rho", [0.0, 0.5])
def test_shared_share_sets_the_far_correlation_and_keeps_the_marginal(rho):
    s = _samples(rho)
    # poses 0, 0.5 and 4 correlation lengths apart in x
    poses = np.array([[2100.0, 0.0, 0.0], [2250.0, 0.0, 0.0], [3300.0, 0.0, 0.0]])
    z = s.fields(poses)[:, :, 0]  # (S, 3)
    corr = np.corrcoef(z.T)
    tol = 4 / np.sqrt(z.shape[0]) + 0.03  # sampling error of a correlation + finite features
    assert corr[0, 2] == pytest.approx(rho + (1 - rho) * np.exp(-(4.0**2) / 2), abs=tol)
    assert corr[0, 1] == pytest.approx(rho + (1 - rho) * np.exp(-(0.5**2) / 2), abs=tol)
    assert z.var(axis=0) == pytest.approx(np.ones(3), abs=0.08)  # standard-normal marginal
    kept = s.with_weights(np.arange(1, s.n_samples + 1))
    np.testing.assert_array_equal(kept.fields(poses), s.fields(poses))


def test_sample_structures_shared_fraction_keeps_the_other_draws_and_checks_input():
    from robovib.gp.chapter3_model import workspace_predictor
    from robovib.milling.structures import sample_structures

    model = workspace_predictor(None, seed=0, require_inputs=("x_mm", "y_mm", "rz_deg"))
    plain = sample_structures(model, 8, rng=3)
    shared = sample_structures(model, 8, rng=3, shared_fraction=0.5)
    assert plain.shared is None and shared.shared.shape == (8, plain.amplitudes.shape[1])
    np.testing.assert_array_equal(plain.amplitudes, shared.amplitudes)
    np.testing.assert_array_equal(plain.process_factor, shared.process_factor)
    assert shared.settings["shared_fraction"] == 0.5
    with pytest.raises(ValueError, match="shared_fraction"):
        sample_structures(model, 8, shared_fraction=1.0)
