"""Loud model quality: a named warning for every output the pose model explains poorly.

``robovib model fit`` used to print the grouped-CV table and nothing else: an X natural
frequency with R² = -0.2 went by without a word (issue 36). :func:`model_quality_warnings`
names every output whose grouped-CV R² is below :data:`MIN_R2` and, where it can see the
cause in the training data, says it:

* a second cluster of the direction's natural frequency at a few poses (the test of
  :func:`robovib.gp.detect_mode_switch`, rules 1-3, passed by a cluster of fewer than
  :data:`MIN_MODE_POSES` poses) is a mode switch the campaign saw too rarely to model its
  field: the high mode there is a constant with a wide band, and held-out poses of it cannot
  be predicted. The cure is more poses there, or every mode (``campaign process --modes-band``)
  instead of the dominant one.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "MIN_MODE_POSES",
    "MIN_R2",
    "MIN_RELATIVE_RMSE_PCT",
    "ModelQualityWarning",
    "model_quality_warnings",
    "nonphysical_outputs",
]

#: Grouped-CV R² below which an output is named.
MIN_R2 = 0.5
#: Relative grouped-CV RMSE [%] below which an output is not named whatever its R²: an
#: output that hardly varies over the poses (a constant mode at 63.5 +- 0.01 Hz) has a
#: meaningless R² but a prediction as good as its measurements (read to ~0.5 %).
MIN_RELATIVE_RMSE_PCT = 1.0
#: Poses of a mode below which its field over the pose cannot be modelled.
MIN_MODE_POSES = 3


class ModelQualityWarning(UserWarning):
    """A pose model that explains an output poorly, or a table entry left out of the fit."""


def _pose_text(names, row) -> str:
    return ", ".join(f"{n.rsplit('_', 1)[0]}={v:g}" for n, v in zip(names, row, strict=True))


def _rare_second_mode(model, direction: str) -> str | None:
    """The cause text where ``direction``'s fn has a second cluster at a few poses, else None."""
    from ..gp.mode_switch import detect_mode_switch

    names = tuple(model.output_names_)
    col = f"{direction}_fn_hz"
    if col not in names:
        return None
    j = names.index(col)
    seen = np.asarray(model.mask_[:, j], bool) & np.isfinite(model.Y_train_[:, j])
    fn, X = np.asarray(model.Y_train_[seen, j], float), np.asarray(model.X_train_[seen], float)
    if fn.size == 0 or np.any(fn <= 0):
        return None
    det = detect_mode_switch(fn, direction=direction)
    if det.found:
        thr = det.threshold_hz
    elif det.reason.startswith("the low mode has fewer"):  # the small cluster is the low one
        order = np.sort(np.log(fn))
        gaps = np.diff(order)
        thr = float(np.exp(order[np.argmax(gaps)] + gaps.max() / 2))
    else:
        return None
    high, low = fn > thr, fn <= thr
    rare = (
        high if np.unique(X[high], axis=0).shape[0] <= np.unique(X[low], axis=0).shape[0] else low
    )
    poses = np.unique(np.round(X[rare], 9), axis=0)
    if poses.shape[0] >= MIN_MODE_POSES:
        return None
    where = "; ".join(_pose_text(model.input_names_, p) for p in poses)
    fns = ", ".join(f"{v:.3g}" for v in np.unique(np.round(fn[rare], 1)))
    n = poses.shape[0]
    return (
        f"a mode switch seen at {n} pose{'s' if n != 1 else ''} ({where}: {fns} Hz): too few to "
        "model; use `campaign process --modes-band` or measure more poses there"
    )


def model_quality_warnings(model, cv_table, *, min_r2: float = MIN_R2) -> list[str]:
    """One line per output whose grouped-CV R² is below ``min_r2``, with its cause if seen.

    Outputs predicted to better than :data:`MIN_RELATIVE_RMSE_PCT` (relative RMSE) are not
    named: their R² is low only because they hardly vary.

    Parameters
    ----------
    model : PoseModalModel
        The fitted pose model (``output_names_``, ``directions_``, ``X_train_``, ``Y_train_``,
        ``mask_``, ``input_names_``).
    cv_table : pandas.DataFrame
        Its grouped-CV table (columns ``output`` and ``r2``,
        :func:`robovib.campaign.fit_pose_model_from_table`).
    min_r2 : float
        The R² below which an output is named.

    Returns
    -------
    list of str
        The warnings (empty: every output explained to ``min_r2``).

    Examples
    --------
    >>> import numpy as np, pandas as pd
    >>> from robovib.campaign.quality import model_quality_warnings
    >>> from robovib.gp import PoseModalModel
    >>> x = np.linspace(0.0, 1.0, 12)
    >>> model = PoseModalModel(("x_m",), ("x",), mode_switch=False).fit(
    ...     x, np.column_stack([20 + x, 3e6 + 1e5 * x, 7e3 - 1e2 * x]))
    >>> model_quality_warnings(model, pd.DataFrame({"output": ["x_fn_hz"], "r2": [0.2]}))
    ['x_fn_hz: grouped-CV R² = 0.20 < 0.5: the model explains little of it between poses']
    """
    causes: dict[str, str | None] = {}
    out = []
    for r in cv_table.to_dict(orient="records"):
        r2 = float(r["r2"])
        if not (np.isfinite(r2) and r2 < min_r2):
            continue
        rel = float(r.get("relative_rmse_pct", np.inf))
        if np.isfinite(rel) and abs(rel) < MIN_RELATIVE_RMSE_PCT:
            continue
        name = str(r["output"])
        d = next((d for d in model.directions_ if name.startswith(f"{d}_")), None)
        if d is not None and d not in causes:
            causes[d] = _rare_second_mode(model, d)
        cause = causes.get(d)
        out.append(
            f"{name}: grouped-CV R² = {r2:.2f} < {min_r2:g}: "
            + (cause if cause else "the model explains little of it between poses")
        )
    return out


def nonphysical_outputs(output_names, means) -> list[str]:
    """The predicted outputs no mode can have: fn or k <= 0, c < 0 (one line each).

    A smooth GP over a table with a gross outlier, or far from its data, can predict a
    negative frequency (issue 38: fn = -26 449 Hz at an ordinary pose); such a prediction is
    refused, not printed.

    Parameters
    ----------
    output_names : sequence of str
        Output names with their unit suffix (``x_fn_hz``, ``x_stiffness_n_per_m``, ...).
    means : sequence of float
        The predicted values (SI).

    Returns
    -------
    list of str
        ``"x_fn_hz = -2.645e+04"`` per non-physical output (empty: all physical).

    Examples
    --------
    >>> from robovib.campaign.quality import nonphysical_outputs
    >>> nonphysical_outputs(["x_fn_hz", "x_damping_ns_per_m"], [-26449.0, 10.0])
    ['x_fn_hz = -2.645e+04']
    """
    out = []
    for name, m in zip(output_names, means, strict=True):
        m = float(m)
        positive = name.endswith(("_fn_hz", "_stiffness_n_per_m"))
        bad = not np.isfinite(m) or (m <= 0 if positive else name.endswith("_ns_per_m") and m < 0)
        if bad:
            out.append(f"{name} = {m:.4g}")
    return out
