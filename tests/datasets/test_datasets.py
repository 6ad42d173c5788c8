"""Table parsing checked against cells read off the thesis text by hand."""

import numpy as np
import pytest

from robovib.datasets import (
    load_reference_table,
    load_table_a1,
    load_table_a2,
    modal_output_columns,
    pose_columns,
)


def test_table_a1_shape_and_poses():
    a1 = load_table_a1(units="thesis")
    assert len(a1) == 180
    assert a1["test"].nunique() == 60
    assert (a1.groupby("test").size() == 3).all()
    # 12 XY points x 5 Rz angles; replicates inherit the pose of their first row.
    assert a1[["x_mm", "y_mm"]].drop_duplicates().shape[0] == 12
    assert sorted(a1["rz_deg"].unique()) == [0, 45, 90, 135, 180]
    assert (a1.groupby("test")[["x_mm", "y_mm", "rz_deg"]].nunique() == 1).all().all()
    assert (a1["z_mm"] == 325).all()


@pytest.mark.parametrize(
    ("test", "rep", "column", "value"),
    [
        (1, 2, "damping_y_kns_per_m", 10.30),
        (28, 2, "fn_z_hz", 10.47),  # the row after a page break
        (43, 3, "fn_z_hz", 9.50),  # another page break inside a test
        (41, 1, "fn_x_hz", 64.00),
        (59, 1, "damping_x_kns_per_m", 9.45),  # first row after the break between 58 and 59
        (45, 1, "fn_x_hz", 61.87),
    ],
)
def test_table_a1_cells(test, rep, column, value):
    a1 = load_table_a1(units="thesis", stiffness_reading="printed")
    row = a1[(a1["test"] == test) & (a1["replicate"] == rep)]
    assert row[column].item() == pytest.approx(value)


def test_table_a1_stiffness_shift_reading():
    printed = load_table_a1(units="thesis", stiffness_reading="printed")
    corrected = load_table_a1(units="thesis", stiffness_reading="corrected")
    flagged = corrected["stiffness_shift_flag"]
    assert flagged.sum() == 4
    assert set(corrected.loc[flagged, "test"]) == {59, 60}
    # Test 60 replicate 1 printed as (0.77, 0.98, 0.98): X missing, Y <- 0.77, Z = 0.98.
    row = corrected[(corrected["test"] == 60) & (corrected["replicate"] == 1)]
    assert np.isnan(row["stiffness_x_mn_per_m"].item())
    assert row["stiffness_y_mn_per_m"].item() == pytest.approx(0.77)
    assert row["stiffness_z_mn_per_m"].item() == pytest.approx(0.98)
    prow = printed[(printed["test"] == 60) & (printed["replicate"] == 1)]
    assert prow["stiffness_x_mn_per_m"].item() == pytest.approx(0.77)
    # Unflagged rows are untouched.
    cols = modal_output_columns("thesis")
    np.testing.assert_array_equal(
        printed.loc[~flagged, cols].to_numpy(), corrected.loc[~flagged, cols].to_numpy()
    )


def test_units_conversion():
    si = load_table_a1(units="si")
    th = load_table_a1(units="thesis")
    np.testing.assert_allclose(si["x_m"], th["x_mm"] / 1000)
    np.testing.assert_allclose(si["stiffness_z_n_per_m"], th["stiffness_z_mn_per_m"] * 1e6)
    np.testing.assert_allclose(si["damping_y_ns_per_m"], th["damping_y_kns_per_m"] * 1e3)
    assert pose_columns("si") == ["x_m", "y_m", "rz_deg"]
    with pytest.raises(ValueError, match="unknown units"):
        load_table_a1(units="imperial")


def test_high_mode_flag():
    a1 = load_table_a1()
    high = a1.loc[a1["x_high_mode"], "test"].unique()
    assert set(high) == {41, 45, 46, 50, 51, 55, 56, 60}
    assert (a1.loc[a1["x_high_mode"], "x_m"] == 2.7).all()


def test_table_a2():
    a2 = load_table_a2(units="thesis")
    assert len(a2) == 30
    row = a2[a2["test"] == 21]
    assert row["stiffness_x_mn_per_m"].item() == pytest.approx(5.98)
    assert row["x_mm"].item() == 2550 and row["y_mm"].item() == 150
    assert not a2["x_high_mode"].any()


def test_reference_tables():
    t2 = load_reference_table(2)
    assert len(t2) == 36
    sel = t2[(t2.model == "GPR") & (t2.metric == "rmse") & (t2.output == "fn_x")]
    assert sel["value"].item() == pytest.approx(3.31)
    t4 = load_reference_table(4)
    np.testing.assert_allclose(t4["stiffness_1e6_nm_per_rad"], [3.93, 3.46, 2.77, 1.57, 0.24, 0.17])
    t9 = load_reference_table(9)
    assert t9.loc[t9.position == 2, "w1_x"].item() == pytest.approx(0.11)
    t10 = load_reference_table(10)
    assert len(t10) == 64
    assert t10.query("test == 5 and position == 2 and direction == 'x' and loop == 'open'")[
        "rms_vibration_mm"
    ].item() == pytest.approx(0.401)
    t13 = load_reference_table(13)
    assert t13.loc[t13.method == "updating", "iterations_mean"].item() == 2078
    for n in (1, 3, 5, 6, 7, 8, 11, 12):
        assert len(load_reference_table(n)) > 0
    with pytest.raises(ValueError, match="no reference table"):
        load_reference_table(99)
