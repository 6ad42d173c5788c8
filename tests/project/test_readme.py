"""The README's walk-through runs as written, in order, in an empty folder.

The main command (``robovib demo``), then the first ``bash`` block under "Using it", the one
under "Your own robot" and the one under "Plan the cut". Each command (a line, or a ``for ... done`` block) runs with bash; any
non-zero exit fails the test and names the command. Lines ending in ``# slow`` (a full study)
are skipped unless ``ROBOVIB_README_SLOW=1``; the ``slow``-marked test runs them all.
``robovib`` is this interpreter's ``python -m robovib.cli`` (the checkout under test), or with
``ROBOVIB_README_PYTHON=/path/to/python`` that interpreter (``.ci/run`` points it at a fresh
virtual environment made with the README's install command alone, so the test extras cannot
hide a missing dependency).

Standalone: ``python tests/project/test_readme.py [--slow]`` prints the time of each command.
"""

from __future__ import annotations

import os
import re
import stat
import subprocess
import sys
import time
from pathlib import Path

import pytest

README = Path(__file__).resolve().parents[2] / "README.md"
SLOW = re.compile(r"#\s*slow\b")


SECTIONS = ("## Using it", "## Your own robot", "## Plan the cut")


def _block(text: str, heading: str) -> str:
    section = text.split(heading, 1)[1]
    block = re.search(r"```bash\n(.*?)```", section, re.S)
    assert block, f"no ```bash block under {heading!r} in README.md"
    return block.group(1)


def readme_commands(text: str | None = None) -> list[str]:
    """The shell commands of the main job and of the first ```bash block of each of
    :data:`SECTIONS`, grouped, in order."""
    text = text if text is not None else README.read_text()
    main = re.search(r"pip install -e \. && (robovib [^\n`]*)", text)
    assert main, "README: no 'pip install -e . && robovib ...' main command"
    lines = [main.group(1)]
    for heading in SECTIONS:
        lines += _block(text, heading).splitlines()
    commands, current, depth = [], [], 0
    for line in lines:
        stripped = line.strip()
        if not stripped or (stripped.startswith("#") and not current):
            continue
        current.append(line)
        if re.match(r"(for|while|if)\b", stripped):
            depth += 1
        if re.match(r"(done|fi)\b", stripped):
            depth -= 1
        if depth == 0 and not stripped.endswith("\\"):
            commands.append("\n".join(current))
            current = []
    assert not current, f"unterminated command in README: {current}"
    return commands


def _shim(folder: Path) -> dict:
    """Environment whose ``robovib`` runs this interpreter on this checkout (or the
    interpreter named by ``ROBOVIB_README_PYTHON``, with only what it has installed)."""
    bindir = folder / ".bin"
    bindir.mkdir()
    exe = bindir / "robovib"
    python = os.environ.get("ROBOVIB_README_PYTHON") or sys.executable
    exe.write_text(f'#!/bin/sh\nexec "{python}" -m robovib.cli "$@"\n')
    exe.chmod(exe.stat().st_mode | stat.S_IEXEC)
    env = dict(os.environ)
    env["PATH"] = f"{bindir}{os.pathsep}{env.get('PATH', '')}"
    if not os.environ.get("ROBOVIB_README_PYTHON"):
        src = str(Path(__file__).resolve().parents[2] / "src")
        env["PYTHONPATH"] = src + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
    else:
        env.pop("PYTHONPATH", None)
    env.setdefault("OMP_NUM_THREADS", "1")
    env.setdefault("OPENBLAS_NUM_THREADS", "1")
    env["MPLBACKEND"] = "Agg"
    env["COLUMNS"] = "80"  # a narrow terminal: tables must not cut a number (checked below)
    return env


def run_readme(folder: Path, slow: bool, log=None) -> list[tuple[str, float]]:
    env = _shim(folder)
    timings = []
    for cmd in readme_commands():
        if SLOW.search(cmd) and not slow:
            continue
        t0 = time.perf_counter()
        res = subprocess.run(["bash", "-e", "-o", "pipefail", "-c", cmd], cwd=folder, env=env,
                             capture_output=True, text=True, timeout=1800)  # fmt: skip
        dt = time.perf_counter() - t0
        timings.append((cmd, dt))
        if log:
            log(f"{dt:6.1f} s  {cmd.splitlines()[0][:100]}")
        assert res.returncode == 0, (
            f"README command failed (exit {res.returncode}):\n{cmd}\n--- stderr ---\n"
            f"{res.stderr[-3000:]}\n--- stdout ---\n{res.stdout[-2000:]}"
        )
        cut = re.search(r".{0,30}(\d…|…\d).{0,30}", res.stdout)
        assert cut is None, f"a number cut with '…' at 80 columns:\n{cmd}\n{cut.group(0)}"
    return timings


def test_readme_commands_parse():
    cmds = readme_commands()
    assert len(cmds) >= 20
    assert all(c.lstrip().startswith(("robovib", "for ", "#", "grep ")) for c in cmds), cmds
    fast = [c for c in cmds if not SLOW.search(c)]
    assert len(fast) >= 0.75 * len(cmds), "keep most README commands in the default run"
    # the grouping keeps multi-line loops whole
    assert any(c.startswith("for ") and c.rstrip().endswith("done") for c in cmds)


def test_readme_walkthrough_runs(tmp_path):
    run_readme(tmp_path, slow=os.environ.get("ROBOVIB_README_SLOW") == "1")


@pytest.mark.slow
def test_readme_walkthrough_runs_with_slow_lines(tmp_path):
    run_readme(tmp_path, slow=True)


if __name__ == "__main__":
    import tempfile

    with tempfile.TemporaryDirectory() as d:
        t0 = time.perf_counter()
        run_readme(Path(d), slow="--slow" in sys.argv, log=print)
        print(f"total {time.perf_counter() - t0:.1f} s")
