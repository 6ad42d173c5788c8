"""A damaged multi-mode table is refused or named, with file, line and column (issue 38 item 5)."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from robovib.campaign import fit_multimode_pose_model
from robovib.campaign.quality import ModelQualityWarning
from robovib.campaign.table_checks import check_modes_table
from robovib.sim import VirtualRobot

COLUMNS = ["row", "direction", "x_mm", "y_mm", "rz_deg", "fn_hz", "stiffness_n_per_m",
           "damping_ns_per_m", "mode_id"]  # fmt: skip


def _modes_table(n=24, rng=2) -> pd.DataFrame:
    """Two X modes of the virtual robot (its dominant and secondary) at ``n`` poses, tracked:
    one line per (recording, mode), recording ``row`` = its manifest row, 1 % scatter."""
    gen = np.random.default_rng(rng)
    poses = np.column_stack([gen.uniform(2100, 2550, n), gen.uniform(-300, 600, n),
                             gen.uniform(0, 180, n)])  # fmt: skip
    ms = VirtualRobot().workspace.modes(
        np.column_stack([poses[:, :2] / 1e3, poses[:, 2]]), "x"
    )  # fmt: skip
    rows = []
    for i, p in enumerate(poses):
        for j in range(2):  # the usual X mode and its weak secondary mode (2.6 fn, 10 k)
            fn, k, z = ms.fn_hz[i, j], ms.stiffness_n_per_m[i, j], ms.damping_ratio[i, j]
            e = 1 + 0.01 * gen.standard_normal(3)
            rows.append([i + 2, "x", *p, fn * e[0], k * e[1], 2 * z * k / (2 * np.pi * fn) * e[2],
                         f"x{j + 1}"])  # fmt: skip
    return pd.DataFrame(rows, columns=COLUMNS)


def _write(table, path):
    table.to_csv(path, index=False)
    return path


def _line(table, i) -> int:
    """File line of DataFrame row ``i`` in the CSV written by :func:`_write` (header: line 1)."""
    return int(i) + 2


def test_a_clean_table_passes_unchanged():
    table = _modes_table()
    check = check_modes_table(table, source="modes.csv")
    assert check.warnings == ()
    assert len(check.table) == len(table)


def test_a_table_without_the_row_column_names_it():
    with pytest.raises(ValueError, match=r"modes\.csv: no column row \(the recording key"):
        check_modes_table(_modes_table().drop(columns="row"), source="modes.csv")


def test_blank_mode_ids_are_named_and_left_out(tmp_path):
    table = _modes_table()
    table.loc[[3, 10], "mode_id"] = ""
    path = _write(table, tmp_path / "modes.csv")
    check = check_modes_table(pd.read_csv(path, keep_default_na=False), source=str(path))
    (w,) = check.warnings
    assert f"{path} lines {_line(table, 3)}, {_line(table, 10)}: blank mode_id" in w
    assert len(check.table) == len(table) - 2


def test_conflicting_duplicates_are_refused_identical_ones_counted_once():
    table = _modes_table()
    copy = table.iloc[[4]].copy()
    same = check_modes_table(pd.concat([table, copy], ignore_index=True), source="m.csv")
    assert len(same.table) == len(table) and "counted once" in same.warnings[0]
    copy["stiffness_n_per_m"] *= 1.2
    damaged = pd.concat([table, copy], ignore_index=True)
    with pytest.raises(ValueError, match=r"m\.csv lines 6, \d+: row \d+, mode_id x1 appears "
                       r"twice with different stiffness_n_per_m \(column stiffness_n_per_m\)"):  # fmt: skip
        check_modes_table(damaged, source="m.csv")


def test_crossed_labels_are_refused_with_the_lines_of_the_smaller_cluster():
    table = _modes_table()
    swapped = table.copy()
    recs = swapped["row"].unique()[::3]  # a third of the recordings: x1 and x2 swapped
    sel = swapped["row"].isin(recs)
    swapped.loc[sel, "mode_id"] = swapped.loc[sel, "mode_id"].map({"x1": "x2", "x2": "x1"})
    with pytest.raises(ValueError, match="crossed labels") as exc:
        check_modes_table(swapped, source="modes.csv")
    msg = str(exc.value)
    assert "column mode_id" in msg
    first = int(np.flatnonzero(sel & (swapped["mode_id"] == "x1").to_numpy())[0])
    assert f"modes.csv lines {_line(swapped, first)}," in msg


@pytest.mark.parametrize(
    ("column", "value", "factor"),
    [("fn_hz", 1e6, None), ("stiffness_n_per_m", None, 1e3), ("damping_ns_per_m", None, 1e-3)],
)
def test_an_outlier_against_the_modes_own_spread_is_refused(column, value, factor):
    table = _modes_table()
    i = 8
    table.loc[i, column] = value if value is not None else table.loc[i, column] * factor
    with pytest.raises(ValueError, match=rf"modes\.csv line {_line(table, i)} column {column}: "
                       r".* is an outlier of mode x1"):  # fmt: skip
        check_modes_table(table, source="modes.csv")


def test_non_physical_values_name_line_and_column():
    table = _modes_table()
    table.loc[5, "fn_hz"] = -3.0
    with pytest.raises(ValueError, match=r"m\.csv line 7 column fn_hz: -3\.0 is not a finite"):
        check_modes_table(table, source="m.csv")


def test_the_multimode_fit_names_every_mode_left_out(tmp_path):
    table = _modes_table(n=16)
    extra = table[table["mode_id"] == "x2"].head(2).copy()
    extra["fn_hz"] *= 1.8
    extra["mode_id"] = "x3"  # a third mode seen at 2 of 16 recordings
    path = _write(pd.concat([table, extra], ignore_index=True), tmp_path / "modes.csv")
    with pytest.warns(ModelQualityWarning, match=r"mode x3 left out of the model: seen at 2 of "
                      r"16 recordings \(12 %\), below min_presence 0\.5"):  # fmt: skip
        fit = fit_multimode_pose_model(path, n_folds=3)
    assert any("mode x3 left out" in w for w in fit.warnings)
    assert fit.model.directions_ == ("x1", "x2")


def test_the_multimode_fit_refuses_an_outlier_before_fitting(tmp_path):
    table = _modes_table(n=16)
    table.loc[6, "fn_hz"] = 1e6
    path = _write(table, tmp_path / "modes.csv")
    with pytest.raises(ValueError, match=rf"{tmp_path / 'modes.csv'} line 8 column fn_hz"):
        fit_multimode_pose_model(path, n_folds=3)


def test_a_gross_outlier_of_a_dominant_mode_table_is_refused_a_mode_switch_is_not(tmp_path):
    from robovib.campaign import fit_pose_model_from_table
    from robovib.campaign.table_checks import check_modal_table

    table = _modes_table(n=20)
    modal = table[table["mode_id"] == "x1"].drop(columns="mode_id").reset_index(drop=True)
    switched = modal.copy()
    switched.loc[[3, 4], "fn_hz"] = 63.5  # the ~63 Hz X mode dominating at 2 poses: 3-4x
    check_modal_table(switched, source="modal.csv")  # passes
    modal.loc[11, "fn_hz"] = 1e6
    path = _write(modal, tmp_path / "modal.csv")
    with pytest.raises(ValueError, match=rf"{tmp_path / 'modal.csv'} line 13 column fn_hz: "
                       r"1e\+06 is an outlier of direction x"):  # fmt: skip
        fit_pose_model_from_table(path)


def test_gpr_predict_never_prints_a_negative_frequency(tmp_path):
    """A model fitted past the checks (1e6 Hz kept) predicts fn < 0 at ordinary poses; the
    command refuses to print it."""
    from typer.testing import CliRunner

    from robovib.cli import app
    from robovib.gp import PoseModalModel

    t = _modes_table(n=20)
    t = t[t["mode_id"] == "x1"].reset_index(drop=True)
    t.loc[6, "fn_hz"] = 1e6
    X = t[["x_mm", "y_mm", "rz_deg"]].to_numpy()
    Y = t[["fn_hz", "stiffness_n_per_m", "damping_ns_per_m"]].to_numpy()
    model = PoseModalModel(directions=("x",), mode_switch=False).fit(X, Y)
    gen = np.random.default_rng(0)
    query = np.column_stack([gen.uniform(2100, 2550, 400), gen.uniform(-300, 600, 400),
                             gen.uniform(0, 180, 400)])  # fmt: skip
    fn = model.predict(query)[:, 0]
    assert np.any(fn < 0)  # the degraded model this guards against
    pose = query[int(np.argmin(fn))]
    path = model.save(tmp_path / "m.h5")
    res = CliRunner().invoke(app, ["gpr", "predict", "--model", str(path), "--x", str(pose[0]),
                                   "--y", str(pose[1]), "--rz", str(pose[2])])  # fmt: skip
    assert res.exit_code == 1
    assert "x_fn_hz = -" in res.output and "not a physical mode" in res.output


def test_a_dominant_table_with_one_recording_twice_is_refused():
    from robovib.campaign.table_checks import check_modal_table

    modal = _modes_table(n=12)
    modal = modal[modal["mode_id"] == "x1"].drop(columns="mode_id").reset_index(drop=True)
    copy = modal.iloc[[2]].assign(fn_hz=lambda t: t["fn_hz"] * 1.05)
    with pytest.raises(
        ValueError, match=r"modal\.csv lines 4, 14: row 4, direction x appears twice"
    ):
        check_modal_table(pd.concat([modal, copy], ignore_index=True), source="modal.csv")
    check_modal_table(pd.concat([modal, modal.iloc[[2]]], ignore_index=True))  # identical: fine
