"""Report of a cut plan along a tool path (issue 39): ``robovib mill plan --report``."""

from __future__ import annotations

__all__ = ["plan_report"]


def plan_report(plan, update=None, provenance=None):
    """An HTML report (:mod:`robovib.report`) of a plan: the table, the figure, the comparison.

    Parameters
    ----------
    plan : PathPlan
        The plan.
    update : CutUpdate, optional
        The test cuts that updated the forecast (how far they moved it).
    provenance : dict, optional
        Inputs and versions.

    Returns
    -------
    robovib.report.Report
    """
    from ..milling.planning import plot_path_plan
    from .kinds import result_report

    fixed = plan.fixed
    paras = [
        f"Mean MRR along the path {plan.mean_mrr_m3_per_s * 1e9:.1f} mm³/s at P(stable) >= "
        f"{plan.settings['p_required']:g}; best single fixed Rz {fixed['rz_deg']:g}° and speed "
        f"{fixed['spindle_rpm']:g} rpm: {fixed['mean_mrr_mm3_per_s']:.1f} mm³/s ({fixed['rule']}).",
    ]
    if "one_depth" in fixed:
        one = fixed["one_depth"]
        paras.append(
            f"One Rz, speed and depth for the whole path: {one['depth_mm']:.2f} mm at "
            f"{one['rz_deg']:g}°, {one['spindle_rpm']:g} rpm: {one['mean_mrr_mm3_per_s']:.1f} mm³/s."
        )
    if update is not None:
        d = update.to_dict()
        paras.append(
            f"{d['n_cuts']} test cuts (label noise {d['label_noise']:g}) moved the forecast: "
            f"effective sample size {d['effective_sample_size_prior']:.0f} -> "
            f"{d['effective_sample_size']:.1f}, information {d['information_nats']:.2f} nats, "
            f"median limit at the cuts {100 * d['median_limit_shift_rel']:+.0f} %."
        )
    return result_report(
        "Cut plan along the tool path", plan,
        figures=[("Path coloured by the allowed depth; Rz and speed along it", plot_path_plan(plan))],
        paragraphs=paras, settings=plan.settings, provenance=provenance,
    )  # fmt: skip
