"""simulate_milling's band-limited force computed in blocks (a long pass's fine grid would be
tens of millions of samples): the same numbers as one pass, the closed form's tooth line."""

import numpy as np

from robovib.milling import ALUMINIUM_7075, CuttingConditions, MillingTool
from robovib.milling.forces import milling_forces
from robovib.sim import experiments

TOOL = MillingTool()
COND = CuttingConditions(1750.0, 0.058e-3, 2e-3, 6e-3)
FS = 1000.0


def _cutting(t):
    return milling_forces(t, TOOL, COND, ALUMINIUM_7075)


def test_blocks_give_the_one_pass_force():
    n, k = 3000, 32
    whole = experiments._band_limited_force(_cutting, n, FS, k)
    for block in (400, 1000, 2999, 3000, 5000):  # fine blocks > milling_forces' 3600 angles
        got = experiments._band_limited_force(_cutting, n, FS, k, block)
        assert got.shape == (n, 3)
        np.testing.assert_array_equal(got, whole)  # the same operations per sample
    # the tooth line is the closed form's Fourier coefficient (the FIR passes it flat),
    # over a whole number of tooth periods (7 periods = 120 samples at 58.33 Hz)
    f_tooth = 2 * 1750.0 / 60.0
    x = experiments._band_limited_force(_cutting, n, FS, k, 1000)[: n // 120 * 120, 0]
    t = np.arange(x.size) / FS
    line = 2.0 / x.size * abs(np.sum(x * np.exp(-2j * np.pi * f_tooth * t)))
    fine = np.arange(4096) / (4096 * f_tooth)
    coef = 2.0 / 4096 * abs(np.fft.rfft(_cutting(fine)[:, 0])[1])
    np.testing.assert_allclose(line, coef, rtol=1e-3)
