"""Thesis Table 9: LQR gains from the Table 8 predictions under each plant formulation (§4.3).

The gains are computed by :func:`robovib.control.design_lqr` from the modal parameters the
thesis printed in Table 8 and set beside the gains it printed in Table 9.
"""

from __future__ import annotations

from dataclasses import dataclass

import pandas as pd

from ..control.lqr import design_lqr
from ..datasets import load_reference_table
from ..modal.parameters import ModalParameters

__all__ = ["Table9Comparison", "table_9_comparison"]


@dataclass(frozen=True)
class Table9Comparison:
    """Gains per (formulation, input, position, direction) beside the thesis' Table 9.

    Attributes
    ----------
    rows
        One dict per gain pair: ``formulation, input, position, direction, w1, w2, thesis_w1,
        thesis_w2`` (``w1`` on displacement [input unit/m], ``w2`` on velocity [input unit·s/m]).
    period_s
        Control period [s].
    """

    rows: tuple[dict, ...]
    period_s: float

    def to_frame(self) -> pd.DataFrame:
        """One row per gain pair.

        Returns
        -------
        pandas.DataFrame
            The comparison.
        """
        return pd.DataFrame(list(self.rows))

    def to_dict(self) -> dict:
        """JSON-ready: settings and rows.

        Returns
        -------
        dict
            The comparison as plain JSON types.
        """
        return {"period_s": self.period_s, "rows": [dict(r) for r in self.rows]}


def table_9_comparison(period_s: float = 0.004) -> Table9Comparison:
    """Gains from the thesis' Table 8 predictions under each formulation, beside Table 9.

    Parameters
    ----------
    period_s
        Control period [s] (thesis: 4 ms).

    Returns
    -------
    Table9Comparison
    """
    t8 = load_reference_table(8)
    t9 = load_reference_table(9).set_index("position")
    rows = []
    for form, inp in (
        ("physical", "displacement"),
        ("physical", "force"),
        ("thesis_printed", "force"),
    ):
        for _, row in t8[t8["kind"] == "predicted"].iterrows():
            pos = int(row["position"])
            for d in ("x", "z"):
                mode = ModalParameters(
                    row[f"fn_{d}_hz"],
                    row[f"stiffness_{d}_mn_per_m"] * 1e6,
                    row[f"damping_ratio_{d}"],
                )
                w = design_lqr(mode, period_s, input=inp, formulation=form).gains
                rows.append({
                    "formulation": form, "input": inp, "position": pos, "direction": d,
                    "w1": float(w[0]), "w2": float(w[1]),
                    "thesis_w1": float(t9.loc[pos, f"w1_{d}"]), "thesis_w2": float(t9.loc[pos, f"w2_{d}"]),
                })  # fmt: skip
    return Table9Comparison(tuple(rows), float(period_s))
