"""``robovib demo``: the chapter-3 study on the shipped thesis data."""

from __future__ import annotations

from typing import Annotated

import typer

from ._common import (
    JsonFlag,
    KernelOpt,
    ModeSwitchOpt,
    SeedOpt,
    Table,
    check_kernel,
    console,
    emit_json,
    escape,
)


def _table(title: str, columns, rows) -> Table:
    t = Table(title=title)
    for col in columns:
        t.add_column(col, justify="right")
    for row in rows:
        t.add_row(*row)
    return t


def demo(
    kernel: KernelOpt = "ard",
    seed: SeedOpt = 0,
    printed_stiffness: Annotated[
        bool,
        typer.Option(
            help="Use Table A1's stiffness cells as printed (tests 59-60 shifted) instead of the corrected reading."
        ),
    ] = False,
    mode_switch: ModeSwitchOpt = True,
    json_out: JsonFlag = False,
) -> None:
    """Chapter-3 study on the shipped thesis data: GPR vs thesis Table 2, MLR, external validation."""
    from ..studies.chapter3 import chapter3_study

    s = chapter3_study(
        kernel=check_kernel(kernel),
        stiffness_reading="printed" if printed_stiffness else "corrected",
        mode_switch=mode_switch,
        rng=seed,
    )
    if json_out:
        frame = s.to_frame()
        emit_json(
            {
                "study_settings": s.settings,
                "outputs": frame.reset_index(names="output").to_dict(orient="records"),
            }
        )
        return
    con = console()
    variant = "X-mode switch classified" if mode_switch else "one GP per output"
    names = [escape(n) for n in s.outputs]
    con.print(
        _table(
            f"5-fold CV of the modal-parameter GPR on Table A1 (kernel={kernel}, {variant}, seed={seed})",
            ("output", "thesis GPR R²", "thesis RMSE", "plain CV R²", "plain RMSE",
             "grouped CV R²", "grouped RMSE"),
            [(n, f"{s.thesis_gpr_r2[i]:.2f}", f"{s.thesis_gpr_rmse[i]:.2f}",
              f"{s.gpr_plain_r2[i]:.2f}", f"{s.gpr_plain_rmse[i]:.2f}",
              f"{s.gpr_grouped_r2[i]:.2f}", f"{s.gpr_grouped_rmse[i]:.2f}")
             for i, n in enumerate(names)],
        )
    )  # fmt: skip
    con.print(
        "plain CV = the thesis' protocol (replicates of a test pose stay in training); "
        "grouped CV = all replicates of a pose held out together (prediction at unseen poses)."
    )
    con.print(
        _table(
            "2nd-order MLR baseline",
            ("output", "thesis MLR R²", "thesis RMSE", "in-sample R²", "in-sample RMSE",
             "5-fold CV R²", "CV RMSE"),
            [(n, f"{s.thesis_mlr_r2[i]:.2f}", f"{s.thesis_mlr_rmse[i]:.2f}",
              f"{s.mlr_insample_r2[i]:.2f}", f"{s.mlr_insample_rmse[i]:.2f}",
              f"{s.mlr_cv_r2[i]:.2f}", f"{s.mlr_cv_rmse[i]:.2f}")
             for i, n in enumerate(names)],
        )
    )  # fmt: skip
    con.print(
        _table(
            "External validation on Table A2 (30 unseen poses), GPR fitted on all of Table A1",
            ("output", "RMSE", "mean rel. error", "max rel. error"),
            [(n, f"{s.external_rmse[i]:.3f}", f"{100 * s.external_mean_relative_error[i]:.1f} %",
              f"{100 * s.external_max_relative_error[i]:.1f} %")
             for i, n in enumerate(names)],
        )
    )  # fmt: skip
