"""FRF files keep every field: HDF5 <-> UFF round trips (hypothesis), refusals instead of losses."""

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from robovib.frf import FRF
from robovib.io import read_frfs, write_frfs

finite = st.floats(-1e3, 1e3, allow_nan=False, allow_infinity=False)


@st.composite
def frfs(draw):
    n = draw(st.integers(2, 40))
    dx = draw(st.sampled_from([0.0625, 0.1, 0.25, 0.5, 1.0, 1.953125, 2.5]))
    x0 = dx * draw(st.integers(0, 200))
    f = x0 + dx * np.arange(n)
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    scale = 10.0 ** draw(st.integers(-9, -3))
    values = scale * (rng.normal(size=n) + 1j * rng.normal(size=n))
    meta = {}
    if draw(st.booleans()):
        meta["path_s_m"] = draw(st.floats(0, 2, allow_nan=False))
    if draw(st.booleans()):
        meta["flagged"] = rng.random(n) < 0.3
    if draw(st.booleans()):
        meta["note"] = draw(st.text("abcxyz_-", min_size=1, max_size=12))
    if draw(st.booleans()):
        meta["n_segments"] = draw(st.integers(0, 10**6))
    pose = tuple(draw(finite) for _ in range(6)) if draw(st.booleans()) else None
    return FRF(
        frequency_hz=f,
        values=values,
        coherence=rng.random(n) if draw(st.booleans()) else None,
        quantity=draw(st.sampled_from(["compliance", "mobility", "accelerance"])),
        direction=draw(st.sampled_from([None, "x", "y", "z"])),
        pose=pose,
        source=draw(st.sampled_from(["EMA", "OMA", "model"])),
        n_averages=draw(st.integers(1, 1000)),
        exp_window_tau_s=draw(st.one_of(st.none(), st.floats(1e-3, 10.0))),
        estimator=draw(st.sampled_from(["H1", "H2", "model"])),
        meta=meta,
    )


def _assert_same(a: FRF, b: FRF, rtol: float) -> None:
    np.testing.assert_allclose(b.frequency_hz, a.frequency_hz, rtol=0, atol=1e-9)
    np.testing.assert_allclose(b.values, a.values, rtol=rtol, atol=0)
    if a.coherence is None:
        assert b.coherence is None
    else:
        np.testing.assert_allclose(b.coherence, a.coherence, rtol=rtol, atol=1e-15)
    for name in ("quantity", "direction", "pose", "source", "n_averages", "estimator"):
        assert getattr(b, name) == getattr(a, name), name
    assert b.exp_window_tau_s == a.exp_window_tau_s
    assert set(b.meta) == set(a.meta)
    for key, value in a.meta.items():
        if isinstance(value, np.ndarray):
            assert b.meta[key].dtype == value.dtype
            np.testing.assert_array_equal(b.meta[key], value)
        else:
            got = b.meta[key].item() if isinstance(b.meta[key], np.generic) else b.meta[key]
            assert got == value and type(got) is type(value), key


@settings(
    max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(items=st.lists(frfs(), min_size=1, max_size=3))
def test_h5_uff_round_trip_keeps_every_field(tmp_path, items):
    """h5 -> uff -> h5: equal up to UFF's 12 significant digits of the ordinates."""
    h5, uff, h5b = tmp_path / "a.h5", tmp_path / "b.uff", tmp_path / "c.h5"
    write_frfs(h5, items)
    from_h5 = read_frfs(h5)
    for a, b in zip(items, from_h5, strict=True):
        _assert_same(a, b, rtol=0)
    write_frfs(uff, from_h5)
    from_uff = read_frfs(uff)
    assert len(from_uff) == len(items)
    for a, b in zip(items, from_uff, strict=True):
        _assert_same(a, b, rtol=1e-10)
    write_frfs(h5b, from_uff)
    for a, b in zip(items, read_frfs(h5b), strict=True):
        _assert_same(a, b, rtol=1e-10)


def _frf(**kw):
    f = np.arange(1.0, 11.0)
    return FRF(f, np.ones(f.size) * (1 - 0.5j) * 1e-6, **kw)  # complex: readers need phase


def test_uff_refuses_what_it_cannot_keep(tmp_path):
    out = tmp_path / "a.uff"
    third = np.arange(10) / 3.0 + 1.0
    with pytest.raises(ValueError, match=r"cannot be written exactly.*write \.h5"):
        write_frfs(out, [FRF(third, np.ones(10))])
    with pytest.raises(ValueError, match=r"80-character ID line; write \.h5"):
        write_frfs(out, [_frf(meta={"long": "x" * 90})])
    with pytest.raises(ValueError, match="1-D numeric arrays only"):
        write_frfs(out, [_frf(meta={"grid": np.ones((2, 2))})])
    assert not out.exists()


def test_exponential_window_correction_survives_uff(tmp_path):
    """The window's damping must still be removed after a trip through UFF (was lost: 0.222 vs 0.162)."""
    from robovib.modal import ModalParameters, fit_dominant_mode

    mode = ModalParameters(16.5, 2e6, 0.04)
    tau = 0.5
    f = np.arange(2.0, 60.0, 0.25)
    # what an exponential window does to the measured FRF: every decay rate grows by 1/tau
    sigma = mode.damping_ratio * 2 * np.pi * mode.natural_frequency_hz + 1 / tau
    wn = 2 * np.pi * mode.natural_frequency_hz
    wd = np.sqrt(wn**2 - (mode.damping_ratio * wn) ** 2)
    wn_w = np.hypot(sigma, wd)
    zeta_w = sigma / wn_w
    windowed = ModalParameters(
        wn_w / (2 * np.pi), mode.stiffness_n_per_m * (wn_w / wn) ** 2, zeta_w
    )
    frf = FRF(f, windowed.compliance(f), exp_window_tau_s=tau, direction="x")
    write_frfs(tmp_path / "w.uff", [frf])
    (back,) = read_frfs(tmp_path / "w.uff")
    fit = fit_dominant_mode(back)
    assert fit.exp_window_corrected
    assert fit.parameters.damping_ratio == pytest.approx(0.04, rel=0.02)


def _as_legacy(path, version=1):
    """Rewrite the header as robovib wrote it before io.h5format: ``version``, no
    ``format_version`` / ``created_utc``."""
    import h5py

    with h5py.File(path, "a") as h5:
        for key in ("format_version", "created_utc", "content_sha256"):
            if key in h5.attrs:
                del h5.attrs[key]
        h5.attrs["version"] = version
    _unseal(path)


def _unseal(path):
    """Blank the byte checksum robovib writes in the user block (older files have none)."""
    from robovib.files.h5safe import USERBLOCK_SIZE

    data = bytearray(path.read_bytes())
    data[:USERBLOCK_SIZE] = bytes(USERBLOCK_SIZE)
    path.write_bytes(bytes(data))


def test_h5_header_is_the_io_convention_and_old_files_load(tmp_path):
    import h5py

    path = tmp_path / "a.h5"
    frf = _frf(direction="x", pose=(1.0, 0.0, 0.5, 0.0, 0.0, 45.0))
    write_frfs(path, [frf])
    with h5py.File(path, "r") as h5:
        assert h5.attrs["format"] == "robovib-frf" and int(h5.attrs["format_version"]) == 1
        assert {"robovib_version", "created_utc", "units"} <= set(h5.attrs)
    _as_legacy(path)
    (back,) = read_frfs(path)
    np.testing.assert_array_equal(back.values, frf.values)
    assert back.pose == frf.pose
    _as_legacy(path, version=2)
    with pytest.raises(ValueError, match="format version 2; this robovib reads versions 1 to 1"):
        read_frfs(path)
    other = tmp_path / "other.h5"
    with h5py.File(other, "w") as h5:
        h5.attrs["format"] = "something else"
    with pytest.raises(ValueError, match=r"not a robovib FRF \(robovib-frf\) file"):
        read_frfs(other)
