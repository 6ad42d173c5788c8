"""Checked inputs at the door and results that say when they are wrong (issue 18, library side).

References are independent of robovib: SciPy's CSD for H1, closed-form SDOF compliances, and
scikit-learn-free synthetic GP data.
"""

import json
import time

import numpy as np
import pytest
from scipy import signal
from synthetic import hammer_hits

from robovib.frf import FRF, estimate_frf, impact_frf
from robovib.modal import ModalParameters, fit_dominant_mode, fit_modes

MODE = ModalParameters(16.5, 2e6, 0.04)


# ------------------------------------------------------------------ enumerations
def test_estimator_name_checked_h1_is_h1():
    """`estimator="h1"` used to return H2 labelled "h1"; now it is H1 (SciPy reference)."""
    fs = 512.0
    forces, responses = hammer_hits(
        [(16.5, 2e6, 0.04)], fs=fs, duration_s=2.0, n_hits=3, snr_db=20, force_noise_rel=0.05,
        width_s=8e-3,
    )  # fmt: skip
    res = impact_frf(
        forces, responses, fs, estimator="h1", force_window_s=None, pretrigger_s=0.0,
        reject=False, f_max_hz=100.0,
    )  # fmt: skip
    assert res.frf.estimator == "H1"
    # H1 = mean Gxy / mean Gxx over the (trigger-aligned) hits: recompute with SciPy
    pre = 0
    gxx = gxy = 0
    for f, r in zip(forces, responses, strict=True):
        trig = int(np.argmax(np.abs(f) >= 0.05 * np.abs(f).max()))
        fa, ra = np.zeros_like(f), np.zeros_like(r)
        fa[: f.size - (trig - pre)], ra[: r.size - (trig - pre)] = f[trig - pre :], r[trig - pre :]
        fr, pxx = signal.welch(fa, fs, window="boxcar", nperseg=f.size)
        _, pxy = signal.csd(fa, ra, fs, window="boxcar", nperseg=f.size)
        gxx, gxy = gxx + pxx, gxy + pxy
    keep = (fr > 0) & (fr <= 100.0)
    h1 = (gxy / gxx)[keep]
    np.testing.assert_allclose(res.frf.values, h1, rtol=1e-8)
    h2 = impact_frf(
        forces, responses, fs, estimator="H2", force_window_s=None, pretrigger_s=0.0,
        reject=False, f_max_hz=100.0,
    ).frf  # fmt: skip
    assert np.max(np.abs(h2.values - h1) / np.abs(h1)) > 1e-3  # H2 is really different here
    for bad in ("h3", "", "H1 "):
        with pytest.raises(ValueError, match="unknown estimator"):
            impact_frf(forces, responses, fs, estimator=bad)
        with pytest.raises(ValueError, match="unknown estimator"):
            estimate_frf(forces[0], responses[0], fs, estimator=bad)
    with pytest.raises(ValueError, match="unknown estimator"):
        FRF(np.arange(1.0, 4), np.ones(3), estimator="h1")


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"force_window_s": -0.01}, r"force_window_s must be > 0 s"),
        ({"pretrigger_s": -0.001}, r"pretrigger_s must be >= 0 s"),
        ({"exp_window_tau_s": -0.5}, r"exp_window_tau_s must be > 0 s"),
        ({"exp_window_tau_s": float("nan")}, r"exp_window_tau_s must be a finite number"),
        ({"f_max_hz": -5.0}, r"f_max_hz must be > 0 Hz"),
        ({"f_max_hz": float("inf")}, r"f_max_hz must be a finite number"),
        ({"f_max_hz": 0.1}, r"fewer than 2 bins"),
        ({"trigger_level": 0.0}, r"trigger_level must be > 0"),
        ({"clip_run": 0}, r"clip_run must be >= 1"),
    ],
)
def test_impact_options_checked(kwargs, message):
    forces, responses = hammer_hits(
        [(16.5, 2e6, 0.04)], fs=256.0, duration_s=1.0, n_hits=2, width_s=8e-3
    )
    impact_frf(forces, responses, 256.0)  # the defaults work on these hits
    with pytest.raises(ValueError, match=message):
        impact_frf(forces, responses, 256.0, **kwargs)


def test_fmin_inside_the_measured_band():
    frf = FRF(np.arange(1.0, 201.0), np.ones(200), quantity="accelerance")
    with pytest.raises(ValueError, match=r"min_frequency_hz=300 Hz leaves fewer than 2 bins"):
        frf.to_compliance(300.0)
    with pytest.raises(ValueError, match="finite number >= 0 Hz"):
        frf.to_compliance(float("nan"))
    with pytest.raises(ValueError, match="band limits must be finite"):
        frf.band(1.0, float("inf"))


def test_feed_samples_and_grid_checked():
    from robovib.milling.at_pose import base_frame_forces, predict_at_pose
    from robovib.milling.maps import workspace_lobe_map

    with pytest.raises(ValueError, match="unknown feed_direction 'z'"):
        base_frame_forces(np.ones((4, 3)), "z")
    model = _ConstantModel()
    forces = np.ones((100, 3))
    from robovib.milling import CuttingConditions

    cond = CuttingConditions(2700.0, 1e-4, 2e-3, 5e-3)
    with pytest.raises(ValueError, match="unknown feed_direction 'z'"):
        predict_at_pose(model, 2400, 0, 0, cond, forces_n=forces, feed_direction="z")
    with pytest.raises(ValueError, match="n_samples must be >= 1"):
        predict_at_pose(model, 2400, 0, 0, cond, forces_n=forces, n_samples=0)
    with pytest.raises(ValueError, match="x_mm must be a finite number in mm"):
        predict_at_pose(model, float("nan"), 0, 0, cond, forces_n=forces)
    with pytest.raises(ValueError, match="x_mm must be a non-empty 1-D array"):
        workspace_lobe_map(model, [], [0.0], [0.0], [2000.0], None, cond, None)
    with pytest.raises(ValueError, match="x_mm grid must be sorted and unique"):
        workspace_lobe_map(model, [2400.0, 2300.0], [0, 1], [0.0], [2000.0], None, cond, None)
    with pytest.raises(ValueError, match="feed_direction must be 'x' or 'y'"):
        workspace_lobe_map(model, [2400.0], [0.0], [0.0], [2000.0], None, cond, None,
                           feed_direction="z")  # fmt: skip


def test_delay_rounding_and_path_checked():
    from robovib.control import delay_analysis, design_delay_aware_lqr, design_lqr
    from robovib.control.schedule import schedule_gains

    d = design_lqr(MODE, 0.004)
    for bad, msg in (
        (float("inf"), "delay_s must be a finite number in s"),
        (float("nan"), "delay_s must be a finite number in s"),
        (-0.004, "delay_s must be >= 0 s"),
        (5.0, "delay_s must be <= 1 s"),
    ):
        with pytest.raises(ValueError, match=msg):
            delay_analysis(d, bad)
        with pytest.raises(ValueError, match=msg):
            design_delay_aware_lqr(MODE, 0.004, bad)
    with pytest.raises(ValueError, match="unknown rounding 'floor'"):
        delay_analysis(d, 0.030, rounding="floor")
    s = np.array([0.1, 0.3, 0.2, 0.4, 0.5])
    with pytest.raises(ValueError, match=r"s_m \[m\] must be sorted and unique"):
        schedule_gains(s, [MODE] * 5, r=0.001)
    with pytest.raises(ValueError, match="repeated"):
        schedule_gains([0.1, 0.2, 0.2, 0.4, 0.5], [MODE] * 5, r=0.001)


def test_fit_modes_order_bounded_and_fast():
    f = np.arange(2, 60, 0.25)
    frf = FRF(f, MODE.compliance(f))
    t0 = time.perf_counter()
    with pytest.raises(ValueError, match="max_order must be <= 200"):
        fit_modes(frf, max_order=1000)
    with pytest.raises(ValueError, match="max_order must be >= 2"):
        fit_modes(frf, max_order=1)
    with pytest.raises(ValueError, match="frequency bins"):
        fit_modes(frf, band_hz=(10, 15), max_order=60)
    assert time.perf_counter() - t0 < 1.0


def test_oma_segment_and_band_checked():
    from robovib.hybrid import oma_frfs

    t = np.arange(1000) / 1000.0
    f = np.random.default_rng(0).normal(size=(1000, 3))
    s = np.linspace(0, 0.2, 1000)
    with pytest.raises(ValueError, match="segment_length_m must be > 0 m"):
        oma_frfs(t, f, f, s, segment_length_m=0.0)
    with pytest.raises(ValueError, match="f_min_hz=50 Hz must be below f_max_hz=40 Hz"):
        oma_frfs(t, f, f, s, f_min_hz=50.0, f_max_hz=40.0)
    with pytest.raises(ValueError, match="unknown direction 'q'"):
        oma_frfs(t, f, f, s, direction="q")


# ------------------------------------------------------------------ hybrid: direction/source
def _path_frfs(direction, source, s_values, f):
    out = []
    for s in s_values:
        mode = ModalParameters(10.0 - 3.0 * s, 1e6 * (1 + 0.5 * s), 0.15)
        out.append(
            FRF(f, mode.compliance(f), direction=direction, source=source, meta={"path_s_m": s})
        )
    return out


def test_hybrid_update_checks_direction_and_source(tmp_path):
    from robovib.hybrid import FRFPoseModel

    f = np.linspace(2, 30, 15)
    model = FRFPoseModel(f, rng=0).fit_frfs(_path_frfs("x", "EMA", np.linspace(0, 1.2, 6), f))
    assert model.direction_ == "x"
    model.save(tmp_path / "m.h5")
    back = FRFPoseModel.load(tmp_path / "m.h5")
    assert back.direction_ == "x"
    with pytest.raises(ValueError, match="direction 'x' but the FRFs are 'y'"):
        back.update_frfs(_path_frfs("y", "OMA", [0.3, 0.7], f))
    with pytest.raises(ValueError, match="FRF 0 is a EMA FRF; this update expects OMA"):
        back.update_frfs(_path_frfs("x", "EMA", [0.3, 0.7], f))
    with pytest.raises(ValueError, match="several directions"):
        FRFPoseModel(f).fit_frfs(_path_frfs("x", "EMA", [0, 1], f) + _path_frfs("y", "EMA", [2], f))
    rep = back.update_frfs(_path_frfs("x", "OMA", [0.3, 0.7], f), mode="posterior")
    assert rep.mode == "posterior"
    assert np.all(back.gp_._active_groups[-2:] == 1)  # OMA noise group


# ------------------------------------------------------------------ flags on fits
def _noisy(values, rel=0.02, seed=0):
    rng = np.random.default_rng(seed)
    scale = np.abs(values).max()
    return values + rel * scale * (rng.normal(size=values.size) + 1j * rng.normal(size=values.size))


def test_clean_fit_is_not_flagged():
    f = np.arange(2, 60, 0.25)
    fit = fit_dominant_mode(FRF(f, _noisy(MODE.compliance(f))))
    assert fit.flags == () and not fit.flagged
    assert fit.parameters.natural_frequency_hz == pytest.approx(16.5, rel=0.01)
    assert fit.to_dict()["flagged"] is False
    multi = fit_modes(FRF(f, MODE.compliance(f)), (5, 40), max_order=20)
    assert not multi.flagged, multi.flags


@pytest.mark.parametrize("band", [None, (10.0, 40.0)])
def test_inverted_polarity_fit_is_flagged(band):
    """A -X FRF (hammer polarity reversed) used to give fn at the band edge or zeta 99 %; it is
    flagged with its cause, and with the symptom the fit shows (edge, damping or misfit)."""
    f = np.arange(2, 60, 0.25)
    fit = fit_dominant_mode(FRF(f, -_noisy(MODE.compliance(f))), band)
    assert fit.flagged
    text = " ".join(fit.flags)
    assert "inverted sign" in text
    assert any(s in text for s in ("edge of the fit band", "damping ratio", "large residual"))
    doc = fit.to_dict()
    assert doc["flagged"] is True and doc["flags"] == list(fit.flags)


def test_noise_only_fit_is_flagged():
    f = np.arange(2, 60, 0.25)
    fit = fit_dominant_mode(FRF(f, _noisy(np.zeros(f.size, complex) + 1e-12, rel=1.0)))
    assert fit.flagged


def test_fit_modes_flags_inverted_sign():
    f = np.arange(2, 60, 0.25)
    with pytest.warns(Warning):
        multi = fit_modes(FRF(f, -MODE.compliance(f)), (5, 40), max_order=20)
    assert multi.flagged
    assert any("negative modal mass" in x for x in multi.flags)


# ------------------------------------------------------------------ extrapolation
def _ConstantModel():
    """Tiny pose model over X 2100-2700 mm, Y -300-600 mm, Rz -90-90 deg (SI outputs)."""
    from robovib.gp import PoseModalModel

    rng = np.random.default_rng(0)
    X = np.column_stack(
        [rng.uniform(2100, 2700, 30), rng.uniform(-300, 600, 30), rng.uniform(-90, 90, 30)]
    )
    base = np.array([20.0, 2e6, 500.0, 25.0, 3e6, 600.0, 40.0, 5e6, 800.0])
    Y = base * (1 + 0.05 * np.sin(X[:, :1] / 200.0)) * (1 + 0.001 * rng.normal(size=(30, 9)))
    return PoseModalModel(kernel="isotropic", mode_switch=False, rng=0).fit(X, Y)


def test_every_pose_prediction_says_when_it_extrapolates():
    from robovib.gp.extrapolation import extrapolating
    from robovib.milling import CuttingConditions
    from robovib.milling.at_pose import pose_extrapolation, predict_at_pose

    model = _ConstantModel()
    forces = np.random.default_rng(1).normal(size=(1500, 3))
    cond = CuttingConditions(2700.0, 1e-4, 2e-3, 5e-3)
    inside = predict_at_pose(model, 2400, 100, 0, cond, forces_n=forces, n_samples=3, skip_s=0.1)
    outside = predict_at_pose(model, 99999, 100, 0, cond, forces_n=forces, n_samples=3, skip_s=0.1)
    assert all(not p.extrapolating and p.extrapolation == () for p in inside)
    assert all(p.extrapolating and p.extrapolation == ("x_mm",) for p in outside)
    assert pose_extrapolation(model, (2400, 700, 100)) == ("y_mm", "rz_deg")
    np.testing.assert_array_equal(
        extrapolating(model, [[2400, 0, 0], [99999, 0, 0], [2400, -301, 0]]), [False, True, True]
    )


# ------------------------------------------------------------------ JSON
def test_json_never_contains_nan_or_infinity():
    from robovib.io import json_dumps

    doc = {"band_m": (np.nan, np.nan), "x": np.array([1.0, np.inf]), "n": np.int64(3), "ok": 1.5}
    text = json_dumps(doc)

    def refuse(token):
        raise AssertionError(f"non-JSON token {token}")

    back = json.loads(text, parse_constant=refuse)
    assert back["band_m"] == [None, None] and back["x"] == [1.0, None] and back["n"] == 3
    assert set(back["null_reasons"]) == {"band_m[0]", "band_m[1]", "x[1]"}
    assert "not a number" in back["null_reasons"]["band_m[0]"]


def test_lobes_at_pose_checked_and_flagged():
    from robovib.milling import ALUMINIUM_7075 as coef
    from robovib.milling.at_pose import lobes_at_pose

    model = _ConstantModel()
    with pytest.raises(ValueError, match="unknown feed_direction 'z'"):
        lobes_at_pose(model, 2400, 0, 0, coef, feed_direction="z")
    with pytest.raises(ValueError, match=r"min < max, got 3000-100 rpm"):
        lobes_at_pose(model, 2400, 0, 0, coef, rpm_range=(3000, 100))
    with pytest.raises(ValueError, match=r"rpm_range\[1\] must be a finite number in rpm"):
        lobes_at_pose(model, 2400, 0, 0, coef, rpm_range=(100, float("inf")))
    with pytest.raises(ValueError, match="radial_depth_m must be > 0 m"):
        lobes_at_pose(model, 2400, 0, 0, coef, radial_depth_m=0.0)
    inside = lobes_at_pose(model, 2400, 0, 0, coef, n_speeds=20)
    outside = lobes_at_pose(model, 99999, 0, 0, coef, n_speeds=20)
    assert not inside.extrapolating and outside.extrapolation == ("x_mm",)
    assert inside.spindle_rpm.shape == inside.critical_depth_m.shape == (20,)
