"""Bad inputs end in one ``error:`` line that names the file and says what is wrong in words
(issue 38, "messages that do not name the file"): never a raw exception text such as
``unexpected IndexError``, ``Format 'tmp' is not supported``, ``outputs [2, 5, 8] have
constant targets``, ``Geometric sequence cannot include zero`` or ``SVD did not converge``.

Each case writes its small input by hand (or with the library's writers) and checks the words
of the one error line: the file's name and the problem.
"""

from __future__ import annotations

import numpy as np
import pytest
from typer.testing import CliRunner

from robovib.cli import app

_MODAL_HEADER = "row,file,direction,x_mm,y_mm,z_mm,rz_deg,fn_hz,stiffness_n_per_m,damping_ns_per_m"
_MODE = "x:30,1e7,0.05"
_RPM = ("--rpm-range", "1000:2000:5")


def _modal_table(rows: int = 6, damping=lambda i: 500.0 + 37 * i, direction="x", fn=None):
    lines = [_MODAL_HEADER]
    for i in range(rows):
        f = fn(i) if fn else f"{15 + 0.3 * i:.3f}"
        lines.append(f"{i + 1},r{i}.uff,{direction},{2100 + 100 * i},{-300 + 150 * i},325,"
                     f"{20 * i},{f},{2e6 + 1e5 * i:.6g},{damping(i):.6g}")  # fmt: skip
    return "\n".join(lines) + "\n"


def _frf_csv(values) -> str:
    return "frequency_hz,x_real_um_per_n,x_imag_um_per_n\n" + "".join(
        f"{f},{v.real},{v.imag}\n" for f, v in zip(range(1, 60), values, strict=False)
    )


def _write(tmp_path, name: str, text: str | bytes) -> str:
    p = tmp_path / name
    p.write_bytes(text if isinstance(text, bytes) else text.encode())
    return name


def _hybrid_one_frf(tmp_path) -> str:
    from robovib.frf import FRF
    from robovib.io import write_frfs
    from robovib.modal import ModalParameters

    f = np.arange(2.0, 40.0, 1.953125)
    frf = FRF(f, ModalParameters(9.0, 1e6, 0.1).compliance(f), direction="x",
              meta={"path_s_m": 0.5})  # fmt: skip
    write_frfs(tmp_path / "one.h5", [frf])
    return "one.h5"


#: id -> (files {name: text}, argv, words the error line must hold)
CASES = {
    "model-fit-text-in-number-column": (
        {"t.csv": _modal_table(fn=lambda i: "abc" if i == 2 else f"{15 + i}")},
        ["model", "fit", "t.csv", "-o", "m.h5"],
        ["t.csv line 4", "fn_hz = 'abc' is not a number"],
    ),
    "model-fit-constant-output-by-name": (
        {"t.csv": _modal_table(damping=lambda i: 1000.0)},
        ["model", "fit", "t.csv", "-o", "m.h5"],
        ["t.csv", "x damping_ns_per_m (= 1000 in all 6 rows)", "constant output"],
    ),
    "model-fit-unknown-direction": (
        {"t.csv": _modal_table(direction="q")},
        ["model", "fit", "t.csv", "-o", "m.h5"],
        ["t.csv", "no row has direction x, y or z", "'q'"],
    ),
    "plot-without-suffix": (
        {},
        ["mill", "lobes", "--mode", _MODE, *_RPM, "--plot", "chart"],
        ["output chart", "no suffix", ".png"],
    ),
    "plot-unknown-suffix": (
        {},
        ["mill", "lobes", "--mode", _MODE, *_RPM, "--plot", "chart.xyz"],
        ["output chart.xyz", ".xyz is not an image format"],
    ),
    "cuts-short-row": (
        {"c.csv": "spindle_rpm,depth_mm,result\n1500,2\n"},
        ["mill", "lobes", "--mode", _MODE, *_RPM, "--cuts", "c.csv"],
        ["c.csv, line 2", "2 cells, expected 3"],
    ),
    "cuts-not-text": (
        {"c.csv": bytes(range(256)) * 4},
        ["mill", "lobes", "--mode", _MODE, *_RPM, "--cuts", "c.csv"],
        ["c.csv", "not a text (UTF-8) cuts file"],
    ),
    "cuts-missing": (
        {},
        ["mill", "lobes", "--mode", _MODE, *_RPM, "--cuts", "nope.csv"],
        ["nope.csv: no such cuts file"],
    ),
    "mode-undamped": (
        {},
        ["mill", "lobes", "--mode", "x:30,1e7,0", *_RPM],
        ["mode 'x:30,1e7,0'", "ZETA must be in (0, 1)"],
    ),
    "mode-negative-stiffness-names-the-mode": (
        {},
        ["mill", "lobes", "--mode", "x:30,-1e7,0.05", *_RPM],
        ["mode 'x:30,-1e7,0.05'", "stiffness_n_per_m must be a positive"],
    ),
    "modal-fit-zero-frf": (
        {"z.csv": _frf_csv([0j] * 59)},
        ["modal", "fit", "z.csv"],
        ["z.csv", "is zero at every frequency"],
    ),
    "modal-fit-flat-frf": (
        {"flat.csv": _frf_csv([1 + 1j] * 59)},
        ["modal", "fit", "flat.csv"],
        ["flat.csv, FRF 0", "no resonance peak"],
    ),
    "lobes-zero-frf": (
        {"z.csv": _frf_csv([0j] * 59)},
        ["mill", "lobes", "--frf", "z.csv", *_RPM],
        ["z.csv", "the FRF x is zero at every frequency"],
    ),
    "forces-one-sample": (
        {"f.csv": "time_s,force_x_n,force_y_n,force_z_n\n0,1,1,1\n"},
        ["mill", "predict", "--x", "2400", "--y", "0", "--rz", "45", "--forces", "f.csv"],
        ["f.csv", "1 sample; a record needs 2 or more"],
    ),
    "forces-time-backwards": (
        {"f.csv": "time_s,force_x_n,force_y_n,force_z_n\n0,1,1,1\n0.002,1,1,1\n0.001,1,1,1\n"},
        ["mill", "predict", "--x", "2400", "--y", "0", "--rz", "45", "--forces", "f.csv"],
        ["f.csv line 4", "time_s = 0.001 does not rise after 0.002"],
    ),
    "frf-output-unknown-format": (
        {},
        ["frf", "compute", "REC", "-o", "out.txt"],
        ["out.txt: unknown FRF file format '.txt'"],
    ),
    "recording-output-without-suffix": (
        {},
        ["sim", "hammer", "-o", "rec", "--hits", "1", "--duration-s", "0.5"],
        ["rec: unknown output format ''"],
    ),
    "frf-compute-zero-force": (
        {
            "r.csv": "time_s,force_n,acceleration_x_m_per_s2\n"
            + "".join(f"{i / 1000},0,0\n" for i in range(2000))
        },
        ["frf", "compute", "r.csv", "-o", "out.h5"],
        ["r.csv", "identically zero"],
    ),
    "sim-campaign-onto-a-file": (
        {"p.csv": "x_mm,y_mm,rz_deg\n2400,0,45\n", "taken": "a file"},
        ["sim", "campaign", "--poses", "p.csv", "-o", "taken", "--hits", "1"],
        ["output folder taken exists and is not a folder"],
    ),
    "path-modes-negative-stiffness": (
        {"s.csv": "s_m,fn_hz,stiffness_n_per_m,damping_ratio\n0.5,16,-2e6,0.05\n"},
        ["control", "schedule", "--path-file", "s.csv"],
        ["s.csv, data row 1", "stiffness_n_per_m must be a positive"],
    ),
    "hybrid-fit-one-frf": (
        {},
        ["hybrid", "fit", "ONE", "-o", "out.h5"],
        ["one.h5", "needs FRFs at 2 or more poses"],
    ),
}


@pytest.mark.parametrize("cid", sorted(CASES))
def test_error_names_the_file_and_the_problem(cid, tmp_path, monkeypatch):
    from robovib.datasets import example_path

    files, argv, words = CASES[cid]
    for name, text in files.items():
        _write(tmp_path, name, text)
    subst = {"REC": str(example_path("hammer.uff"))}
    if "ONE" in argv:
        subst["ONE"] = _hybrid_one_frf(tmp_path)
    argv = [subst.get(a, a) for a in argv]
    monkeypatch.chdir(tmp_path)
    res = CliRunner().invoke(app, argv)
    lines = [ln for ln in res.output.splitlines() if ln.startswith("error:")]
    assert res.exit_code == 1 and len(lines) == 1, res.output
    line = lines[0]
    assert "unexpected" not in line and "Traceback" not in res.output
    for w in words:
        assert w in line, f"{w!r} not in {line!r}"
