"""What each single-pose command imports (issue 27): heavy modules only where the command uses them.

Each command runs in a fresh interpreter; the modules it loaded are read from ``sys.modules``. ``scipy.signal`` (FRF estimation, ~1 s with ``scipy.stats``) and matplotlib
(plots) are not needed to predict at a pose, draw ZOA lobes or design gains.
"""

from __future__ import annotations

import subprocess
import sys

import pytest

POSE = ["--x", "2400", "--y", "0", "--rz", "45"]
UNNEEDED = {"scipy.signal", "matplotlib"}


_RUN = """
import sys
from robovib.cli import app
try:
    app(sys.argv[1:], standalone_mode=False)
finally:
    print("MODULES:" + ",".join(sorted(sys.modules)), file=sys.stderr)
"""


def _imported(args: list[str]) -> set[str]:
    """``sys.modules`` after the command ran in a fresh interpreter (the whole command: options,
    computation, JSON rendering). ``-X importtime`` would miss modules that SciPy loads through
    its own lazy ``__getattr__``, such as ``scipy.signal``."""
    cmd = [sys.executable, "-c", _RUN, *args, "--json"]
    out = subprocess.run(cmd, capture_output=True, text=True)
    assert out.returncode == 0, out.stderr[-2000:]
    line = [ln for ln in out.stderr.splitlines() if ln.startswith("MODULES:")][-1]
    return set(line.removeprefix("MODULES:").split(","))


@pytest.mark.parametrize(
    ("args", "used"),
    [
        (["mill", "predict", *POSE], "robovib.milling.workflow"),
        (["mill", "lobes", "--method", "zoa", *POSE], "robovib.milling.lobes"),
        (["control", "gains", *POSE], "robovib.control.lqr"),
    ],
    ids=["mill-predict", "mill-lobes-zoa", "control-gains"],
)
def test_single_pose_command_skips_frf_estimation_and_plotting(args, used):
    imported = _imported(args)
    assert used in imported  # the report is read right: the command's own module is listed
    assert not imported & UNNEEDED, sorted(imported & UNNEEDED)


def test_lazy_packages_still_export_every_name():
    """``robovib.frf`` / ``robovib.modal`` load names on first use; all of ``__all__`` resolves."""
    code = (
        "import sys, robovib.frf as f, robovib.modal as m\n"
        "assert 'scipy.signal' not in sys.modules\n"
        "from robovib.modal import ModalParameters\n"
        "assert 'scipy.signal' not in sys.modules\n"
        "missing = [n for p in (f, m) for n in p.__all__ if getattr(p, n, None) is None]\n"
        "assert not missing, missing\n"
        "assert 'scipy.signal' in sys.modules\n"
        "print('ok')\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.stdout.strip() == "ok", out.stderr[-2000:]
