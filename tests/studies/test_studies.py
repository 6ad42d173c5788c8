"""Thesis reproductions in robovib.studies return frozen results with to_frame() / to_dict()."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from robovib.datasets import load_reference_table
from robovib.studies.analytical import compare_with_table_a1
from robovib.studies.table9 import table_9_comparison


def test_table9_result_is_frozen_and_serialisable():
    res = table_9_comparison()
    frame = res.to_frame()
    # 3 formulations x the predicted Table 8 positions x 2 directions, beside Table 9.
    t8 = load_reference_table(8)
    n = 3 * int((t8["kind"] == "predicted").sum()) * 2
    assert len(frame) == len(res.rows) == n
    assert {"w1", "w2", "thesis_w1", "thesis_w2"} <= set(frame.columns)
    doc = json.loads(json.dumps(res.to_dict()))
    assert doc["period_s"] == pytest.approx(0.004) and len(doc["rows"]) == n
    with pytest.raises(dataclasses.FrozenInstanceError):
        res.period_s = 1.0


def test_analytical_comparison_result():
    res = compare_with_table_a1()
    frame = res.to_frame()
    assert len(frame) == 60  # Table A1 poses
    # Relative error is analytical / measured - 1, recomputed from the two columns.
    np.testing.assert_allclose(
        frame["fn_x_rel_error"], frame["fn_x_analytical_hz"] / frame["fn_x_measured_hz"] - 1
    )
    doc = json.loads(json.dumps(res.to_dict()))
    assert set(doc["summary"]) == {f"{q}_{d}" for d in "xyz" for q in ("fn", "stiffness")}
    frame.loc[0, "fn_x_rel_error"] = 99.0  # a copy: the result itself is unchanged
    assert res.to_frame().loc[0, "fn_x_rel_error"] != 99.0
