"""FRF lines in a band against the hit length: the one check of frf compute and the campaign."""

from pathlib import Path

import numpy as np
import pytest

from robovib.frf import FRF, BandTooShortError, check_lines_in_band

EXAMPLES = Path(__file__).parents[2] / "src/robovib/datasets/examples"


def _frf(sample_rate_hz, n_samples, f_max_hz):
    # the FFT lines of hits of n_samples at sample_rate_hz: k * fs / N
    f = np.arange(n_samples // 2 + 1) * sample_rate_hz / n_samples
    f = f[(f > 0) & (f <= f_max_hz)]
    return FRF(f, np.ones(f.size, complex))


def test_lines_counted_with_both_ends_and_the_needed_length():
    frf = _frf(1000.0, 500, 200.0)  # hits of 0.5 s: lines 2 Hz apart
    # 40, 42, ..., 50 Hz: 6 lines, both ends on a line
    assert check_lines_in_band(frf, (40.0, 50.0), hit_samples=500, sample_rate_hz=1000.0) == 6
    assert check_lines_in_band(frf, (39.0, 51.0), hit_samples=500, sample_rate_hz=1000.0) == 6
    with pytest.raises(BandTooShortError) as err:
        check_lines_in_band(frf, (40.0, 46.0), hit_samples=500, sample_rate_hz=1000.0,
                            min_lines=5, band_name="fit band")  # fmt: skip
    e = err.value
    assert isinstance(e, ValueError)
    assert (e.n_lines, e.min_lines, e.df_hz, e.hit_duration_s) == (4, 5, 2.0, 0.5)
    assert e.needed_s == pytest.approx(5 / 6.0)  # 5 lines over a 6 Hz band
    assert str(e) == (
        "FRF resolution df = 2 Hz from hits of 500 samples = 0.5 s leaves 4 lines in the "
        "fit band 40-46 Hz, fewer than 5: the hits are too short for this band (need >= 0.833 s)"
    )
    with pytest.raises(BandTooShortError, match="leaves 0 lines in the band 300-400 Hz"):
        check_lines_in_band(frf, (300.0, 400.0), hit_samples=500, sample_rate_hz=1000.0)


def test_frf_compute_and_the_campaign_refuse_short_hits(tmp_path):
    from typer.testing import CliRunner

    from robovib.campaign.manifest import read_manifest
    from robovib.campaign.process import ProcessingSettings, process_row
    from robovib.cli import app

    # hammer.uff: hits of 2048 samples at 512 Hz = 4 s, lines 0.25 Hz apart
    args = ["frf", "compute", str(EXAMPLES / "hammer.uff"), "--fmin", "50"]
    res = CliRunner().invoke(app, [*args, "--fmax", "50.75", "-o", str(tmp_path / "a.h5")])
    assert res.exit_code == 1
    assert (
        "error: 4 FRF lines between --fmin and --fmax at df = 0.25 Hz (hits of 4 s): too short "
        "for the band"
    ) in res.output
    res = CliRunner().invoke(app, [*args, "--fmax", "51", "-o", str(tmp_path / "b.h5")])
    assert res.exit_code == 0, res.output  # 50, 50.25, ..., 51: 5 lines
    row = read_manifest(EXAMPLES / "campaign.csv")[0]
    assert process_row(row, ProcessingSettings(min_fit_bins=5)).error is None
    bad = process_row(row, ProcessingSettings(min_fit_bins=100_000))
    assert "from hits of 2048 samples = 4 s leaves" in bad.error
    assert "the hits are too short for this band" in bad.error
