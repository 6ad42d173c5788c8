"""The command line serves blocks from the heap and keeps freed heap (glibc ``mallopt``): the
charts' stream of numpy temporaries no longer page-faults every block in again (16.7 s of
system CPU on a 100-sample ``mill lobes`` before)."""

import subprocess
import sys
import textwrap

import pytest

import robovib.cli
from robovib.cli import _malloc

# Batches of temporaries the size of the dense chart's (a (200, 40, 8, 8) block stack, 4 MiB,
# through powers and sums as in the Pade approximant), freed together after each batch.
CHURN = textwrap.dedent(
    """
    import resource, sys
    import numpy as np
    from robovib.cli._malloc import keep_freed_heap
    took = keep_freed_heap() if sys.argv[1] == "pad" else None
    a = np.random.default_rng(0).normal(size=(8000, 8, 8)) * 0.1
    def batch():
        a2 = a @ a
        a4 = a2 @ a2
        return (3.0 * a4 + 2.0 * a2 + a).sum()
    batch()
    f0 = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
    for _ in range(40):
        batch()
    print(took, resource.getrusage(resource.RUSAGE_SELF).ru_minflt - f0)
    """
)


def _faults(mode):
    out = subprocess.run([sys.executable, "-c", CHURN, mode], capture_output=True, text=True,
                         check=True, timeout=120).stdout.split()  # fmt: skip
    return out[0], int(out[1])


def test_kept_heap_stops_the_page_fault_churn():
    if not sys.platform.startswith("linux"):
        pytest.skip("mallopt is glibc's")
    took, with_pad = _faults("pad")
    if took != "True":
        pytest.skip("no glibc mallopt here (musl)")
    _, default = _faults("default")
    # 40 batches of ~6 blocks of 4 MiB: ~1000 pages each faulted in again by default.
    assert default > 40 * 1000
    assert with_pad < default / 20


def test_main_sets_it_before_the_command(monkeypatch, capsys):
    calls = []
    monkeypatch.setattr(_malloc, "keep_freed_heap", lambda: calls.append("pad") or True)
    monkeypatch.setattr(sys, "argv", ["robovib", "--version"])
    with pytest.raises(SystemExit):
        robovib.cli.main()
    assert calls == ["pad"]
    assert "robovib" in capsys.readouterr().out
