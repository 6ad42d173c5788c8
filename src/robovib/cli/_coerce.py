"""Light conversion of plain option values, so that running a command does not import Pydantic.

Typer 0.2x converts every parameter value through a Pydantic ``TypeAdapter``: the first value
converted imports Pydantic (~0.13 s of CPU, more than the rest of a pose command's imports
together). ``robovib --help`` converts nothing, so a pose command paid it on top of the
``--help`` floor. Typer's public hooks do not avoid it (``parser=`` is wrapped in an adapter
too, and Typer 0.2x has no ``click_type=``).

:func:`install_light_coercion` gives each parameter of robovib's own command tree a subclass of
its class whose ``process_value`` — click's public step "convert, check missing, run the
callback" — converts the plain cases robovib uses itself: a decimal ``int``/``float`` written
in digits (within the option's ``min``/``max``), any ``str``, a ``bool`` that already is one,
a list of strings, a ``Path`` of an option without path checks, and an absent value. Anything
else — another type, a value that is not plain (``"1_000"``, ``"inf"``, ``" 5"``), one out of
range, a missing required value, a path that exists but cannot be read — goes to Typer's own
``process_value``, so every accepted value converts to what Typer gives and every error message
is Typer's. The parameter's type and settings come from the command function's own annotations
(``Annotated[float, typer.Option(...)]``); no private name of Typer or click is used.
"""

from __future__ import annotations

import os
import re
import typing
from pathlib import Path
from typing import Any

__all__ = ["install_light_coercion"]

_INT = re.compile(r"[+-]?\d+\Z")
_FLOAT = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?\Z")
_NO = object()
_PLAIN = (bool, str, int, float, list[str], Path)
#: Path settings under which Typer only wraps the text in a Path (and checks readability).
_PLAIN_PATH = {"exists": False, "file_okay": True, "dir_okay": True, "writable": False,
               "readable": True, "resolve_path": False, "allow_dash": False, "path_type": None}  # fmt: skip
_LIGHT_CLASSES: dict[type, type] = {}
_LIGHT_COMMANDS: dict[type, type] = {}


class _Plain(typing.NamedTuple):
    """What the light converter needs of one parameter: its type and its range."""

    annotation: Any
    lo: Any
    hi: Any


def _plain_value(plain: _Plain, value: Any, multiple: bool) -> Any:
    """``value`` converted as Typer would, or ``_NO`` where Typer's converter must decide."""
    annotation = plain.annotation
    if value is None:  # absent: Typer gives None, or () for a repeated option
        return () if multiple else None
    if annotation == list[str]:  # a repeated option: Typer gives a list
        ok = isinstance(value, (list, tuple)) and all(isinstance(v, str) for v in value)
        return list(value) if ok else _NO
    if annotation is bool:
        return value if isinstance(value, bool) else _NO
    if annotation is str:
        return value if isinstance(value, str) else _NO
    if annotation is Path:
        if not isinstance(value, (str, Path)) or not str(value):
            return _NO
        if os.path.exists(value) and not os.access(value, os.R_OK):
            return _NO  # Typer words "is not readable"
        return Path(value)
    if annotation is int or annotation is float:
        if isinstance(value, str):
            if not (_INT if annotation is int else _FLOAT).match(value):
                return _NO
            out = annotation(value)
        elif isinstance(value, annotation) and not isinstance(value, bool):
            out = value
        else:
            return _NO
        if (plain.lo is not None and out < plain.lo) or (plain.hi is not None and out > plain.hi):
            return _NO
        return out
    return _NO


def _light_class(base: type) -> type:
    """The subclass of ``base`` (a Typer parameter class) converting plain values itself."""
    if base not in _LIGHT_CLASSES:

        class Light(base):
            robovib_plain: _Plain

            def process_value(self, ctx: Any, value: Any) -> Any:
                out = _plain_value(self.robovib_plain, value, self.multiple or self.nargs == -1)
                if out is _NO or (self.required and self.value_is_missing(out)):
                    return super().process_value(ctx, value)  # Typer decides (and words it)
                if self.callback is not None:
                    out = self.callback(ctx, self, out)
                return out

        Light.__name__ = Light.__qualname__ = f"Light{base.__name__}"
        _LIGHT_CLASSES[base] = Light
    return _LIGHT_CLASSES[base]


def _make_light(p: Any, plain: _Plain) -> None:
    """Give the parameter ``p`` the light converter for ``plain`` (once)."""
    if not isinstance(p, tuple(_LIGHT_CLASSES.values())):
        p.__class__ = _light_class(type(p))
    p.robovib_plain = plain


def _light_command_class(base: type) -> type:
    """The subclass of a command class whose ``--help`` option (made per use) is light too:
    an absent ``--help`` is None, which Typer would convert through Pydantic."""
    if base not in _LIGHT_COMMANDS:

        class LightCommand(base):
            def get_help_option(self, ctx: Any) -> Any:
                option = super().get_help_option(ctx)
                if option is not None and callable(getattr(type(option), "process_value", None)):
                    _make_light(option, _Plain(bool, None, None))
                return option

        LightCommand.__name__ = LightCommand.__qualname__ = f"Light{base.__name__}"
        _LIGHT_COMMANDS[base] = LightCommand
    return _LIGHT_COMMANDS[base]


def _plain_of(hint: Any) -> _Plain | None:
    """The :class:`_Plain` of an annotation ``Annotated[T, typer.Option(...)]``, or None."""
    info = None
    if typing.get_origin(hint) is typing.Annotated:
        hint, *extras = typing.get_args(hint)
        info = next((e for e in extras if hasattr(e, "param_decls")), None)
    args = typing.get_args(hint)
    if type(None) in args and len(args) == 2:  # T | None
        hint = next(a for a in args if a is not type(None))
    if typing.get_origin(hint) is list and typing.get_args(hint) == (str,):
        hint = list[str]
    if hint not in _PLAIN:
        return None
    if info is None:
        return _Plain(hint, None, None)
    if getattr(info, "parser", None) is not None or getattr(info, "clamp", False):
        return None
    if hint is Path and any(getattr(info, k, v) != v for k, v in _PLAIN_PATH.items()):
        return None
    return _Plain(hint, getattr(info, "min", None), getattr(info, "max", None))


def _give_light(command: Any) -> None:
    """Give the plain parameters of one command the light converter."""
    function = getattr(getattr(command, "callback", None), "__wrapped__", None)
    if function is None:
        return
    try:
        hints = typing.get_type_hints(function, include_extras=True)
    except (NameError, TypeError):  # an annotation that does not resolve: Typer converts
        return
    for p in getattr(command, "params", ()):
        plain = _plain_of(hints.get(p.name, None)) if p.name in hints else None
        if (
            plain is None
            or p.nargs not in (1, -1)
            or (p.nargs == -1 and plain.annotation != list[str])
        ):
            continue
        if p.multiple and plain.annotation != list[str]:
            continue
        if callable(getattr(type(p), "process_value", None)):
            _make_light(p, plain)


def install_light_coercion(command: Any) -> None:
    """Give every plain parameter under the click ``command`` the light converter (once)."""
    stack = [command]
    while stack:
        cmd = stack.pop()
        if type(cmd) not in _LIGHT_COMMANDS.values():
            _give_light(cmd)
            if callable(getattr(cmd, "get_help_option", None)):
                cmd.__class__ = _light_command_class(type(cmd))
        stack.extend(getattr(cmd, "commands", {}).values())
