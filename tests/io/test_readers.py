"""Recording readers never lose or invent a hit (issue 13/18): property tests on files written by
pyuff or by hand (never by robovib's own writer), one per layout."""

import numpy as np
import pytest
import pyuff
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from robovib.frf import check_hit, segment_hits
from robovib.io import read_recording, read_recording_channels

SETTINGS = settings(
    max_examples=12, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)


def pulse(n, fs, t0, peak, width_s=2e-3):
    t = np.arange(n) / fs
    return (
        peak
        * np.clip(np.sin(np.pi * (t - t0) / width_s), 0, None)
        * ((t >= t0) & (t <= t0 + width_s))
    )


def decay(n, fs, t0, amp, fn=25.0):
    t = np.arange(n) / fs - t0
    return amp * np.where(t >= 0, np.exp(-3 * t) * np.sin(2 * np.pi * fn * t), 0.0)


def rec58(data, fs, spec, label, rsp_dir, lc=0, node=1, ref_dir=0):
    return pyuff.prepare_58(
        binary=0, func_type=1, load_case_id=lc, rsp_node=node, rsp_dir=rsp_dir, ref_node=1,
        ref_dir=ref_dir, ordinate_spec_data_type=spec, ordinate_axis_units_lab=label,
        orddenom_spec_data_type=0, abscissa_spacing=1, data=np.asarray(data, float),
        x=np.arange(len(data)) / fs,
    )  # fmt: skip


def write_pyuff(path, sets):
    pyuff.UFF(str(path)).write_sets(sets, mode="add")


@SETTINGS
@given(n_hits=st.integers(1, 5), seed=st.integers(0, 1000), response_first=st.booleans())
def test_uff_pairs_all_load_case_zero(tmp_path_factory, n_hits, seed, response_first):
    """Force/response pairs all with load-case id 0: every hit read, in order."""
    rng = np.random.default_rng(seed)
    fs, n = 1024.0, 512
    peaks = rng.uniform(100, 900, n_hits)
    sets = []
    for p in peaks:
        pair = [rec58(pulse(n, fs, 0.02, p), fs, 13, "N", 1),
                rec58(decay(n, fs, 0.02, p / 100), fs, 12, "m/s^2", 1)]  # fmt: skip
        sets += pair[::-1] if response_first else pair
    path = tmp_path_factory.mktemp("u") / "pairs.uff"
    write_pyuff(path, sets)
    rec = read_recording(path)
    assert rec.n_hits == n_hits and rec.report.hits_formed == n_hits
    assert rec.report.records_read == 2 * n_hits and not rec.report.hits_rejected
    expect = [pulse(n, fs, 0.02, p).max() for p in peaks]
    np.testing.assert_allclose(rec.forces.max(axis=1), expect, rtol=1e-6)


@SETTINGS
@given(
    n_hits=st.integers(1, 6),
    spacing_s=st.floats(0.7, 1.5),
    seed=st.integers(0, 1000),
    double=st.sampled_from([None, "before", "after"]),
)
def test_uff_continuous_record_is_cut_into_hits(tmp_path_factory, n_hits, spacing_s, seed, double):
    """One force and one response record holding n hits a spacing apart: n hits out; a double
    hit (a second, smaller pulse 40 ms before or after one impact) stays one hit, flagged."""
    rng = np.random.default_rng(seed)
    fs = 1024.0
    n = round((0.1 + n_hits * spacing_s) * fs)
    onsets = 0.1 + spacing_s * np.arange(n_hits)
    peaks = rng.uniform(100, 900, n_hits)
    force = sum(pulse(n, fs, t, p) for t, p in zip(onsets, peaks, strict=True))
    victim = int(rng.integers(n_hits))
    if double is not None:
        shift = 0.04 if double == "after" else -0.04
        force = force + pulse(n, fs, onsets[victim] + shift, 0.4 * peaks[victim])
    force = force + rng.normal(size=n) * 0.05
    resp = sum(decay(n, fs, t, p / 100) for t, p in zip(onsets, peaks, strict=True))
    path = tmp_path_factory.mktemp("u") / "cont.uff"
    write_pyuff(path, [rec58(force, fs, 13, "N", 2), rec58(resp, fs, 12, "m/s^2", 2)])
    rec = read_recording(path, "y", pretrigger_s=0.05 if double == "before" else 0.01)
    assert rec.report.layout == ("continuous" if n_hits > 1 else "paired")
    assert rec.n_hits == n_hits and not rec.report.hits_rejected
    expect = [pulse(n, fs, t, p).max() for t, p in zip(onsets, peaks, strict=True)]
    np.testing.assert_allclose(rec.forces.max(axis=1), expect, rtol=0.02)
    for i, f in enumerate(rec.forces):  # each hit keeps its pre-trigger; only the victim is double
        rep = check_hit(f, f, fs, pretrigger_s=0.009)
        is_double = any("double hit" in r for r in rep.reasons)
        assert is_double == (double is not None and i == victim), (i, rep.reasons)


@SETTINGS
@given(n_hits=st.integers(1, 4), seed=st.integers(0, 1000))
def test_uff_one_force_three_responses(tmp_path_factory, n_hits, seed):
    """Force + X/Y/Z responses per hit, load case 0: three channels, none overwritten."""
    rng = np.random.default_rng(seed)
    fs, n = 1024.0, 512
    gains = {1: 1.0, 2: -2.0, 3: 3.0}
    peaks = rng.uniform(100, 900, n_hits)
    sets = []
    for p in peaks:
        sets.append(rec58(pulse(n, fs, 0.02, p), fs, 13, "N", 1))
        sets += [rec58(g * decay(n, fs, 0.02, p / 100), fs, 12, "g", d) for d, g in gains.items()]
    path = tmp_path_factory.mktemp("u") / "tri.uff"
    write_pyuff(path, sets)
    chans = read_recording_channels(path)
    assert [c.direction for c in chans] == ["x", "y", "z"]
    assert all(c.n_hits == n_hits and c.reference_direction == "x" for c in chans)
    for c, g in zip(chans, gains.values(), strict=True):
        expect = np.array([g * decay(n, fs, 0.02, p / 100) * 9.80665 for p in peaks])
        np.testing.assert_allclose(c.responses, expect, rtol=1e-6, atol=1e-9)
    assert read_recording(path).direction == "x"  # the direct channel
    assert read_recording(path, "x").direction == "x"
    with pytest.raises(ValueError, match="contradicts the file"):
        read_recording(path, "z")  # force is along X: Z is a cross channel, not a Z test


@SETTINGS
@given(n_hits=st.integers(1, 4), with_hit_column=st.booleans(), seed=st.integers(0, 1000))
def test_csv_six_decimal_time_at_5120_hz(tmp_path_factory, n_hits, with_hit_column, seed):
    """DAQ export: time printed with 6 decimals at 5120 Hz (rounding is not a gap)."""
    rng = np.random.default_rng(seed)
    fs, spacing = 5120.0, 0.6
    peaks = rng.uniform(100, 900, n_hits)
    if with_hit_column:
        n = 1024
        lines = ["hit,time_s,force_n,acceleration_g"]
        for h, p in enumerate(peaks):
            f, a = pulse(n, fs, 0.02, p), decay(n, fs, 0.02, p / 100)
            lines += [f"{h},{i / fs:.6f},{f[i]:.6f},{a[i]:.6f}" for i in range(n)]
    else:
        n = round((0.05 + n_hits * spacing) * fs)
        on = 0.05 + spacing * np.arange(n_hits)
        f = sum(pulse(n, fs, t, p) for t, p in zip(on, peaks, strict=True))
        a = sum(decay(n, fs, t, p / 100) for t, p in zip(on, peaks, strict=True))
        lines = ["time_s,force_n,acceleration_g"]
        lines += [f"{i / fs:.6f},{f[i]:.6f},{a[i]:.6f}" for i in range(n)]
    path = tmp_path_factory.mktemp("c") / "daq.csv"
    path.write_text("\n".join(lines) + "\n")
    rec = read_recording(path, "z")
    assert rec.n_hits == n_hits and rec.report.hits_formed == n_hits
    assert rec.sample_rate_hz == pytest.approx(fs, rel=1e-6)
    np.testing.assert_allclose(rec.forces.max(axis=1), peaks, rtol=0.05)


def test_csv_real_gap_is_named(tmp_path):
    fs = 5120.0
    idx = np.delete(np.arange(600), 300)  # one sample missing
    lines = ["time_s,force_n,acceleration_g"] + [f"{i / fs:.6f},1.0,0.5" for i in idx]
    path = tmp_path / "gap.csv"
    path.write_text("\n".join(lines))
    with pytest.raises(ValueError, match=r"not uniformly sampled.*sample 300 \(t = 0.0587"):
        read_recording(path)


def test_negative_direction_code_negates_and_cross_frf_kept_apart(tmp_path):
    fs, n = 1024.0, 256
    f, a = pulse(n, fs, 0.02, 500.0), decay(n, fs, 0.02, 5.0)
    path = tmp_path / "neg.uff"
    write_pyuff(path, [rec58(f, fs, 13, "N", 1), rec58(a, fs, 12, "m/s^2", -1)])
    rec = read_recording(path, "x")
    np.testing.assert_allclose(rec.responses[0], -a, atol=1e-9)
    assert any("negated" in note for note in rec.report.notes)


def test_unpaired_record_is_reported_not_invented(tmp_path):
    fs, n = 1024.0, 256
    sets = []
    for lc in (1, 2, 3):
        sets.append(rec58(pulse(n, fs, 0.02, 300.0 + lc), fs, 13, "N", 3, lc=lc))
        if lc != 2:
            sets.append(rec58(decay(n, fs, 0.02, 3.0), fs, 12, "m/s^2", 3, lc=lc))
    path = tmp_path / "missing.uff"
    write_pyuff(path, sets)
    rec = read_recording(path)
    assert rec.n_hits == 2
    assert rec.report.hits_rejected[0][0] == "load case 2"
    assert "no acceleration" in rec.report.hits_rejected[0][1]


def test_double_hit_smaller_first_pulse_is_caught():
    fs, n = 4096.0, 4096
    f = pulse(n, fs, 0.03, 150.0, 1e-3) + pulse(n, fs, 0.05, 600.0, 1e-3)
    rep = check_hit(f, f, fs)
    assert not rep.accepted and "before the largest" in rep.reasons[0]
    f2 = pulse(n, fs, 0.03, 600.0, 1e-3) + pulse(n, fs, 0.05, 150.0, 1e-3)
    assert not check_hit(f2, f2, fs).accepted
    assert check_hit(pulse(n, fs, 0.03, 600.0, 1e-3), f, fs).accepted


def test_segment_double_hit_inside_window_and_truncated_tail():
    fs = 1000.0
    n = 3300
    f = pulse(n, fs, 0.1, 500.0) + pulse(n, fs, 0.15, 200.0)  # double hit at 0.1 s
    f += pulse(n, fs, 1.1, 400.0) + pulse(n, fs, 2.1, 450.0) + pulse(n, fs, 3.2, 300.0)
    seg = segment_hits(f, fs, hold_off_s=0.5, pretrigger_s=0.01)
    assert seg.n_hits == 3 and list(seg.n_pulses) == [2, 1, 1]
    assert len(seg.rejected) == 1 and "truncated" in seg.rejected[0][1]
    assert seg.length == 1000
    hit0 = f[seg.starts[0] : seg.starts[0] + seg.length]
    assert "double hit" in check_hit(hit0, hit0, fs).reasons[0]


def frf58(values, f, rsp_dir, ref_dir):
    return pyuff.prepare_58(
        binary=0, func_type=4, load_case_id=0, rsp_node=1, rsp_dir=rsp_dir, ref_node=1,
        ref_dir=ref_dir, ordinate_spec_data_type=8, ordinate_axis_units_lab="m",
        orddenom_spec_data_type=13, orddenom_axis_units_lab="N", abscissa_spacing=1,
        data=np.asarray(values, complex), x=f,
    )  # fmt: skip


def test_uff_frf_direction_signs_and_cross_frf(tmp_path):
    from robovib.io import read_frfs
    from robovib.modal import fit_dominant_mode

    f = np.arange(1.0, 80.0, 0.25)
    h = 1.0 / (1e6 * (1 - (f / 20.0) ** 2 + 2j * 0.05 * f / 20.0))
    path = tmp_path / "frfs.uff"
    write_pyuff(path, [frf58(-h, f, -1, 1), frf58(h, f, 2, 1)])
    direct, cross = read_frfs(path)
    np.testing.assert_allclose(direct.values, h, rtol=1e-9)  # -X response: sign restored
    assert direct.direction == "x" and "reference_direction" not in direct.meta
    assert cross.direction == "y" and cross.meta["reference_direction"] == "x"
    assert fit_dominant_mode(direct).parameters.stiffness_n_per_m == pytest.approx(1e6, rel=0.01)
    with pytest.raises(ValueError, match="cross FRF"):
        fit_dominant_mode(cross)
