"""Names of a package imported on first use (PEP 562), so that a command loads only what it uses."""

from __future__ import annotations

import sys
from collections.abc import Callable
from importlib import import_module


def lazy_exports(
    package: str, where: dict[str, str]
) -> tuple[Callable[[str], object], Callable[[], list[str]]]:
    """Module-level ``__getattr__`` and ``__dir__`` for a package whose names load lazily.

    Parameters
    ----------
    package : str
        The package's ``__name__``.
    where : dict
        Public name -> submodule (relative to the package) that defines it.

    Returns
    -------
    (__getattr__, __dir__)
        To assign in the package's ``__init__``; a name, once loaded, is cached in the package.

    Examples
    --------
    >>> getattr_, dir_ = lazy_exports("robovib.modal", {"ModalParameters": "parameters"})
    >>> getattr_("ModalParameters").__name__
    'ModalParameters'
    """

    def __getattr__(name: str) -> object:
        if name in where:
            value = getattr(import_module(f".{where[name]}", package), name)
            setattr(sys.modules[package], name, value)
            return value
        raise AttributeError(f"module {package!r} has no attribute {name!r}")

    def __dir__() -> list[str]:
        return sorted(set(vars(sys.modules[package])) | set(where))

    return __getattr__, __dir__
