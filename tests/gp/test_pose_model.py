"""PoseModalModel: mode-switch detection, prediction, extrapolation flags, HDF5 round trip."""

from __future__ import annotations

import h5py
import numpy as np
import pytest
from sklearn.base import clone
from sklearn.exceptions import NotFittedError

from robovib.datasets import load_table_a1
from robovib.gp import BatchedGPRegressor, PoseModalModel, detect_mode_switch
from robovib.gp.mode_switch import ModeSwitchingGPRegressor
from robovib.modal import ModalParameters


def _synthetic(switch: bool, n_side: int = 7, rng=0):
    """One direction over (x_mm, y_mm) on a grid, 2 replicates; a 60 Hz mode at x > 2550 mm."""
    gen = np.random.default_rng(rng)
    g = np.linspace(2100, 2700, n_side)
    xx, yy = np.meshgrid(g, np.linspace(-300, 600, n_side))
    X = np.repeat(np.column_stack([xx.ravel(), yy.ravel()]), 2, axis=0)
    u = (X[:, 0] - 2100) / 600
    fn = 16 + 6 * u + 0.5 * np.sin(X[:, 1] / 300)
    k = 3e6 + 2e6 * u
    c = 8e3 - 2e3 * u
    high = switch & (X[:, 0] > 2550)
    fn = np.where(high, 63 + 0.5 * np.cos(X[:, 1] / 300), fn)
    c = np.where(high, 1.2e3, c)
    Y = np.column_stack([fn, k, c]) * (1 + 0.005 * gen.standard_normal((X.shape[0], 3)))
    return X, Y, high


@pytest.fixture(scope="module")
def switch_model():
    X, Y, high = _synthetic(True)
    model = PoseModalModel(input_names=("x_mm", "y_mm"), directions=("x",), rng=0).fit(X, Y)
    return model, X, Y, high


# ------------------------------------------------------------------------------- detection
def test_detect_mode_switch_on_synthetic_samples():
    gen = np.random.default_rng(1)
    bimodal = np.concatenate([gen.uniform(15, 23, 150), gen.uniform(61, 65, 25)])
    found = detect_mode_switch(bimodal, direction="x")
    assert found.found and 23 < found.threshold_hz < 61
    assert (found.n_low, found.n_high) == (150, 25)
    # One smooth mode (skewed), and two touching clusters without a gap: no switch.
    assert not detect_mode_switch(gen.gamma(2.0, 2.0, 200) + 10).found
    touching = np.concatenate([gen.uniform(9.3, 10.0, 70), gen.uniform(10.2, 11.5, 110)])
    res = detect_mode_switch(np.round(touching, 1))
    assert not res.found and res.gap_sigma < 3
    # A high mode at 2 samples is still a switch (never blended into the low mode), said so;
    # min_high_samples restores the old rule, and too few low samples is never a switch.
    rare = np.concatenate([gen.uniform(15, 23, 50), [63.0, 64.0]])
    res = detect_mode_switch(rare)
    assert res.found and (res.n_low, res.n_high) == (50, 2) and 23 < res.threshold_hz < 63
    assert "too few to model" in res.reason
    assert not detect_mode_switch(rare, min_high_samples=3).found
    assert not detect_mode_switch(np.concatenate([[5.0, 5.1], gen.uniform(15, 23, 50)])).found
    with pytest.raises(ValueError, match="positive"):
        detect_mode_switch([10.0, -1.0, 12.0])


def test_detection_on_table_a1_finds_the_x_switch_only():
    a1 = load_table_a1()
    res = {d: detect_mode_switch(a1[f"fn_{d}_hz"].dropna().to_numpy(), direction=d) for d in "xyz"}
    assert res["x"].found and not res["y"].found and not res["z"].found
    assert 23.0 < res["x"].threshold_hz < 61.0
    # The high samples are exactly the rows the dataset flags as the ~63 Hz mode.
    assert res["x"].n_high == int(a1["x_high_mode"].sum())


def test_synthetic_model_with_and_without_switch(switch_model):
    model, *_ = switch_model
    assert model.mode_switches_["x"].found
    assert isinstance(model.estimators_[0], ModeSwitchingGPRegressor)
    query = np.array([[2700.0, 150.0], [2200.0, 150.0]])
    fn = model.predict(query)[:, 0]
    # Synthetic truth (see _synthetic): high mode 63 + 0.5 cos(y/300), low 16 + 6 u + 0.5 sin(y/300).
    truth = [63 + 0.5 * np.cos(150 / 300), 16 + 6 * 100 / 600 + 0.5 * np.sin(150 / 300)]
    np.testing.assert_allclose(fn, truth, atol=0.5)
    p = model.mode_switch_probability(query)
    assert p.shape == (2, 1) and p[0, 0] > 0.5 > p[1, 0]
    modes = model.modes(query)
    assert modes[0]["x"].high_mode_probability == pytest.approx(p[0, 0])
    assert isinstance(modes[0]["x"].parameters, ModalParameters)

    Xs, Ys, _ = _synthetic(False)
    smooth = PoseModalModel(input_names=("x_mm", "y_mm"), directions=("x",), rng=0).fit(Xs, Ys)
    assert not smooth.mode_switches_["x"].found
    assert smooth.mode_switch_probability(query) is None
    assert smooth.modes(query)[0]["x"].high_mode_probability is None
    # Without a switch the model is the batched GP of the three outputs.
    ref = BatchedGPRegressor(kernel="ard", rng=0).fit(Xs, Ys)
    np.testing.assert_allclose(smooth.predict(query), ref.predict(query), rtol=1e-6)
    with pytest.raises(ValueError, match="no direction shows a mode switch"):
        clone(smooth).set_params(mode_switch=True).fit(Xs, Ys)
    # An assumed switch is not tested.
    assumed = clone(smooth).set_params(mode_switch={"x": 40.0}).fit(*_synthetic(True)[:2])
    assert assumed.mode_switches_["x"].assumed and assumed.mode_switches_["x"].found


def test_output_names_units_and_modes_in_si(switch_model):
    model, *_ = switch_model
    assert model.output_names_ == ("x_fn_hz", "x_stiffness_n_per_m", "x_damping_ns_per_m")
    assert model.input_units_ == ("mm", "mm")
    mean, std = model.predict([[2300.0, 0.0]], return_std=True)
    mode = model.modes([[2300.0, 0.0]])[0]["x"]
    assert mode.parameters.natural_frequency_hz == pytest.approx(mean[0, 0])
    assert mode.parameters.stiffness_n_per_m == pytest.approx(mean[0, 1])
    assert mode.parameters.damping_ns_per_m == pytest.approx(mean[0, 2])
    assert mode.fn_std_hz == pytest.approx(std[0, 0])


def test_extrapolating_box_and_hull():
    # L-shaped workspace: (2650, 550) is inside the box but outside the measured poses' hull.
    gen = np.random.default_rng(0)
    pts = [(x, y) for x in np.linspace(2100, 2700, 7) for y in np.linspace(-300, 600, 7)]
    pts = np.array([p for p in pts if not (p[0] > 2450 and p[1] > 200)])
    fn = 20 + pts[:, 0] / 1000 + gen.normal(0, 0.05, len(pts))
    Y = np.column_stack([fn, 3e6 + pts[:, 1], np.full(len(pts), 5e3) + gen.normal(0, 50, len(pts))])
    model = PoseModalModel(input_names=("x_mm", "y_mm"), directions=("x",)).fit(pts, Y)
    q = np.array([[2300.0, 0.0], [2650.0, 550.0], [2800.0, 0.0], [2700.0, 100.0]])
    np.testing.assert_array_equal(model.extrapolating(q), [False, True, True, False])
    np.testing.assert_array_equal(model.outside_inputs(q)[:, 0], [False, False, True, False])


# ------------------------------------------------------------------------------- persistence
def test_save_load_round_trip(switch_model, tmp_path):
    model, *_ = switch_model
    path = model.save(
        tmp_path / "m.h5", cv={"rmse": np.ones(3), "grouped": True}, provenance={"source": "t"}
    )
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.h5"]  # no temporary left behind
    loaded = PoseModalModel.load(path)
    q = np.column_stack([np.linspace(2000, 2800, 25), np.linspace(-400, 700, 25)])
    m1, s1 = model.predict(q, return_std=True)
    m2, s2 = loaded.predict(q, return_std=True)
    np.testing.assert_allclose(m2, m1, rtol=1e-10)
    assert np.all(np.abs(s2 - s1) <= 1e-10 * (np.abs(s1) + s1.max(axis=0)))
    np.testing.assert_allclose(
        loaded.mode_switch_probability(q), model.mode_switch_probability(q), atol=1e-10
    )
    assert loaded.mode_switches_ == model.mode_switches_
    assert loaded.get_params() == model.get_params()
    assert loaded.provenance_["source"] == "t" and loaded.cv_["grouped"]
    with h5py.File(path) as h5:
        assert h5.attrs["format"] == "robovib.PoseModalModel"
        assert int(h5.attrs["format_version"]) == 1
        assert "robovib_version" in h5.attrs
        assert list(h5.attrs["input_units"]) == ["mm", "mm"]
        assert "units" in h5["training/Y"].attrs


def test_save_load_smooth_model_with_noise_groups_isotropic(tmp_path):
    X, Y, _ = _synthetic(False, n_side=5)
    groups = np.tile([0, 1], X.shape[0] // 2)
    model = PoseModalModel(("x_mm", "y_mm"), ("x",), kernel="isotropic").fit(X, Y, groups=groups)
    loaded = PoseModalModel.load(model.save(tmp_path / "g.h5"))
    # Rounding of the hyperparameters (1e-16) amplified by cond(K) of this low-noise design.
    np.testing.assert_allclose(loaded.predict(X[:7]), model.predict(X[:7]), rtol=1e-8)
    np.testing.assert_array_equal(loaded.groups_, groups)


def test_load_errors(tmp_path, switch_model):
    bad = tmp_path / "bad.h5"
    bad.write_text("not hdf5")
    with pytest.raises(ValueError, match="not a readable HDF5"):
        PoseModalModel.load(bad)
    with h5py.File(tmp_path / "other.h5", "w") as h5:
        h5.attrs["format"] = "something-else"
    with pytest.raises(ValueError, match=r"not a robovib\.PoseModalModel"):
        PoseModalModel.load(tmp_path / "other.h5")
    path = switch_model[0].save(tmp_path / "v.h5")
    with h5py.File(path, "a") as h5:
        h5.attrs["format_version"] = 99
    with pytest.raises(ValueError, match="bytes do not match the checksum"):
        PoseModalModel.load(path)  # changed after robovib wrote it
    data = bytearray(path.read_bytes())
    data[:512] = bytes(512)  # no byte checksum (as in files written before robovib stored one)
    path.write_bytes(bytes(data))
    with pytest.raises(ValueError, match="format version 99"):
        PoseModalModel.load(path)
    with pytest.raises(ValueError, match="does not exist"):
        switch_model[0].save(tmp_path / "missing" / "m.h5")


# ------------------------------------------------------------------------------- contract
def test_bad_input_and_unfitted():
    X, Y, _ = _synthetic(False, n_side=4)
    m = PoseModalModel(("x_mm", "y_mm"), ("x",))
    with pytest.raises(NotFittedError):
        m.predict(X)
    with pytest.raises(ValueError, match=r"Y must be \(n, 3\)"):
        m.fit(X, Y[:, :2])
    with pytest.raises(ValueError, match="x_stiffness_n_per_m must be > 0"):
        m.fit(X, Y * [1, -1, 1])
    with pytest.raises(ValueError, match="NaN"):
        m.fit(np.where(np.arange(len(X))[:, None] == 0, np.nan, X), Y)
    with pytest.raises(ValueError, match="unknown mode_switch"):
        clone(m).set_params(mode_switch="yes").fit(X, Y)
    with pytest.raises(ValueError, match="carries no unit"):
        PoseModalModel(("x", "y_mm"), ("x",)).fit(X, Y)
    with pytest.raises(ValueError, match="rz_deg"):
        PoseModalModel(("x_mm", "y_mm"), ("x",), rz_symmetric=True).fit(X, Y)
    fitted = clone(m).fit(X, Y)
    with pytest.raises(ValueError, match="columns"):
        fitted.predict(np.ones((2, 3)))


def test_path_model_with_one_input(tmp_path):
    """The chapter-4 shape: one path coordinate s [m], two directions."""
    gen = np.random.default_rng(4)
    s = np.repeat(np.linspace(0.0, 0.9, 10), 2)
    fn = 10 - 3 * s
    k = (1.4 - 0.6 * s) * 1e6
    c = 2 * 0.15 * k / (2 * np.pi * fn)
    one = np.column_stack([fn, k, c])
    Y = np.hstack([one, 1.1 * one]) * (1 + 0.003 * gen.standard_normal((s.size, 6)))
    model = PoseModalModel(("s_m",), ("x", "z")).fit(s, Y)
    assert not any(d.found for d in model.mode_switches_.values())
    assert model.output_names_[3] == "z_fn_hz" and model.input_units_ == ("m",)
    np.testing.assert_array_equal(model.extrapolating([0.45, 0.95, -0.01]), [False, True, True])
    mode = model.modes([0.45])[0]["x"]
    assert mode.parameters.natural_frequency_hz == pytest.approx(10 - 3 * 0.45, rel=0.01)
    assert mode.to_dict()["damping_ratio"] == pytest.approx(0.15, rel=0.05)
    loaded = PoseModalModel.load(model.save(tmp_path / "path.h5"))
    np.testing.assert_allclose(loaded.predict([0.1, 0.7]), model.predict([0.1, 0.7]), rtol=1e-10)


def test_update_posterior_equals_a_fixed_hyperparameter_fit_on_all_data(tmp_path):
    X, Y, _ = _synthetic(False, n_side=6)
    first = np.arange(X.shape[0]) < 50
    model = PoseModalModel(("x_mm", "y_mm"), ("x",)).fit(X[first], Y[first])
    hp = model.estimators_[0].hyperparameters_
    model.update(X[~first], Y[~first])
    assert model.X_train_.shape[0] == X.shape[0]
    # Reference: the same hyperparameters held fixed, all data, one fit.
    ref = BatchedGPRegressor(kernel="ard", optimizer=None, initial_hyperparameters=hp).fit(X, Y)
    q = np.array([[2250.0, 100.0], [2650.0, -200.0]])
    m0, s0 = ref.predict(q, return_std=True)
    m1, s1 = model.predict(q, return_std=True)
    np.testing.assert_allclose(m1, m0, rtol=1e-8)
    np.testing.assert_allclose(s1, s0, rtol=1e-6)
    with pytest.raises(ValueError, match="unknown update mode"):
        model.update(X[:2], Y[:2], mode="full")
    with pytest.raises(ValueError, match=r"Y must be \(n, 3\)"):
        model.update(X[:2], Y[:2, :2])


def test_update_with_a_new_high_mode_pose(switch_model, tmp_path):
    from sklearn.gaussian_process import GaussianProcessClassifier

    model = clone(switch_model[0]).fit(*switch_model[1:3])
    msgp = model.estimators_[0]
    old = msgp.classifier_.base_estimator_
    old_rows = np.column_stack([old.X_train_, old.y_train_])
    pose = np.array([[2450.0, 600.0]])  # between the training poses, in the low-mode region
    model.update(np.repeat(pose, 3, axis=0), np.tile([63.0, 4.0e6, 1.2e3], (3, 1)))
    assert msgp.n_high_ == int(switch_model[3].sum()) + 3
    # The high-mode GP holds the new pose; the low-mode GP does not see its switching outputs.
    assert msgp.high_model_.predict(pose)[0, 0] == pytest.approx(63.0, abs=1.0)
    assert not msgp.low_model_.mask_[-3:].any()
    # Classifier: scikit-learn's GPC with the kernel held fixed on the old + new (pose, label).
    xs = (pose - msgp._x_loc) / msgp._x_scale
    rows = np.unique(np.vstack([old_rows, [[*xs[0], 1.0]]]), axis=0)
    ref = GaussianProcessClassifier(old.kernel_, optimizer=None).fit(rows[:, :-1], rows[:, -1] > 0)
    q = np.column_stack([np.linspace(2100, 2700, 13), np.linspace(-300, 600, 13)])
    np.testing.assert_allclose(
        model.mode_switch_probability(q)[:, 0],
        ref.predict_proba((q - msgp._x_loc) / msgp._x_scale)[:, 1],
        atol=1e-12,
    )
    loaded = PoseModalModel.load(model.save(tmp_path / "u.h5"))
    np.testing.assert_allclose(loaded.predict(q), model.predict(q), rtol=1e-9)
