"""Issue 24: covariance families, the predictive distribution (latent/measurement, mode
mixture) and the grouped-CV band calibration, against SciPy / scikit-learn / known truths."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import integrate, stats

from robovib.gp import BatchedGPRegressor, PoseModalModel
from robovib.gp.bands import ModalPredictive
from robovib.gp.calibration import fit_student_t, grouped_folds


# ------------------------------------------------------------------------------ kernels
@pytest.mark.oracle
@pytest.mark.parametrize(("covariance", "nu"), [("matern52", 2.5), ("matern32", 1.5), ("se", None)])
def test_covariance_families_match_scikit_learn(covariance, nu):
    from sklearn.gaussian_process import GaussianProcessRegressor
    from sklearn.gaussian_process.kernels import RBF, Matern, WhiteKernel
    from sklearn.gaussian_process.kernels import ConstantKernel as C

    rng = np.random.default_rng(1)
    X = rng.uniform(0, 3, (40, 2))
    y = np.sin(X[:, 0]) + 0.3 * X[:, 1] ** 2 + 0.05 * rng.standard_normal(40)
    gp = BatchedGPRegressor(kernel="ard", covariance=covariance, mean="zero", normalize=False,
                            rng=0, n_restarts=3).fit(X, y[:, None])  # fmt: skip
    hp = gp.hyperparameters_
    base = Matern(hp.length_scales[0], nu=nu) if nu else RBF(hp.length_scales[0])
    fixed = C(hp.signal_std[0] ** 2) * base + WhiteKernel(hp.noise_std[0] ** 2)
    sk = GaussianProcessRegressor(fixed, optimizer=None).fit(X, y)
    Xq = rng.uniform(0, 3, (7, 2))
    m, s = gp.predict(Xq, return_std=True)
    m_sk, s_sk = sk.predict(Xq, return_std=True)  # includes the white noise
    np.testing.assert_allclose(m[:, 0], m_sk, atol=1e-7)
    np.testing.assert_allclose(np.hypot(s[:, 0], hp.noise_std[0]), s_sk, atol=1e-7)
    np.testing.assert_allclose(gp.log_marginal_likelihood()[0], sk.log_marginal_likelihood_value_)
    # Our optimum is scikit-learn's (the analytic gradient of each family is right).
    free = C(1.0) * (Matern(np.ones(2), nu=nu) if nu else RBF(np.ones(2))) + WhiteKernel(0.01)
    sk_opt = GaussianProcessRegressor(free, n_restarts_optimizer=5, random_state=0).fit(X, y)
    assert gp.log_marginal_likelihood()[0] >= sk_opt.log_marginal_likelihood_value_ - 1e-3
    one_m, one_s = gp.predict_one(Xq[0])
    np.testing.assert_allclose([one_m[0], one_s[0]], [m[0, 0], s[0, 0]], rtol=1e-9)


def test_unknown_covariance_is_refused():
    with pytest.raises(ValueError, match="unknown covariance"):
        BatchedGPRegressor(covariance="rbf").fit(np.arange(5.0)[:, None], np.arange(5.0))
    with pytest.raises(ValueError, match="needs calibrate=True"):
        PoseModalModel(covariance="auto").fit(np.zeros((4, 3)), np.ones((4, 9)))


# ------------------------------------------------------------------------------ predictive
@pytest.mark.oracle
@pytest.mark.parametrize("dof", [1, 2, 3, 4, 6, 10, 30, np.inf])
def test_numpy_student_t_matches_scipy(dof):
    from robovib.gp.bands import _t_cdf, _t_logpdf, t_quantile

    z = np.linspace(-9, 9, 181)
    ref = stats.t(dof) if np.isfinite(dof) else stats.norm()
    np.testing.assert_allclose(_t_cdf(z, dof), ref.cdf(z), atol=1e-14)
    np.testing.assert_allclose(_t_logpdf(z, dof), ref.logpdf(z), atol=1e-12)
    for q in (0.75, 0.95, 0.975):
        assert float(t_quantile(q, np.array(dof))) == pytest.approx(ref.ppf(q), abs=1e-10)


def _one(p, means, lat, noise, scale=(1.0, 1.0), dof=(np.inf, np.inf)) -> ModalPredictive:
    return ModalPredictive(
        ("x_fn_hz",), ("Hz",), ("x",), np.array([[p]]), np.array([[means]], float),
        np.array([[lat]], float), np.array([[noise]], float), np.array([scale], float),
        np.array([dof], float),
    )  # fmt: skip


@pytest.mark.oracle
def test_single_component_sets_are_scipy_intervals():
    g = _one(0.0, (10.0, 10.0), (0.3, 0.3), (0.4, 0.4))
    (iv,) = g.intervals(0.95, "measurement")[0][0]
    np.testing.assert_allclose(iv, stats.norm.interval(0.95, 10.0, 0.5), rtol=1e-12)
    (iv,) = g.intervals(0.9, "latent")[0][0]
    np.testing.assert_allclose(iv, stats.norm.interval(0.9, 10.0, 0.3), rtol=1e-12)
    t = _one(0.0, (10.0, 10.0), (0.3, 0.3), (0.4, 0.4), scale=(2.0, 2.0), dof=(4.0, 4.0))
    s = np.hypot(2.0 * 0.3, 0.4)  # the calibration scales the latent std only
    (iv,) = t.intervals(0.95)[0][0]
    np.testing.assert_allclose(iv, stats.t.interval(0.95, 4.0, 10.0, s), rtol=1e-10)
    np.testing.assert_allclose(t.logpdf([[11.0]]), stats.t.logpdf(11.0, 4.0, 10.0, s))
    np.testing.assert_allclose(t.point_std("measurement"), stats.t.std(4.0, 10.0, s))
    np.testing.assert_allclose(t.point_std("latent"), stats.t.std(4.0, 0.0, 0.6))


@pytest.mark.oracle
def test_bimodal_set_holds_its_mass_and_matches_the_scipy_mixture():
    pr = _one(0.3, (16.0, 63.5), (0.5, 0.4), (0.2, 0.3), scale=(1.2, 0.9), dof=(6.0, np.inf))
    s = pr.component_scale("measurement")[0, 0]

    def pdf(y):
        return 0.7 * stats.t.pdf(y, 6.0, 16.0, s[0]) + 0.3 * stats.norm.pdf(y, 63.5, s[1])

    sets = pr.intervals(0.95)[0][0]
    assert len(sets) == 2  # two modes, two intervals
    mass = sum(integrate.quad(pdf, a, b)[0] for a, b in sets)
    assert mass == pytest.approx(0.95, abs=2e-3)
    ends = [pdf(v) for iv in sets for v in iv]  # a highest-density set: equal density at its ends
    np.testing.assert_allclose(ends, ends[0], rtol=0.05)
    y = np.array([[15.2]])
    expect_cdf = 0.7 * stats.t.cdf(15.2, 6.0, 16.0, s[0]) + 0.3 * stats.norm.cdf(15.2, 63.5, s[1])
    np.testing.assert_allclose(pr.cdf(y), expect_cdf)
    np.testing.assert_allclose(np.exp(pr.logpdf(y)), pdf(15.2))
    assert pr.point()[0, 0] == 16.0  # the more probable mode, never a blend
    draws = pr.sample(20000, rng=0, kind="measurement")[:, 0, 0]
    assert np.mean(draws > 40) == pytest.approx(0.3, abs=0.015)


def test_sample_draws_one_mode_per_direction():
    n_out = 3
    pr = ModalPredictive(
        ("x_fn_hz", "x_stiffness_n_per_m", "x_damping_ns_per_m"), ("Hz", "N/m", "N*s/m"),
        ("x", "x", "x"), np.full((1, n_out), 0.5),
        np.array([[[16.0, 63.0], [3e6, 5e6], [7e3, 1e3]]]), np.full((1, n_out, 2), 1e-6),
        np.zeros((1, n_out, 2)), np.ones((n_out, 2)), np.full((n_out, 2), np.inf),
    )  # fmt: skip
    d = pr.sample(2000, rng=1)[:, 0, :]
    high = d[:, 0] > 40
    assert 0.4 < high.mean() < 0.6
    np.testing.assert_array_equal(d[:, 1] > 4e6, high)  # k of the same mode as fn
    np.testing.assert_array_equal(d[:, 2] < 4e3, high)


# ------------------------------------------------------------------------------ calibration
def test_student_t_fit_recovers_scale_and_tail():
    rng = np.random.default_rng(3)
    dof, scale, _ = fit_student_t(2.5 * rng.standard_t(4.0, 4000))
    assert scale == pytest.approx(2.5, rel=0.1)
    assert 3.0 <= dof <= 6.0
    dof, scale, _ = fit_student_t(0.7 * rng.standard_normal(4000))
    assert dof >= 30 and scale == pytest.approx(0.7, rel=0.05)
    # Latent and noise parts: only the latent std is scaled (noise known from replicates).
    lat = rng.uniform(0.5, 2.0, 4000)
    noise = np.full(4000, 0.8)
    e = np.sqrt((1.8 * lat) ** 2 + noise**2) * rng.standard_normal(4000)
    dof, scale, _ = fit_student_t(e, lat, noise)
    assert dof >= 30 and scale == pytest.approx(1.8, rel=0.05)
    # Too few errors: Gaussian, never narrowed.
    dof, scale, _ = fit_student_t([0.1, -0.2, 0.05])
    assert np.isinf(dof) and scale == 1.0


def test_grouped_folds_keep_replicates_together():
    X = np.repeat(np.arange(12.0)[:, None] * [1.0, 2.0], 3, axis=0)
    fold = grouped_folds(X, 5, rng=0)
    for pose in range(12):
        assert np.unique(fold[3 * pose : 3 * pose + 3]).size == 1
    assert np.unique(fold).size == 5
    with pytest.raises(ValueError, match="2 distinct poses"):
        grouped_folds(np.zeros((4, 2)), 5)


def _synthetic(rng, n_pose, reps=2):
    """A rough pose dependence with heavy-tailed test-to-test scatter (known truth)."""
    X = rng.uniform([2100, -300, 0], [2700, 600, 180], (n_pose, 3))

    def truth(X):
        u = (X[:, 0] - 2100) / 600
        v = (X[:, 1] + 300) / 900
        fn = 15 + 3 * u + 1.5 * np.sin(5 * v) + 0.8 * np.abs(np.sin(np.radians(2 * X[:, 2])))
        k = 3e6 * (1 + 0.3 * u - 0.2 * np.cos(4 * v))
        c = 6e3 * (1 + 0.4 * v) + 800 * np.sin(np.radians(X[:, 2]))
        return np.column_stack([fn, k, c])

    Xr = np.repeat(X, reps, axis=0)
    T = truth(Xr)
    noise = rng.standard_t(3, T.shape) * T * [0.01, 0.04, 0.05]
    return Xr, T + noise, truth


def test_calibrated_bands_cover_unseen_poses_of_a_synthetic_robot():
    """Bands calibrated on 40 poses cover new measurements at 40 unseen poses at ~95 %."""
    rng = np.random.default_rng(7)
    X, Y, _ = _synthetic(rng, 40)
    m = PoseModalModel(directions=("x",), mode_switch=False, calibrate=True,
                       covariance="matern52", rng=0).fit(X, Y)  # fmt: skip
    Xt, Yt, _ = _synthetic(np.random.default_rng(8), 40)
    pred = m.predictive(Xt)
    cover = pred.contains(Yt, 0.95).mean()
    assert 0.88 <= cover <= 0.995
    cal = m.calibration_
    assert cal.coverage.shape == (3, 3) and np.all(cal.n == 80)
    assert set(m.covariances_) == {"matern52"}
    # Latent band (the modal parameter itself) is narrower than the measurement band.
    lat = pred.intervals(0.95, "latent")
    meas = pred.intervals(0.95, "measurement")
    assert all(
        (lv[0][1] - lv[0][0]) < (mv[0][1] - mv[0][0])
        for lr, mr in zip(lat, meas, strict=True)
        for lv, mv in zip(lr, mr, strict=True)
    )


def test_calibration_round_trips_through_the_file_and_the_fast_predictor(tmp_path):
    from robovib.gp.saved_model import PosePredictor, predict_at

    rng = np.random.default_rng(2)
    X, Y, _ = _synthetic(rng, 25)
    m = PoseModalModel(directions=("x",), mode_switch=False, calibrate=True, covariance="auto",
                       rng=0).fit(X, Y)  # fmt: skip
    path = m.save(tmp_path / "m.h5")
    back, fast = PoseModalModel.load(path), PosePredictor.load(path)
    Xq = X[:4] + 7.0
    ref = m.predictive(Xq)
    for other in (back, fast):
        got = other.predictive(Xq)
        np.testing.assert_allclose(got.point(), ref.point(), rtol=1e-8)
        np.testing.assert_allclose(got.point_std("measurement"), ref.point_std("measurement"),
                                   rtol=1e-6)  # fmt: skip
    assert back.calibration_.covariance == m.calibration_.covariance
    out = predict_at(fast, dict(zip(m.input_names, Xq[0], strict=True)))
    first = out.outputs[0]
    assert first["measurement_std"] > first["std"] > 0
    ((lo, hi),) = first["measurement_95"]
    assert lo < first["mean"] < hi


def test_reliability_figure_has_a_panel_per_output_and_the_coverage(tmp_path):
    import matplotlib

    matplotlib.use("Agg")
    from robovib.gp import plot_calibration

    rng = np.random.default_rng(4)
    X, Y, _ = _synthetic(rng, 20)
    m = PoseModalModel(directions=("x",), mode_switch=False, calibrate=True, rng=0).fit(X, Y)
    fig = plot_calibration(m.calibration_)
    visible = [ax for ax in fig.axes if ax.get_visible()]
    assert len(visible) == 4  # 3 PIT histograms + coverage
    heights = [p.get_height() for p in visible[0].patches]
    # Density histogram: its area is 1 (bins of width 0.1).
    assert sum(heights) * 0.1 == pytest.approx(1.0)
    table = m.calibration_.table()
    assert list(table["output"]) == list(m.output_names_)
    assert {"coverage_50", "coverage_90", "coverage_95", "nlpd", "rmse"} <= set(table.columns)


def test_stability_sampling_draws_the_mode_mixture_of_the_pose_model():
    """P(stable) samples the calibrated mixture: the share of high-mode X draws is P(high)."""
    from robovib.gp import load_chapter3_model
    from robovib.milling.uncertainty import mode_distribution_at_pose

    model = load_chapter3_model()
    # A pose where the classifier hesitates between the 16-23 Hz and the ~63 Hz X mode.
    cand = np.column_stack([np.full(46, 2700.0), np.zeros(46), np.linspace(0.0, 45.0, 46)])
    p = model.mode_switch_probability(cand)[:, 0]
    pose = cand[int(np.argmin(np.abs(p - 0.5)))]
    p_high = float(model.mode_switch_probability(pose[None])[0, 0])
    assert 0.2 < p_high < 0.8
    dist = mode_distribution_at_pose(model, pose, n_draws=4000, rng=1)
    draws = dist["x"].draws
    assert draws.shape == (4000, 3)
    high = draws[:, 0] > model.mode_switches_["x"].threshold_hz
    assert high.mean() == pytest.approx(p_high, abs=0.03)
    # k and c come from the same mode as fn: the high mode's damping is far lower.
    assert (
        np.median(draws[high, 2]) < 0.5 * np.median(draws[~high, 2])
        if 0.05 < p_high < 0.95
        else True
    )
    picked = dist["x"].sample(50, rng=2)
    assert len(picked) == 50 and all(m.natural_frequency_hz > 0 for m in picked)


def test_lobes_say_which_mode_they_assumed_where_the_model_is_unsure():
    from robovib.gp import load_chapter3_model
    from robovib.milling import ALUMINIUM_7075, CuttingConditions, MillingTool
    from robovib.milling.chart import lobes_chart

    model = load_chapter3_model()
    kw = dict(tool=MillingTool(), conditions=CuttingConditions(1000.0, 1e-4, 1e-3, 6e-3),
              coefficients=ALUMINIUM_7075, spindle_rpm=np.linspace(200, 3000, 40), method="zoa",
              pose_model=model)  # fmt: skip
    unsure = lobes_chart(pose=(2700.0, 0.0, 20.0), **kw)
    p = model.mode_switch_probability([[2700.0, 0.0, 20.0]])[0, 0]
    assert 0.05 < p < 0.95
    assert len(unsure.notes) == 1 and unsure.notes[0].startswith("x: P(high mode dominant)")
    assert unsure.to_dict()["notes"] == list(unsure.notes)
    sure = lobes_chart(pose=(2100.0, 0.0, 45.0), **kw)
    assert model.mode_switch_probability([[2100.0, 0.0, 45.0]])[0, 0] < 0.05
    assert sure.notes == ()
