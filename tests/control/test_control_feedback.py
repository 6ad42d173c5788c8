"""Issue 40: ``adaptive+force``'s band-stable delay-aware feedback and the loop with a delay
the gains were not designed for.

References: the closed loop simulated step by step from the mode's own ODE (exact
zero-order hold by SciPy) with the correction applied ``D`` periods late, against the
spectral radius of :func:`implemented_loop_matrix` with ``plant_delay_steps=D``.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy import signal

from robovib.control.controller_file import design_controller, load_controller
from robovib.control.controllers import DelayAwareFeedback
from robovib.control.design import band_stable_feedback
from robovib.control.loop_analysis import implemented_loop_matrix
from robovib.control.lqr import design_delay_aware_lqr, spectral_radius
from robovib.control.path_design import ControlPath
from robovib.gp.dominant_modes import PoseMode
from robovib.modal.parameters import ModalParameters

MODE = ModalParameters(18.0, 1.0e6, 0.05)
T = 0.004


def _simulated_decay(gains, designed_steps: int, true_steps: int, n: int = 4000,
                     actuator_gain: float = 1.0, mode: ModalParameters = MODE) -> float:  # fmt: skip
    """Per-period growth factor of the loop run step by step (its last 2000 periods).

    The plant gets ``actuator_gain`` x the command; the controller's history is the command.
    """
    wn, z = 2 * np.pi * mode.natural_frequency_hz, mode.damping_ratio
    a = np.array([[0.0, 1.0], [-(wn**2), -2 * z * wn]])
    b = np.array([[0.0], [wn**2]])  # a correction moves the mode like a base displacement
    ad, bd, *_ = signal.cont2discrete((a, b, np.eye(2), np.zeros((2, 1))), T)
    g = np.asarray(gains, float)
    x = np.array([1e-3, 0.0])
    x_prev = 0.0
    u = np.zeros(n + max(designed_steps, true_steps) + 1)  # u[k + off]: command of period k
    off = max(designed_steps, true_steps)
    norms = []
    for k in range(n):
        v = (x[0] - x_prev) / T
        hist = u[k + off - designed_steps : k + off][::-1]  # u_{k-1}, ..., u_{k-d}
        u[k + off] = -(g[0] * x[0] + g[1] * v + g[2:] @ hist)
        x_prev = x[0]
        x = ad @ x + bd[:, 0] * (actuator_gain * u[k + off - true_steps])
        norms.append(np.abs(x).sum() + np.abs(u[k + off - 2 * off : k + off + 1]).sum())
    return (norms[-1] / norms[-2001]) ** (1 / 2000)


@pytest.mark.parametrize("true_steps", [6, 8, 12])
def test_loop_matrix_with_a_wrong_delay_matches_the_loop_run_step_by_step(true_steps):
    gains = design_delay_aware_lqr(MODE, T, 8 * T, r=[[30.0]]).gains
    rho = spectral_radius(implemented_loop_matrix(MODE, gains, T, 8,
                                                  plant_delay_steps=true_steps))  # fmt: skip
    assert _simulated_decay(gains, 8, true_steps) == pytest.approx(rho, abs=2e-3)


@pytest.mark.parametrize(("true_steps", "actuator_gain"), [(8, 0.8), (12, 1.2), (6, 1.5)])
def test_loop_matrix_with_an_actuator_gain_error_matches_the_loop_run_step_by_step(
    true_steps, actuator_gain
):
    gains = design_delay_aware_lqr(MODE, T, 8 * T, r=[[30.0]]).gains
    rho = spectral_radius(implemented_loop_matrix(MODE, gains, T, 8, plant_delay_steps=true_steps,
                                                  actuator_gain=actuator_gain))  # fmt: skip
    simulated = _simulated_decay(gains, 8, true_steps, actuator_gain=actuator_gain)
    assert simulated == pytest.approx(rho, abs=2e-3)


@pytest.mark.parametrize("bad", [0.0, -1.0, float("nan"), float("inf")])
def test_loop_matrix_refuses_a_non_positive_or_non_finite_actuator_gain(bad):
    gains = design_delay_aware_lqr(MODE, T, 8 * T, r=[[30.0]]).gains
    with pytest.raises(ValueError, match="actuator_gain"):
        implemented_loop_matrix(MODE, gains, T, 8, actuator_gain=bad)
    with pytest.raises(ValueError, match="actuator_gains"):
        band_stable_feedback([[MODE]], [MODE], T, 0.032, (0.032,), actuator_gains=(1.0, bad))


def test_band_stable_feedback_over_the_actuator_gain_refuses_a_weight_that_grows_at_plus_20_pct():
    """The weight chosen with a perfect actuator grows, run step by step, with 1.2x the
    command; the one chosen over 0.8-1.2 decays with every gain and delay of the check."""
    fast = ModalParameters(18.0 * 1.05, 1.0e6, 0.05)
    band = [[ModalParameters(18.0 * f, 1.0e6, 0.05)] for f in (0.95, 1.0, 1.05)]
    grid = np.logspace(-1, 3, 9)
    delays = (0.024, 0.032, 0.040, 0.048)
    r1, g1, _ = band_stable_feedback([band], [MODE], T, 0.032, delays, r_grid=grid)
    r2, g2, worst = band_stable_feedback([band], [MODE], T, 0.032, delays, r_grid=grid,
                                         actuator_gains=(0.8, 1.0, 1.2))  # fmt: skip
    assert r2 > r1 and max(worst) < 1.0
    assert _simulated_decay(g1[0], 8, 12, actuator_gain=1.2, mode=fast) > 1.0
    for k in (0.8, 1.2):
        for steps in (6, 12):
            assert _simulated_decay(g2[0], 8, steps, actuator_gain=k, mode=fast) < 1.0


def test_loop_matrix_with_the_designed_delay_is_unchanged():
    gains = design_delay_aware_lqr(MODE, T, 8 * T, r=[[30.0]]).gains
    np.testing.assert_array_equal(implemented_loop_matrix(MODE, gains, T, 8),
                                  implemented_loop_matrix(MODE, gains, T, 8,
                                                          plant_delay_steps=8))  # fmt: skip


def test_band_stable_feedback_takes_the_most_aggressive_weight_stable_everywhere():
    band = [[ModalParameters(18.0 * f, 1.0e6, 0.05)] for f in (0.95, 1.0, 1.05)]
    grid = np.logspace(-1, 3, 9)
    delays = (0.024, 0.032, 0.040, 0.048)
    r, gains, worst = band_stable_feedback([band], [MODE], T, 0.032, delays, r_grid=grid)
    assert max(worst) < 1.0

    def worst_radius(rr):
        g = design_delay_aware_lqr(MODE, T, 0.032, r=[[rr]]).gains
        return max(spectral_radius(implemented_loop_matrix(p, g, T, 8, plant_delay_steps=d))
                   for p in band for d in (6, 8, 10, 12))  # fmt: skip

    assert worst_radius(r) < 1.0
    smaller = grid[grid < r]
    assert smaller.size and worst_radius(smaller.max()) >= 1.0  # the next one is not stable
    np.testing.assert_allclose(gains[0], design_delay_aware_lqr(MODE, T, 0.032, r=[[r]]).gains)


class _NoForceModel:
    """A flat workspace model whose X mode makes the force model amplify (left out)."""

    input_names = ("x_mm", "y_mm", "rz_deg")

    def modes(self, X):
        m = ModalParameters(18.0, 1.0e6, 0.05)
        pm = PoseMode(m, 0.2, 2e4, 0.05 * m.damping_ns_per_m, False, None)
        return [{"x": pm, "z": pm} for _ in np.atleast_2d(X)]


def test_new_files_feed_back_the_axes_without_a_force_model_and_older_files_do_not(tmp_path):
    path = ControlPath.through(_NoForceModel.input_names, [[2350, 500, 30], [2350, -200, 100]])
    doc = design_controller(_NoForceModel(), path, "adaptive+force", spindle_rpm=125.0)
    fed = set(doc["gains"].get("feedback", {}))
    kept = set(doc["gains"]["force_model_r"])
    assert fed and not fed & kept  # the feedback goes exactly where no force model is
    assert max(max(v) for v in doc["stability"]["feedback_worst_spectral_radius"].values()) < 1
    assert doc["stability"]["feedback_actuator_gains"] == [0.8, 0.9, 1.0, 1.1, 1.2]
    assert "stability.feedback_actuator_gains" in doc["units"]
    f = tmp_path / "v3.json"
    f.write_text(json.dumps(doc))
    parts = load_controller(f)._inner.inner.parts
    fb = [p for p in parts if isinstance(p, DelayAwareFeedback) and p.gains]
    assert len(fb) == 1 and {("x", "y", "z")[a] for a in fb[0].gains} == fed
    old = json.loads(json.dumps(doc))
    old["format_version"] = 2
    del old["gains"]["feedback"]
    f2 = tmp_path / "v2.json"
    f2.write_text(json.dumps(old))
    parts = load_controller(f2)._inner.inner.parts
    assert not any(isinstance(p, DelayAwareFeedback) and p.gains for p in parts)


@pytest.fixture(scope="module")
def _feedback_doc():
    path = ControlPath.through(_NoForceModel.input_names, [[2350, 500, 30], [2350, -200, 100]])
    return design_controller(_NoForceModel(), path, "adaptive+force", spindle_rpm=125.0)


def _edited(doc, tmp_path, edit):
    d = json.loads(json.dumps(doc))
    edit(d)
    f = tmp_path / "edited.json"
    f.write_text(json.dumps(d))
    return f


def _first_feedback_direction(d):
    return next(iter(d["gains"]["feedback"]))


@pytest.mark.parametrize(
    ("label", "edit", "match"),
    [
        ("a row short", lambda d: d["gains"]["feedback"][_first_feedback_direction(d)].pop(),
         r"gains\.feedback\.\w must be \d+ rows"),
        ("a gain short", lambda d: [r.pop() for r in d["gains"]["feedback"][
            _first_feedback_direction(d)]], r"x 10 gains \(2 \+ delay"),
        ("NaN", lambda d: d["gains"]["feedback"][_first_feedback_direction(d)][2].__setitem__(
            0, float("nan")), "non-finite"),
        ("both", lambda d: d["gains"]["force_model_r"].__setitem__(
            _first_feedback_direction(d), 10.0), "both a force model"),
        ("string bool", lambda d: d["learner"].__setitem__("pool_loop_phase", "false"),
         r"learner\.pool_loop_phase must be true or false"),
    ],
)  # fmt: skip
def test_a_malformed_feedback_or_learner_switch_is_refused_naming_it(
    _feedback_doc, tmp_path, label, edit, match
):
    assert "feedback" in _feedback_doc["gains"]
    with pytest.raises(ValueError, match=match):
        load_controller(_edited(_feedback_doc, tmp_path, edit))


def test_replay_of_a_simulated_record_reproduces_a_feedback_files_closed_loop_commands(
    _feedback_doc, tmp_path
):
    """The feedback acts on the measured tracker, so replay must rebuild its loop exactly."""
    from robovib.control.controller_file import write_controller_file
    from robovib.control.cut_replay import replay
    from robovib.io import read_milling_record_csv
    from robovib.milling.forces import ACETAL, CuttingConditions, MillingTool
    from robovib.sim import LinearMove, VirtualRobot, run_closed_loop
    from robovib.sim.disturbances import REALISTIC_LEVELS

    path = write_controller_file(tmp_path / "ctl.json", _feedback_doc)
    ctl = load_controller(path)
    fed = [("x", "y", "z").index(d) for d in _feedback_doc["gains"]["feedback"]]
    tool, cond = MillingTool(), CuttingConditions(125.0, 0.3e-3, 3e-3, 6e-3)
    t = np.arange(1500) / 1000.0
    local = REALISTIC_LEVELS.cutting_force(t, tool, cond, ACETAL, rng=np.random.default_rng(3))
    force = np.column_stack([local[:, 1], -local[:, 0], local[:, 2]])
    move = LinearMove("workspace", (2.35, 0.30, 50.0), (2.35, 0.25, 55.0))
    planned = ctl.planned(125.0, tool.n_flutes)
    rec = run_closed_loop(VirtualRobot(), move, force, 1000.0, planned, rng=5,
                          force_noise_n=2.0, force_bias_n=5.0)  # fmt: skip
    assert np.max(np.abs(planned.commands_mm[:, fed])) > 1e-4  # the feedback axes moved
    rec.to_csv(tmp_path / "cut.csv", digits=17)
    again = replay(load_controller(path), read_milling_record_csv(tmp_path / "cut.csv"),
                   spindle_rpm=125.0)  # fmt: skip
    np.testing.assert_allclose(again.commands_mm, planned.commands_mm, rtol=0, atol=1e-9)


def test_cli_design_says_which_axes_got_the_feedback_and_what_it_was_checked_over(tmp_path):
    from typer.testing import CliRunner

    from robovib.cli import app

    ctl = tmp_path / "ctl.json"
    res = CliRunner().invoke(app, ["control", "design", "--start", "2350,400,30", "--end",
                                   "2350,0,80", "--points", "7", "--controller",
                                   "adaptive+force", "-o", str(ctl)])  # fmt: skip
    assert res.exit_code == 0, res.output
    st = json.loads(ctl.read_text())["stability"]
    assert st["feedback_r"]  # this line's force model amplifies somewhere: a feedback instead
    for d, r in st["feedback_r"].items():
        worst = max(st["feedback_worst_spectral_radius"][d])
        assert (f"feedback ({d}): delay-aware LQR, R = {r:.3g}, worst spectral radius "
                f"{worst:.3f} (stable over the band, true delays 16-48 ms, actuator gain "
                "0.8-1.2)") in res.output  # fmt: skip


def test_an_axis_with_neither_force_model_nor_stable_feedback_is_reported(monkeypatch):
    # No weight stable over the band: the axis keeps only its learners, and the design says so
    # (it used to drop the feedback silently).
    import robovib.control.controller_file as controller_file

    monkeypatch.setattr(controller_file, "band_stable_feedback", lambda *a, **k: None)
    path = ControlPath.through(_NoForceModel.input_names, [[2350, 500, 30], [2350, -200, 100]])
    with pytest.warns(RuntimeWarning, match="no feedback weight is stable") as record:
        doc = design_controller(_NoForceModel(), path, "adaptive+force", spindle_rpm=125.0)
    assert not doc["gains"].get("feedback")
    warned = {str(w.message).split("axis ")[1][0] for w in record if "axis" in str(w.message)}
    assert warned == {"x", "z"} - set(doc["gains"]["force_model_r"])
