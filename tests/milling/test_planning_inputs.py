"""choose_configurations and fixed_configuration refuse bad tables with the problem named
(fixed_configuration took any depth rule but 'segment' as 'path', and NaN depths, silently)."""

import numpy as np
import pytest

from robovib.milling.planning import choose_configurations, fixed_configuration

ALLOWED = np.full((3, 2, 4), 2e-3)
RZ, RPM, LENGTH = np.array([0.0, 45.0]), np.array([1000.0, 1500.0, 2000.0, 2500.0]), np.ones(3)
P_AT = np.full(ALLOWED.shape, 0.99)


@pytest.mark.parametrize(
    ("change", "match"),
    [
        ({"allowed_m": ALLOWED[:, :1]}, "allowed_m must be"),
        ({"allowed_m": np.where(ALLOWED > 0, np.nan, 0)}, "allowed_m must be depths"),
        ({"length_mm": np.ones(2)}, "length_mm must be"),
        ({"length_mm": np.array([1.0, 0.0, 1.0])}, "segment lengths > 0"),
        ({"spindle_rpm": np.array([1000.0, np.nan, 2000.0, 2500.0])}, "spindle_rpm"),
        ({"spindle_rpm": -RPM}, "spindle_rpm"),
        ({"rz_deg": np.array([0.0, np.inf])}, "rz_deg"),
        ({"depth_rule": "layer"}, "depth_rule must be 'segment' or 'path', got 'layer'"),
        ({"p_required": 1.0}, "p_required"),
        ({"depth_m": 1e-3, "p_stable_at_depth": None}, "needs p_stable_at_depth"),
        ({"depth_m": -1e-3, "p_stable_at_depth": P_AT}, "depth_m must be"),
        ({"depth_m": 1e-3, "p_stable_at_depth": P_AT[:2]}, "p_stable_at_depth must be"),
        ({"depth_m": 1e-3, "p_stable_at_depth": P_AT * np.nan}, "probabilities"),
    ],
)
def test_bad_tables_are_refused(change, match):
    kw = {"allowed_m": ALLOWED, "rz_deg": RZ, "spindle_rpm": RPM, "length_mm": LENGTH, **change}
    args = [kw.pop(k) for k in ("allowed_m", "rz_deg", "spindle_rpm", "length_mm")]
    with pytest.raises(ValueError, match=match):
        fixed_configuration(*args, **kw)
    with pytest.raises(ValueError, match=match):
        choose_configurations(*args, max_rz_rate_deg_per_mm=1.0, **kw)


def test_a_negative_rz_rate_is_refused():
    with pytest.raises(ValueError, match="max_rz_rate_deg_per_mm"):
        choose_configurations(ALLOWED, RZ, RPM, LENGTH, max_rz_rate_deg_per_mm=-1.0)


def test_good_tables_still_plan():
    # fastest speed, same depth everywhere: the closed-form answer
    choice = choose_configurations(ALLOWED, RZ, RPM, LENGTH, max_rz_rate_deg_per_mm=1.0)
    assert np.all(RPM[choice.speed_index] == 2500.0)
    assert choice.score == pytest.approx(2e-3 * 2500.0)
    assert fixed_configuration(ALLOWED, RZ, RPM, LENGTH)["spindle_rpm"] == 2500.0
