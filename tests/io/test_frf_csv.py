"""FRF CSV reader/writer: units in the header converted at the edge, errors naming the column."""

from __future__ import annotations

import numpy as np
import pytest

from robovib.frf import FRF
from robovib.io import read_frf_csv, read_frfs, write_frf_csv, write_frfs
from robovib.modal import ModalParameters

MODE = ModalParameters(20.0, 2e6, 0.05)
F = np.linspace(0.0, 60.0, 121)


def _write(path, header, cols):
    np.savetxt(path, np.column_stack(cols), delimiter=",", header=header, comments="")
    return path


def test_compliance_in_um_per_n(tmp_path):
    h = MODE.compliance(F)
    p = _write(tmp_path / "a.csv", "frequency_hz,real_um_per_n,imag_um_per_n",
               [F, 1e6 * h.real, 1e6 * h.imag])  # fmt: skip
    (frf,) = read_frf_csv(p, direction="x")
    assert frf.quantity == "compliance" and frf.direction == "x"
    np.testing.assert_allclose(frf.values, h, rtol=1e-9)


def test_accelerance_in_g_and_mobility_converted_to_compliance(tmp_path):
    w = 2 * np.pi * F
    h = MODE.compliance(F)
    acc_g = -(w**2) * h / 9.80665
    p = _write(
        tmp_path / "acc.csv", "frequency_hz,real_g_per_n,imag_g_per_n", [F, acc_g.real, acc_g.imag]
    )
    (frf,) = read_frf_csv(p)
    assert frf.frequency_hz[0] == F[1]  # 0 Hz cannot be converted
    np.testing.assert_allclose(frf.values, h[1:], rtol=1e-9)
    mob = 1j * w * h * 1e3  # mm/s/N
    p = _write(tmp_path / "mob.csv", "frequency_hz,real_mm_per_s_per_n,imag_mm_per_s_per_n",
               [F, mob.real, mob.imag])  # fmt: skip
    (frf,) = read_frf_csv(p, min_frequency_hz=5.0)
    assert frf.frequency_hz[0] == 5.0
    np.testing.assert_allclose(frf.values, h[F >= 5], rtol=1e-9)
    (raw,) = read_frf_csv(p, compliance=False)
    assert raw.quantity == "mobility"
    np.testing.assert_allclose(raw.values, mob / 1e3, rtol=1e-9)


def test_round_trip_two_directions_and_read_frfs(tmp_path):
    f = F[1:]
    a = FRF(f, MODE.compliance(f), coherence=np.full(f.size, 0.9), direction="x")
    b = FRF(f, 2 * MODE.compliance(f), direction="y")
    write_frfs(tmp_path / "two.csv", [a, b])
    header = (tmp_path / "two.csv").read_text().splitlines()[0]
    assert (
        header
        == "frequency_hz,x_real_m_per_n,x_imag_m_per_n,x_coherence,y_real_m_per_n,y_imag_m_per_n"
    )
    x, y = read_frfs(tmp_path / "two.csv")
    assert (x.direction, y.direction) == ("x", "y")
    np.testing.assert_allclose(x.values, a.values, rtol=1e-11)
    np.testing.assert_allclose(x.coherence, 0.9)
    np.testing.assert_allclose(y.values, b.values, rtol=1e-11)
    assert y.coherence is None
    write_frf_csv(tmp_path / "um.csv", a, unit="um_per_n")
    (back,) = read_frf_csv(tmp_path / "um.csv")
    assert back.direction == "x"
    np.testing.assert_allclose(back.values, a.values, rtol=1e-11)


@pytest.mark.parametrize(
    ("header", "cell", "match"),
    [
        ("frequency_hz,real_in_per_n,imag_in_per_n", "1", "real_in_per_n.*unknown unit"),
        ("frequency_hz,real_m_per_n", "1", "real_m_per_n.*no imaginary column"),
        ("frequency_hz,real_m_per_n,imag_mm_per_n", "1", "one unit"),
        ("freq,real_m_per_n,imag_m_per_n", "1", "frequency_hz"),
        ("frequency_hz,real_m_per_n,imag_m_per_n", "abc", "column 'imag_m_per_n'.*not a number"),
        ("frequency_hz,real_m_per_n,imag_m_per_n", "nan", "column 'imag_m_per_n'.*not finite"),
        ("frequency_hz,q_real_m_per_n,q_imag_m_per_n", "1", "direction prefix"),
    ],
)
def test_errors_name_the_column(tmp_path, header, cell, match):
    n = header.count(",") + 1
    rows = [",".join(["1", *["1"] * (n - 1)]), ",".join(["2", *["1"] * (n - 2), cell])]
    p = tmp_path / "bad.csv"
    p.write_text(header + "\n" + "\n".join(rows) + "\n")
    with pytest.raises(ValueError, match=match):
        read_frf_csv(p)


def test_writer_rejects_wrong_unit_and_mixed_axes(tmp_path):
    a = FRF(F[1:], MODE.compliance(F[1:]), direction="x")
    with pytest.raises(ValueError, match="not a compliance unit"):
        write_frf_csv(tmp_path / "a.csv", a, unit="g_per_n")
    b = FRF(F[2:], MODE.compliance(F[2:]), direction="y")
    with pytest.raises(ValueError, match="one frequency axis"):
        write_frf_csv(tmp_path / "a.csv", [a, b])


def test_one_frf_csv_reader():
    """``read_frfs_csv`` is the former name of ``read_frf_csv`` (one function, no wrapper)."""
    import robovib.io as rio
    from robovib.milling import chart

    assert rio.read_frfs_csv is rio.read_frf_csv is chart.read_frf_csv


def test_frf_csv_read_by_the_one_table_reader(tmp_path):
    """FRF CSV goes through io.read_table: comment lines anywhere, an Excel export (';',
    decimal commas, BOM, units in brackets) reads as the plain file, and a short line is named
    by its number."""
    from robovib.io import read_table

    f = np.array([10.0, 10.5, 11.0])
    h = MODE.compliance(f) * 1e6  # um/N
    plain = tmp_path / "plain.csv"
    lines = [f"{a:.17g},{b.real:.17g},{b.imag:.17g}" for a, b in zip(f, h, strict=True)]
    plain.write_text("# exported\nfrequency_hz,real_um_per_n,imag_um_per_n\n" + lines[0]
                     + "\n# a note between rows\n" + "\n".join(lines[1:]) + "\n")  # fmt: skip
    excel = tmp_path / "excel.csv"
    rows = [ln.replace(",", ";").replace(".", ",") for ln in lines]
    excel.write_text(
        "Frequency [Hz];Real [um/N];Imag [um/N]\n" + "\n".join(rows) + "\n", encoding="utf-8-sig"
    )  # units in brackets: frequency_hz, real_um_per_n
    (a,) = read_frf_csv(plain, direction="x")
    (b,) = read_frf_csv(excel, direction="x")
    np.testing.assert_allclose(a.values, MODE.compliance(f), rtol=1e-12)
    np.testing.assert_array_equal(a.values, b.values)
    assert read_table(plain, comment="#").lines == (3, 5, 6)  # file lines, comments counted
    short = tmp_path / "short.csv"
    short.write_text("frequency_hz,real_m_per_n,imag_m_per_n\n1,1,1\n2,1\n")
    with pytest.raises(ValueError, match=r"short\.csv line 3: 2 cells, expected 3"):
        read_frf_csv(short)
