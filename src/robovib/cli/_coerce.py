"""Light conversion of plain option values, so that running a command does not import Pydantic.

Recent Typer (0.2x, with ``typer._click``) converts every parameter value through a Pydantic
``TypeAdapter``: the first command-line value converted imports Pydantic (~0.2 s, more than the
rest of a pose command's imports together) and builds one adapter per parameter. ``robovib
--help`` converts nothing, so a pose command paid it on top of the ``--help`` floor.

:func:`install_light_coercion` gives each parameter of robovib's own command tree a converter
for the plain cases robovib uses: a decimal ``int``/``float`` written in digits (within the
option's ``min``/``max``), any ``str``, a ``bool`` that already is one, a ``Path`` without a
custom path type. Anything else — another type, a list or tuple, a value that is not plain
(``"1_000"``, ``"inf"``, ``" 5"``), one out of range — goes to Typer's own converter, so every
accepted value converts to what Typer gives and every error message is Typer's. With an older
Typer (plain click, no ``_runtime_param``) nothing is changed.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

__all__ = ["install_light_coercion"]

_INT = re.compile(r"[+-]?\d+\Z")
_FLOAT = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?\Z")
_NO = object()


def _plain_value(annotation: Any, info: Any, value: Any) -> Any:
    """``value`` converted to ``annotation``, or ``_NO`` where Typer's converter must decide."""
    if annotation == list[str]:  # a repeated option: Typer gives a list
        ok = isinstance(value, (list, tuple)) and all(isinstance(v, str) for v in value)
        return list(value) if ok else _NO
    if annotation is bool:
        return value if isinstance(value, bool) else _NO
    if annotation is str:
        return value if isinstance(value, str) else _NO
    if annotation is int or annotation is float:
        if isinstance(value, str):
            if not (_INT if annotation is int else _FLOAT).match(value):
                return _NO
            out = annotation(value)
        elif isinstance(value, annotation) and not isinstance(value, bool):
            out = value
        else:
            return _NO
        if getattr(info, "clamp", False):
            return _NO
        lo, hi = getattr(info, "min", None), getattr(info, "max", None)
        if (lo is not None and out < lo) or (hi is not None and out > hi):
            return _NO
        return out
    return _NO


def _light_class(coercion: Any, param_types: Any) -> type:
    """The ``RuntimeParam`` subclass converting plain values itself (built once)."""
    from dataclasses import dataclass

    @dataclass(frozen=True)
    class _LightRuntimeParam(coercion.RuntimeParam):
        descriptor: Any = None
        is_path: bool = False

        def _coerce_value(self, value: Any, param: Any, ctx: Any) -> Any:
            info = self.parameter_info
            if self.is_path:
                if isinstance(value, (str, Path)) and str(value):
                    return param_types.coerce_cli_path(
                        Path(value), info, path_type=Path, param=param, ctx=ctx
                    )
                out = _NO
            else:
                out = _plain_value(self.annotation, info, value)
            if out is _NO:  # Typer decides (and words the error)
                full = coercion.build_runtime_param(self.descriptor)
                return full._coerce_value(value, param=param, ctx=ctx)
            return out

    return _LightRuntimeParam


def _light_runtime_param(descriptor: Any, light_class: type) -> Any:
    """A light ``RuntimeParam`` for ``descriptor``, or None (keep Typer's)."""
    annotation = descriptor.annotation
    info = descriptor.parameter_info
    if descriptor.file_annotation is not None or getattr(info, "parser", None) is not None:
        return None
    is_path = annotation is Path and getattr(info, "path_type", None) is None
    if annotation not in (bool, str, int, float, list[str]) and not is_path:
        return None
    return light_class(
        parameter_info=info, annotation=annotation, descriptor=descriptor, is_path=is_path
    )


def install_light_coercion(command: Any) -> None:
    """Give every parameter under the click ``command`` the light converter where it applies."""
    try:
        from typer import _coercion as coercion
        from typer import _param_types as param_types
    except ImportError:  # older Typer: click converts, no Pydantic
        return
    if not all(hasattr(coercion, n) for n in ("RuntimeParam", "build_runtime_param")):
        return
    if not hasattr(param_types, "coerce_cli_path"):
        return
    light_class = _light_class(coercion, param_types)
    stack = [command]
    while stack:
        cmd = stack.pop()
        for p in getattr(cmd, "params", ()):
            _give_light(p, light_class)
        if callable(getattr(cmd, "get_help_option", None)):
            _light_help(cmd, light_class)
        stack.extend(getattr(cmd, "commands", {}).values())


def _give_light(p: Any, light_class: type) -> None:
    """Set the light converter on the Typer parameter ``p`` where it applies."""
    descriptor = getattr(p, "type_descriptor", None)
    if descriptor is None or getattr(p, "_runtime_param", _NO) is not None:
        return
    if p.nargs != 1 or (p.multiple and descriptor.annotation != list[str]):
        return
    light = _light_runtime_param(descriptor, light_class)
    if light is not None:
        p._runtime_param = light


def _light_help(cmd: Any, light_class: type) -> None:
    """The ``--help`` option (made on first use, per command) gets the light converter too."""
    original = cmd.get_help_option

    def get_help_option(ctx: Any) -> Any:
        option = original(ctx)
        if option is not None:
            _give_light(option, light_class)
        return option

    cmd.get_help_option = get_help_option
