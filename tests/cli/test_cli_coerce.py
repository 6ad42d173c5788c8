"""The CLI's light option conversion (``robovib.cli._coerce``) against Typer's own converter.

Typer 0.2x converts every option value through Pydantic (imported on the first conversion, ~0.2 s);
robovib converts plain values itself. The reference is the same Typer app without the light
converter: every value must come out the same, every error with the same message.
"""

from __future__ import annotations

import re
import tomllib
from importlib import metadata
from pathlib import Path
from typing import Annotated

import click
import pytest
import typer

from robovib.cli._coerce import install_light_coercion


def _command(light: bool):
    got: dict = {}
    app = typer.Typer(add_completion=False)

    @app.command()
    def run(
        x: Annotated[float, typer.Option()] = 1.0,
        n: Annotated[int, typer.Option(min=1, max=9)] = 2,
        name: Annotated[str, typer.Option()] = "a",
        path: Annotated[Path | None, typer.Option()] = None,
        mode: Annotated[list[str] | None, typer.Option()] = None,
        flag: Annotated[bool, typer.Option()] = False,
    ) -> None:
        got.update(x=x, n=n, name=name, path=path, mode=mode, flag=flag)

    cmd = typer.main.get_command(app)
    if light:
        install_light_coercion(cmd)
    return cmd, got


def _run(args: list[str], light: bool):
    cmd, got = _command(light)
    try:
        cmd.main(args, standalone_mode=False)
    except click.exceptions.ClickException as exc:
        return ("error", exc.format_message())
    except Exception as exc:  # the vendored click's exceptions in recent Typer
        if hasattr(exc, "format_message"):
            return ("error", exc.format_message())
        raise
    return ("ok", {k: (v, type(v)) for k, v in got.items()})


@pytest.mark.parametrize(
    "args",
    [
        [],
        ["--x", "2400", "--n", "3", "--name", "zoa", "--flag"],
        ["--x", "-1.5e-3", "--n", "+9"],
        ["--x", ".5", "--n", "1"],
        ["--x", "7."],
        ["--path", "some/file.h5", "--mode", "1", "--mode", "b"],
        # not plain: Typer's converter decides (accepts or words the error)
        ["--x", "1_000"],
        ["--x", "inf"],
        ["--x", " 5"],
        ["--n", "2.0"],
        ["--x", "abc"],
        ["--n", "abc"],
        ["--n", "0"],
        ["--n", "10"],
        ["--x", ""],
        ["--path", __file__],  # an existing, readable file
        ["--path", ""],
        ["--mode"],
    ],
)
def test_light_conversion_gives_what_typer_gives(args):
    assert _run(args, light=True) == _run(args, light=False)


def _version(text: str) -> tuple[int, ...]:
    return tuple(int(re.match(r"\d+", part).group()) for part in text.split(".")[:3])


def test_typer_is_inside_the_pinned_range():
    """pyproject bounds Typer from above: a Typer release can change how every option converts,
    so a Typer outside the range fails here (it is never skipped)."""
    pyproject = tomllib.loads((Path(__file__).parents[2] / "pyproject.toml").read_text())
    spec = next(d for d in pyproject["project"]["dependencies"] if d.startswith("typer"))
    bounds = dict(re.findall(r"(>=|<)\s*([\d.]+)", spec))
    assert set(bounds) == {">=", "<"}, f"typer needs a lower and an upper bound, got {spec!r}"
    installed = _version(metadata.version("typer"))
    assert _version(bounds[">="]) <= installed < _version(bounds["<"]), (installed, spec)


def test_light_conversion_is_installed_on_the_robovib_tree():
    """Every plain parameter of ``mill predict`` gets the light converter, and a whole pose
    command runs without importing Pydantic (the cost the converter exists to avoid)."""
    import subprocess
    import sys

    from robovib.cli import app

    cmd = typer.main.get_command(app)
    install_light_coercion(cmd)
    install_light_coercion(cmd)  # idempotent: one subclass level
    predict = cmd.commands["mill"].commands["predict"]
    kinds = {p.name: type(p).__name__ for p in predict.params}
    assert set(kinds.values()) == {"LightTyperOption"}, kinds
    code = (
        "import sys\nfrom robovib.cli import app\n"
        "try:\n    app(['gpr', 'predict', '--x', '2400', '--y', '0', '--rz', '45', '--json'])\n"
        "except SystemExit as exc:\n    assert exc.code in (0, None), exc.code\n"
        "print(sorted(m for m in sys.modules if m.split('.')[0] == 'pydantic'))\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.strip().splitlines()[-1] == "[]", done.stdout[-500:]
