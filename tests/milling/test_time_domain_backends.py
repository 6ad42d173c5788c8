"""The time-domain margin without its compiled loop: numba missing, ``NUMBA_DISABLE_JIT=1``,
and a cache folder numba cannot write (a read-only install with no writable home)."""

import sys
from dataclasses import replace

import numba
import numpy as np
import pytest

from robovib.milling import ALUMINIUM_7075, CuttingConditions, MillingTool, time_domain
from robovib.milling.sdm import sdm_lobes
from robovib.milling.time_domain import simulate_regenerative_cut, time_domain_limit_ratios
from robovib.modal import ModalParameters

TOOL = MillingTool()
COND = CuttingConditions(1750.0, 0.058e-3, 3e-3, 6e-3)
MX = [ModalParameters(15.615, 3.6648e6, 0.1146)]
MY = [ModalParameters(8.03, 0.8954e6, 0.1803)]
SIM = dict(steps_per_tooth=40, n_tooth_periods=60)


@pytest.fixture
def fresh_loop(monkeypatch):
    """The compiled loop looked up again in this test (the module keeps it once found)."""
    monkeypatch.delitem(time_domain._COMPILED, "loop", raising=False)


def _brackets_match_single_cuts():
    # The margin's brackets against single simulate_regenerative_cut runs (numpy stepping) at
    # every factor: the reference that does not use the loop under test.
    rpm = np.array([1750.0, 2600.0, 3100.0])
    factors, above = (0.5, 0.8, 0.9), (1.1, 1.6)
    lim = sdm_lobes(MX, MY, TOOL, COND, ALUMINIUM_7075, rpm).a_lim_m[None, :]
    low, high = time_domain_limit_ratios([(MX, MY)], TOOL, COND, ALUMINIUM_7075, rpm, lim,
                                         factors=factors, above=above, **SIM)  # fmt: skip
    grid = np.array([*factors, *above])
    onsets = []
    for r, speed in enumerate(rpm):
        chat = simulate_regenerative_cut(MX, MY, TOOL, replace(COND, spindle_rpm=speed),
                                         ALUMINIUM_7075, lim[0, r] * grid, **SIM).chatter  # fmt: skip
        run = int(np.argmin(chat[::-1])) if not chat.all() else chat.size  # chattering at top
        onset = chat.size - run
        assert 0 < onset < chat.size  # stable below, chatter at the top: a bracket inside
        assert (low[0, r], high[0, r]) == (grid[onset - 1], grid[onset])
        onsets.append(onset)
    assert len(set(onsets)) > 1 and max(onsets) >= len(factors)  # above the limit as well


def test_without_numba_the_numpy_stepping_gives_the_margin(monkeypatch, fresh_loop):
    monkeypatch.setitem(sys.modules, "numba", None)  # `import numba` raises ImportError
    assert time_domain._compiled_loop() is None
    _brackets_match_single_cuts()


def test_numba_disable_jit_takes_the_numpy_stepping(monkeypatch, fresh_loop):
    # The interpreted loop would take ~0.5 s per cut; the numpy stepping is used instead.
    monkeypatch.setattr(numba.config, "DISABLE_JIT", True)
    assert time_domain._compiled_loop() is None
    _brackets_match_single_cuts()


def test_an_unwritable_cache_compiles_without_caching(monkeypatch, fresh_loop):
    from numba.core import caching

    # No cache locator applies (source folder and user cache folder both read-only): numba's
    # own `cache=True` then raises; the loop is compiled uncached instead.
    # The class name differs between numba versions.
    impl = getattr(caching, "CacheImpl", None) or caching._CacheImpl
    monkeypatch.setattr(impl, "_locator_classes", [])
    with pytest.raises(RuntimeError, match="cannot cache"):
        numba.njit(cache=True)(time_domain._poincare_loop)
    loop = time_domain._compiled_loop()
    assert isinstance(loop, numba.core.registry.CPUDispatcher)
    assert isinstance(loop._cache, caching.NullCache)


def test_an_unknown_backend_is_refused():
    fn, k, z = np.array([[15.6]]), np.array([[3.7e6]]), np.array([[0.1]])
    with pytest.raises(ValueError, match="backend must be 'numba' or 'numpy', got 'cuda'"):
        time_domain._poincare_rows(fn, k, z, np.array([[True]]), np.array([1750.0]),
                                   np.array([1e-3]), TOOL, COND, ALUMINIUM_7075,
                                   backend="cuda", entry_tooth_periods=0, **SIM)  # fmt: skip
