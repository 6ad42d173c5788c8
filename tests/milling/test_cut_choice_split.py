"""Test cuts chosen under the process-factor split (a local factor drawn afresh at every cut and
point, issue 39's re-plan): ``choose_test_cuts`` and ``choose_forecast_cuts`` with
``local_factor`` against enumeration of the outcome patterns with the local factor integrated by
quadrature, SciPy's root finder and Monte-Carlo draws of rows, local factors and label noise."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from scipy import optimize

from robovib.milling.cut_posterior import choose_forecast_cuts, choose_test_cuts
from robovib.milling.factor_grid import local_p_stable, local_quantile, row_p_stable

LOCAL = (0.55, 1.3)
# midpoint quadrature of the log-uniform local factor (error <= 1 / N per probability)
RHO = np.exp(np.log(LOCAL[0]) + (np.arange(20_000) + 0.5) / 20_000 * np.log(LOCAL[1] / LOCAL[0]))


def _p_chatter(lim_r, depth):
    """P(rho a_r <= d) for each row, by quadrature over rho."""
    return np.mean(RHO[None, :] * np.asarray(lim_r, float)[:, None] <= depth, axis=1)


def _median_depth(lim_c, w):
    return optimize.brentq(lambda d: w @ _p_chatter(lim_c, d) - 0.5, 1e-6, 1.0, xtol=1e-12)


def _mutual_information(p_chat, w):
    """I(y; row) of independent cuts given the row, every outcome pattern enumerated.

    p_chat : (R, n) P(chatter | row) of the n cuts."""
    n = p_chat.shape[1]
    h_joint = 0.0
    for pattern in itertools.product([0, 1], repeat=n):
        y = np.array(pattern, bool)
        p = w @ np.prod(np.where(y, p_chat, 1 - p_chat), axis=1)
        h_joint -= p * np.log(p) if p > 0 else 0.0
    with np.errstate(divide="ignore", invalid="ignore"):
        h_row = -(np.where(p_chat > 0, p_chat * np.log(p_chat), 0.0)
                  + np.where(p_chat < 1, (1 - p_chat) * np.log(1 - p_chat), 0.0))  # fmt: skip
    return h_joint - w @ h_row.sum(axis=1)


def test_choose_test_cuts_with_a_local_factor_maximises_the_mutual_information():
    rng = np.random.default_rng(3)
    n_rows, n_cand = 24, 7
    lim = np.exp(rng.normal(np.log(4e-3), 0.35, (n_rows, n_cand)))
    w = rng.uniform(size=n_rows)
    w /= w.sum()
    idx, depth = choose_test_cuts(lim, w, 2, local_factor=LOCAL)
    ref_depth = np.array([_median_depth(lim[:, c], w) for c in range(n_cand)])
    np.testing.assert_allclose(depth, ref_depth[idx], rtol=1e-3)
    p = np.column_stack([_p_chatter(lim[:, c], ref_depth[c]) for c in range(n_cand)])
    # greedy: the first cut of most information alone, the second most with the first
    first = np.array([_mutual_information(p[:, [c]], w) for c in range(n_cand)])
    assert idx[0] == np.argmax(first)
    assert np.sort(first)[-1] - np.sort(first)[-2] > 1e-3  # no quadrature tie
    second = np.array(
        [_mutual_information(p[:, [idx[0], c]], w) if c != idx[0] else -1 for c in range(n_cand)]
    )
    assert idx[1] == np.argmax(second)
    assert np.sort(second)[-1] - np.sort(second)[-2] > 1e-3


def test_a_cut_whose_outcome_is_local_noise_is_not_chosen():
    """Rows within +-3 % of each other at candidate 0: a hard step splits them evenly (the most
    entropy), but with the local factor its outcome says almost nothing about the rows; at
    candidate 1 the rows' limits differ three-fold (a 25/75 split, less entropy, more
    information)."""
    n = 40
    w = np.full(n, 1 / n)
    lim = np.column_stack([
        4e-3 * np.linspace(0.97, 1.03, n),
        np.where(np.arange(n) < 10, 1.5e-3, 4.5e-3),
    ])  # fmt: skip
    assert choose_test_cuts(lim, w, 1)[0][0] == 0  # the hard step: the even split
    idx, _ = choose_test_cuts(lim, w, 1, local_factor=LOCAL)
    assert idx[0] == 1
    with pytest.raises(ValueError, match="at most 10 cuts"):
        choose_test_cuts(np.ones((3, 12)), np.full(3, 1 / 3), 11, local_factor=LOCAL)
    with pytest.raises(ValueError, match="local_factor must be"):
        choose_test_cuts(lim, w, 1, local_factor=(1.3, 0.55))
    with pytest.raises(ValueError, match="not all zero"):
        choose_test_cuts(lim, np.zeros(n), 1, local_factor=LOCAL)
    # groups: at most one cut per label
    g = choose_test_cuts(lim, w, 1, local_factor=LOCAL, groups=["a", "b"])[0]
    assert g[0] == 1


def _forecast_reference(lim, w, ev, ed, eps, qs):
    """Expected Brier score after one cut, every candidate and depth, by enumeration."""
    s_ev = 1 - np.column_stack([_p_chatter(ev[:, e], ed[e]) for e in range(ev.shape[1])])

    def brier(v):  # sum over outcomes of P(y) sum_e p_e (1 - p_e), p_e the posterior forecast
        z = v.sum()
        p = v @ s_ev / z
        return z * np.mean(p * (1 - p))

    out = {}
    for c in range(lim.shape[1]):
        for q in qs:
            d = optimize.brentq(lambda d, c=c, q=q: w @ _p_chatter(lim[:, c], d) - q, 1e-6, 1.0,
                                xtol=1e-12)  # fmt: skip
            pc = eps + (1 - 2 * eps) * _p_chatter(lim[:, c], d)
            out[c, d] = brier(w * pc) + brier(w * (1 - pc))
    return out, brier(w), s_ev


def test_choose_forecast_cuts_with_a_local_factor_against_enumeration_and_monte_carlo():
    rng = np.random.default_rng(5)
    n_rows, n_cand, n_ev, eps = 20, 5, 6, 0.1
    common = np.exp(rng.normal(0.0, 0.3, n_rows))  # rows correlated across points
    lim = 4e-3 * common[:, None] * np.exp(rng.normal(0.0, 0.25, (n_rows, n_cand)))
    ev = 4e-3 * common[:, None] * np.exp(rng.normal(0.0, 0.25, (n_rows, n_ev)))
    ed = rng.uniform(2.5e-3, 5e-3, n_ev)
    w = rng.uniform(size=n_rows)
    w /= w.sum()
    qs = (0.3, 0.5, 0.7)
    idx, depth, scores = choose_forecast_cuts(
        lim, w, ev, ed, 1, label_noise=eps, depth_quantiles=qs, local_factor=LOCAL
    )
    ref, before, s_ev = _forecast_reference(lim, w, ev, ed, eps, qs)
    assert scores[0] == pytest.approx(before, abs=1e-5)
    (c_best, d_best), b_best = min(ref.items(), key=lambda kv: kv[1])
    assert idx[0] == c_best and depth[0] == pytest.approx(d_best, rel=1e-3)
    assert scores[1] == pytest.approx(b_best, abs=1e-5)
    runner_up = sorted(ref.values())[1]
    assert runner_up - b_best > 1e-4  # no tie within the quadrature error (~1e-6)
    # the expected Brier score itself, by Monte-Carlo draws of rows, local factors and labels
    n = 400_000
    r = rng.choice(n_rows, n, p=w)
    lf = np.exp(rng.uniform(*np.log(LOCAL), (n, 1 + n_ev)))
    chatter = (lf[:, 0] * lim[r, idx[0]] <= depth[0]) ^ (rng.uniform(size=n) < eps)
    stable_ev = lf[:, 1:] * ev[r] > ed[None, :]
    pc = eps + (1 - 2 * eps) * _p_chatter(lim[:, idx[0]], depth[0])
    forecast = {y: (w * lk) @ s_ev / np.sum(w * lk) for y, lk in ((True, pc), (False, 1 - pc))}
    p_after = np.where(chatter[:, None], forecast[True], forecast[False])
    assert np.mean((p_after - stable_ev) ** 2) == pytest.approx(scores[1], abs=3e-3)
    p_before = w @ s_ev
    assert np.mean((p_before - stable_ev) ** 2) == pytest.approx(scores[0], abs=3e-3)
    # without the local factor the hard step gives another score (the option is used)
    _, _, hard = choose_forecast_cuts(lim, w, ev, ed, 1, label_noise=eps, depth_quantiles=qs)
    assert abs(hard[0] - scores[0]) > 1e-2


def test_choose_test_cuts_depth_without_a_local_factor_against_loops_and_at_plan_size():
    """The hard step's depth (the structure limit whose weight at or below is nearest one half,
    ties shared) against plain loops; and at the size of ``mill plan --cuts --suggest-cuts``
    (48 structures x 32 factors = 1536 rows, 2400 candidates), which once needed
    S^2 C = 42 GiB."""
    rng = np.random.default_rng(7)
    lim = rng.choice([1e-3, 2e-3, 3e-3, 5e-3, np.inf], (15, 6))
    w = rng.uniform(size=15)
    w /= w.sum()
    idx, depth = choose_test_cuts(lim, w, 3)
    for c, d in zip(idx, depth, strict=True):
        best, best_gap = None, np.inf
        for s in range(lim.shape[0]):  # first structure (in order) of the least gap
            if not np.isfinite(lim[s, c]):
                continue
            gap = abs(sum(w[t] for t in range(15) if lim[t, c] <= lim[s, c]) - 0.5)
            if gap < best_gap - 1e-12:
                best, best_gap = lim[s, c], gap
        assert d == best
    big = np.exp(rng.normal(np.log(4e-3), 0.3, (1536, 2400)))
    idx, depth = choose_test_cuts(big, np.full(1536, 1 / 1536), 2)
    assert idx.shape == (2,) and np.all(np.isfinite(depth))


def test_cli_suggest_cuts_after_cuts_uses_the_local_factor(tmp_path, monkeypatch):
    import json

    from typer.testing import CliRunner

    from robovib.cli import app
    from robovib.milling import cut_posterior

    seen = []

    def spy(*args, **kwargs):
        seen.append(kwargs.get("local_factor"))
        return choose_test_cuts(*args, **kwargs)

    monkeypatch.setattr(cut_posterior, "choose_test_cuts", spy)
    cuts = tmp_path / "cuts.csv"
    cuts.write_text("x_mm,y_mm,rz_deg,spindle_rpm,depth_mm,result\n2350,0,0,1750,2,stable\n")
    args = ["mill", "plan", "--start", "2200,-100", "--end", "2600,400", "--segments", "4",
            "--samples", "12", "--rpm-range", "1500:3000:4", "--cuts", str(cuts), "--json",
            "--n-suggest", "2"]  # fmt: skip
    out = CliRunner().invoke(app, [*args, "--suggest-cuts", str(tmp_path / "a.csv")])
    assert out.exit_code == 0, out.output
    assert seen == [(0.55, 1.3)]
    assert len(json.loads(out.output)["suggested_cuts"]) == 2
    out = CliRunner().invoke(
        app, [*args, "--suggest-cuts", str(tmp_path / "b.csv"), "--local-factor", "none"]
    )
    assert out.exit_code == 0, out.output
    assert seen == [(0.55, 1.3), None]
    for option, bad in (("--local-factor", "1.3,0.55"), ("--common-factor", "0,1.1"),
                        ("--common-factor", "nan,1")):  # fmt: skip
        out = CliRunner().invoke(app, [*args, option, bad])
        assert out.exit_code != 0 and f"{option} must be LO,HI" in out.output, out.output


def test_p_stable_with_a_local_factor_rejects_bad_input():
    lim = np.array([[4e-3], [3e-3]])
    for depth in (-1e-3, np.inf):
        with pytest.raises(ValueError, match="depths must be finite and >= 0"):
            row_p_stable(lim, depth, LOCAL)
    with pytest.raises(ValueError, match="limits must be positive"):
        row_p_stable(-lim, 1e-3, LOCAL)
    for w in ([0.0, 0.0], [np.nan, 1.0], [-0.5, 1.5]):
        with pytest.raises(ValueError, match="weights must be finite"):
            local_p_stable(lim, w, 1e-3, LOCAL)
    for chunk in (0, -3, 2.5):  # once left uninitialised memory in the result
        with pytest.raises(ValueError, match="chunk must be"):
            local_quantile(lim, [0.5, 0.5], 0.5, LOCAL, chunk=chunk)
    # depth 0 is stable under every row, whatever the local factor
    assert local_p_stable(lim, [0.5, 0.5], 0.0, LOCAL) == pytest.approx(1.0)


def test_depth_cap_keeps_rows_that_the_local_factor_can_bring_below_it():
    """``StructureSamples.limits(depth_cap_m=D)`` with a local factor: a row whose limit is above
    D but below D / low can still chatter below D and must stay finite (the uncapped limits are
    the reference)."""
    from robovib.gp.chapter3_model import workspace_predictor
    from robovib.milling import ALUMINIUM_7075, CuttingConditions, MillingTool
    from robovib.milling.structures import sample_structures

    tool, cond = MillingTool(), CuttingConditions(1750.0, 0.058e-3, 1e-3, 6e-3)
    model = workspace_predictor(None, seed=0, require_inputs=("x_mm", "y_mm", "rz_deg"))
    st = sample_structures(model, 8, rng=1).on_factor_grid(
        4, process_factor=(0.9, 1.1), local_factor=LOCAL
    )
    poses, rpm = [[2300.0, 0.0, 40.0], [2500.0, 200.0, 100.0]], [1500.0, 2200.0, 3000.0]
    free = st.limits(poses, rpm, tool, cond, ALUMINIUM_7075)
    cap = float(np.median(free[np.isfinite(free)]))
    capped = st.limits(poses, rpm, tool, cond, ALUMINIUM_7075, depth_cap_m=cap)
    reachable = free * LOCAL[0] <= cap  # may chatter below the cap
    band = reachable & (free > cap)
    assert band.sum() >= 5  # rows the local factor alone brings below the cap
    np.testing.assert_allclose(capped[reachable], free[reachable], rtol=1e-9)


@pytest.mark.parametrize("q", [0.0, 0.3, 0.5, 0.8, 0.95])
def test_local_quantile_of_a_single_valued_local_factor_by_its_definition(q):
    """``lo == hi``: min { d : sum_r w_r [lo a_r <= d] > q }, exact ties of the cumulative weight
    with ``q`` included (weights 0.5, 0.3, 0.2)."""
    lim = np.array([[1e-3, 4e-3], [2e-3, np.inf], [3e-3, 2e-3]])
    w = np.array([0.5, 0.3, 0.2])
    got = local_quantile(lim, w, q, (0.8, 0.8))
    for c in range(2):
        cands = sorted(0.8 * lim[:, c])
        ref = next(d for d in cands if sum(w[0.8 * lim[:, c] <= d]) > q + 1e-12)
        assert got[c] == ref
