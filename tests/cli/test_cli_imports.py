"""What each single-pose command imports (issue 27): heavy modules only where the command uses them.

Each command runs in a fresh interpreter; the modules it loaded are read from ``sys.modules``. ``scipy.signal`` (FRF estimation, ~1 s with ``scipy.stats``) and matplotlib
(plots) are not needed to predict at a pose, draw ZOA lobes or design gains.
"""

from __future__ import annotations

import subprocess
import sys

import pytest

POSE = ["--x", "2400", "--y", "0", "--rz", "45"]
#: Never needed to answer at one pose: FRF estimation (scipy.signal), plotting, fitting
#: (scikit-learn and the SciPy distributions it pulls in).
UNNEEDED = {"scipy.signal", "matplotlib", "sklearn", "scipy.stats", "scipy.optimize",
            "pydantic", "numpy.ma"}  # fmt: skip


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


def _next_poses_args() -> list[str]:
    from robovib.datasets import example_path
    from robovib.gp.chapter3_model import chapter3_model_path

    return ["model", "next-poses", "--model", str(chapter3_model_path()), "--candidates",
            str(example_path("poses.csv")), "--k", "3"]  # fmt: skip


@pytest.mark.parametrize(
    ("args", "used", "unneeded"),
    [
        (["mill", "predict", *POSE], "robovib.milling.at_pose", UNNEEDED | {"scipy", "pandas"}),
        (["mill", "lobes", "--method", "zoa", *POSE], "robovib.milling.lobes",
         UNNEEDED | {"scipy", "pandas"}),
        (["mill", "lobes", "--method", "sdm", "--rpm-range", "1000:3000:4", *POSE],
         "robovib.milling.sdm", UNNEEDED | {"pandas"}),
        # the LQR's Riccati equation and matrix exponential in NumPy (robovib._linalg)
        (["control", "gains", *POSE], "robovib.control.lqr", UNNEEDED | {"scipy", "pandas"}),
        # the candidates CSV and the model read without pandas and scikit-learn
        (None, "robovib.campaign.selection", UNNEEDED | {"scipy", "pandas"}),
    ],
    ids=["mill-predict", "mill-lobes-zoa", "mill-lobes-sdm", "control-gains", "model-next-poses"],
)  # fmt: skip
def test_single_pose_command_loads_only_what_it_computes_with(args, used, unneeded):
    """Issue 27: every single-pose command reads the saved pose model with NumPy and h5py
    (:class:`robovib.gp.saved_model.PosePredictor`), never scikit-learn or SciPy's statistics."""
    imported = _imported(_next_poses_args() if args is None else args)
    assert used in imported  # the report is read right: the command's own module is listed
    assert "robovib.gp.saved_model" in imported
    assert not imported & unneeded, sorted(imported & unneeded)


def test_library_packages_import_light():
    """``import robovib.control / milling / campaign / gp`` pulls neither FRF estimation nor
    scikit-learn: the heavy modules are imported where they are used."""
    code = (
        "import sys, robovib.control, robovib.milling, robovib.campaign, robovib.gp\n"
        "heavy = {'scipy.signal', 'scipy.stats', 'sklearn', 'matplotlib', 'pandas'}\n"
        "print(sorted(heavy & set(sys.modules)))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.stdout.strip() == "[]", out.stdout + out.stderr[-2000:]


def test_lazy_packages_still_export_every_name():
    """``robovib.frf`` / ``modal`` / ``campaign`` load names on first use; all of ``__all__``
    resolves."""
    code = (
        "import sys, robovib.frf as f, robovib.modal as m, robovib.campaign as c\n"
        "assert 'scipy.signal' not in sys.modules\n"
        "from robovib.modal import ModalParameters\n"
        "assert 'scipy.signal' not in sys.modules\n"
        "missing = [n for p in (f, m, c) for n in p.__all__ if getattr(p, n, None) is None]\n"
        "assert not missing, missing\n"
        "assert 'scipy.signal' in sys.modules\n"
        "print('ok')\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.stdout.strip() == "ok", out.stderr[-2000:]
