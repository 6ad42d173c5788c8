"""Rule 5 of the mode-switch test: a mode whose frequency varies smoothly over a coarse grid of
poses shows two clusters of frequencies, and must not be modelled as a switch between modes."""

import numpy as np
import pytest

from robovib.gp import PoseModalModel, detect_mode_switch

GRID = np.array(
    [[x, y, rz] for x in (2100, 2325, 2550) for y in (-300, 0, 300, 600) for rz in (0, 90, 180)],
    float,
)


def _smooth_fn(X, rng):
    # One mode: 16 Hz at Rz = 0/180 deg, 22 Hz at Rz = 90 deg; three Rz levels make two clusters.
    rz = np.radians(X[:, 2])
    return (
        16 + 6 * np.sin(rz) ** 2 + 0.5 * (X[:, 0] - 2300) / 300 + 0.05 * rng.standard_normal(len(X))
    )


def test_smooth_variation_on_a_grid_is_not_a_switch():
    fn = _smooth_fn(GRID, np.random.default_rng(0))
    without_poses = detect_mode_switch(fn)
    assert without_poses.found  # the frequencies alone look like two modes
    with_poses = detect_mode_switch(fn, poses=GRID)
    assert not with_poses.found
    assert "varying over the workspace" in with_poses.reason


@pytest.mark.parametrize("high_hz", [40.0, 63.0])
def test_a_switch_to_a_distinct_mode_is_still_found(high_hz):
    rng = np.random.default_rng(1)
    X = rng.uniform([2100, -300, 0], [2700, 600, 180], (40, 3))
    fn = np.where(X[:, 0] > 2550, high_hz, 16 + 2 * X[:, 1] / 600)
    fn = fn * (1 + 0.01 * rng.standard_normal(40))
    assert detect_mode_switch(fn, poses=X).found


def test_a_switch_between_clusters_the_pose_cannot_predict_is_found():
    # Close frequencies (ratio < 2) at poses scattered among the others: not a smooth function.
    rng = np.random.default_rng(2)
    X = rng.uniform([2100, -300, 0], [2700, 600, 180], (40, 3))
    high = rng.uniform(size=40) < 0.3
    fn = np.where(high, 24.0, 16.0) * (1 + 0.01 * rng.standard_normal(40))
    d = detect_mode_switch(fn, poses=X)
    assert d.found, d.reason


def test_poses_of_the_wrong_length_are_refused():
    fn = _smooth_fn(GRID, np.random.default_rng(0))
    with pytest.raises(ValueError, match="one row per frequency"):
        detect_mode_switch(fn, poses=GRID[:-1])


def test_pose_model_on_a_grid_predicts_the_smooth_mode_between_levels():
    """Off-grid, the prediction follows the smooth truth instead of the nearer cluster."""
    rng = np.random.default_rng(3)
    fn = _smooth_fn(GRID, rng)
    Y = np.column_stack([fn, 2e6 * (1 + 0.05 * GRID[:, 1] / 600), 400 + GRID[:, 2]])
    model = PoseModalModel(directions=("x",), rng=0).fit(GRID, Y)
    assert not model.mode_switches_["x"].found
    X = np.array([[2200.0, 150.0, 45.0], [2400.0, 450.0, 135.0]])
    truth = 16 + 6 * np.sin(np.radians(45.0)) ** 2 + 0.5 * (X[:, 0] - 2300) / 300
    mean, std = model.predict(X, return_std=True)
    assert np.all(np.abs(mean[:, 0] - truth) < 2.5)  # 19 Hz truth; the clusters sit at 16 and 22
    assert np.all(std[:, 0] > 0)
