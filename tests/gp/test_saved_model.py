"""robovib.gp.saved_model: the NumPy-only predictor of a saved pose model.

References: the full PoseModalModel loaded from the same file (scikit-learn estimators),
scikit-learn's GaussianProcessClassifier for the Laplace classifier, SciPy's Delaunay
triangulation for the hull test.
"""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from robovib.gp import PoseModalModel
from robovib.gp.chapter3_model import chapter3_model_path, load_chapter3_predictor
from robovib.gp.extrapolation import _in_hull
from robovib.gp.saved_model import PosePredictor, _LaplaceGPC, predict_at


@pytest.fixture(scope="module")
def shipped():
    return PoseModalModel.load(chapter3_model_path()), load_chapter3_predictor()


def _poses(model, n, seed):
    rng = np.random.default_rng(seed)
    lo, hi = model.input_min_, model.input_max_
    X = rng.uniform(lo - 0.15 * (hi - lo), hi + 0.15 * (hi - lo), size=(n, lo.size))
    return np.vstack([X, model.X_train_])


def test_shipped_model_predictions_match_the_full_model(shipped):
    full, fast = shipped
    assert isinstance(fast, PosePredictor)
    X = _poses(full, 400, 0)
    m_ref, s_ref = full.predict(X, return_std=True)
    m, s = fast.predict(X, return_std=True)
    np.testing.assert_allclose(m, m_ref, rtol=1e-10)
    np.testing.assert_allclose(s, s_ref, rtol=1e-8, atol=1e-10 * np.nanmax(s_ref))
    np.testing.assert_allclose(
        fast.mode_switch_probability(X), full.mode_switch_probability(X), rtol=0, atol=1e-10
    )
    np.testing.assert_array_equal(fast.extrapolating(X), full.extrapolating(X))
    np.testing.assert_array_equal(fast.outside_inputs(X), full.outside_inputs(X))
    assert fast.output_names_ == full.output_names_
    assert fast.output_units_ == full.output_units_


def test_predict_at_is_the_same_for_both(shipped):
    full, fast = shipped
    pose = {"x_mm": 2900.0, "y_mm": 0.0, "rz_deg": 45.0}
    a, b = predict_at(full, pose).to_dict(), predict_at(fast, pose).to_dict()
    assert a["extrapolating"] and a["outside_inputs"] == ["x_mm"]
    assert a.keys() == b.keys() and a["notes"] == b["notes"]
    assert a["high_mode_probability"] == pytest.approx(b["high_mode_probability"], abs=1e-10)
    for name, ref in a["predictions"].items():
        assert b["predictions"][name]["unit"] == ref["unit"]
        assert b["predictions"][name]["mean"] == pytest.approx(ref["mean"], rel=1e-10)


def test_modes_and_next_poses_are_the_same_for_both(shipped):
    """Issue 27: the pose commands (mill, control, next-poses) read the predictor; its modes
    and next-pose choice equal the full model's."""
    from robovib.campaign import next_poses

    full, fast = shipped
    X = full.X_train_[::15] + np.array([10.0, -10.0, 5.0])  # near training poses: physical modes
    assert len(X) >= 10
    for a, b in zip(full.modes(X), fast.modes(X), strict=True):
        assert a.keys() == b.keys()
        for d in a:
            pa, pb = a[d], b[d]
            assert pb.parameters.natural_frequency_hz == pytest.approx(
                pa.parameters.natural_frequency_hz, rel=1e-10
            )
            assert pb.parameters.damping_ratio == pytest.approx(
                pa.parameters.damping_ratio, rel=1e-9
            )
            assert pb.fn_std_hz == pytest.approx(pa.fn_std_hz, rel=1e-8)
            assert pb.extrapolating == pa.extrapolating
            assert pb.high_mode_probability == pytest.approx(pa.high_mode_probability, abs=1e-10)
    cand = _poses(full, 40, 2)[:40]
    ref, got = next_poses(full, cand, k=4), next_poses(fast, cand, k=4)
    np.testing.assert_array_equal(got.indices, ref.indices)
    np.testing.assert_allclose(got.variance_reduction, ref.variance_reduction, rtol=1e-8)
    assert got.total_variance_before == pytest.approx(ref.total_variance_before, rel=1e-8)


@pytest.mark.oracle
def test_laplace_classifier_matches_scikit_learn():
    from sklearn.gaussian_process import GaussianProcessClassifier
    from sklearn.gaussian_process.kernels import RBF
    from sklearn.gaussian_process.kernels import ConstantKernel as C

    rng = np.random.default_rng(3)
    X = rng.normal(size=(40, 3))
    y = (X[:, 0] + 0.5 * X[:, 1] ** 2 + 0.3 * rng.normal(size=40)) > 0.4
    Xq = rng.normal(size=(200, 3)) * 1.5
    for theta in (np.log([2.0, 0.7, 1.5, 3.0]), np.log([30.0, 0.3, 5.0, 1e5])):
        kernel = (C(1.0) * RBF(np.ones(3))).clone_with_theta(theta)
        ref = GaussianProcessClassifier(kernel, optimizer=None).fit(X, y).predict_proba(Xq)[:, 1]
        np.testing.assert_allclose(_LaplaceGPC(X, y, theta).predict_proba(Xq), ref, atol=1e-10)


@pytest.mark.parametrize("dim", [2, 3, 4])
def test_hull_test_matches_delaunay(dim):
    from scipy.spatial import Delaunay

    rng = np.random.default_rng(dim)
    pts = rng.normal(size=(25 + 5 * dim, dim))
    q = rng.normal(size=(300, dim)) * 1.3
    q = np.vstack([q, pts, 0.5 * (pts[:10] + pts[10:20])])  # vertices and inner points
    ref = Delaunay(pts).find_simplex(q, tol=1e-9) >= 0
    got = np.array([_in_hull(pts, x) for x in q])
    np.testing.assert_array_equal(got, ref)


def test_saved_model_with_noise_groups_isotropic_and_no_switch(tmp_path):
    rng = np.random.default_rng(5)
    X = rng.uniform([0, 0], [1, 2], size=(30, 2))
    u, v = X[:, 0], X[:, 1]
    base = np.column_stack(
        [10 + 3 * np.sin(3 * u), 1e6 * (1.5 + np.cos(2 * v)), 500 + 100 * np.sin(2 * u * v)]
    )
    Y = base * (1 + 0.02 * rng.normal(size=base.shape))
    Y[3, 1] = np.nan  # a missing cell
    groups = (np.arange(30) % 2).astype(int)
    model = PoseModalModel(("u_m", "v_m"), ("x",), kernel="isotropic", mode_switch=False)
    model.fit(X, Y, groups=groups).save(tmp_path / "m.h5")
    fast = PosePredictor.load(tmp_path / "m.h5")
    model = PoseModalModel.load(tmp_path / "m.h5")  # what the predictor replaces
    Xq = _poses(model, 100, 1)
    m_ref, s_ref = model.predict(Xq, return_std=True)
    m, s = fast.predict(Xq, return_std=True)
    np.testing.assert_allclose(m, m_ref, rtol=1e-10)
    np.testing.assert_allclose(s, s_ref, rtol=1e-8)
    assert fast.mode_switch_probability(Xq) is None
    np.testing.assert_array_equal(fast.extrapolating(Xq), model.extrapolating(Xq))


def test_bad_files_and_inputs(tmp_path, shipped):
    (tmp_path / "x.h5").write_text("not hdf5")
    with pytest.raises(ValueError, match="not a readable HDF5 file"):
        PosePredictor.load(tmp_path / "x.h5")
    _, fast = shipped
    with pytest.raises(ValueError, match="NaN or inf"):
        fast.predict([[2400.0, np.nan, 45.0]])
    with pytest.raises(ValueError, match=r"X must be \(n, 3\)"):
        fast.predict([[2400.0, 0.0]])
    with pytest.raises(ValueError, match="missing rz_deg"):
        predict_at(fast, {"x_mm": 2400.0, "y_mm": 0.0})


def test_prediction_imports_neither_scikit_learn_nor_scipy_nor_pandas():
    code = (
        "import sys\n"
        "from robovib.gp.chapter3_model import load_chapter3_predictor\n"
        "from robovib.gp.saved_model import predict_at\n"
        "p = predict_at(load_chapter3_predictor(), {'x_mm': 2400, 'y_mm': 0, 'rz_deg': 45})\n"
        "print(sorted(m for m in ('sklearn', 'scipy', 'pandas') if m in sys.modules))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


def test_gpr_predict_command_imports_neither_scikit_learn_nor_scipy_nor_pandas():
    """The whole command (options, prediction, JSON provenance): what keeps it under 1 s."""
    cmd = [sys.executable, "-X", "importtime", "-m", "robovib.cli", "gpr", "predict",
           "--x", "2400", "--y", "0", "--rz", "45", "--json"]  # fmt: skip
    out = subprocess.run(cmd, capture_output=True, text=True, check=True)
    imported = {line.rsplit("|", 1)[-1].strip() for line in out.stderr.splitlines()}
    assert "robovib.gp.saved_model" in imported
    assert not imported & {"sklearn", "scipy", "pandas", "matplotlib"}
