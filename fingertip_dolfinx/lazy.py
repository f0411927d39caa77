"""Names of a package imported from their modules on first use (PEP 562), so that importing
the package, or one light module of it, loads no heavy dependency (DOLFINx, PETSc)."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from importlib import import_module


def lazy_exports(package: str, api: Mapping[str, str]) -> tuple[Callable, Callable]:
    """A package's `__getattr__` and `__dir__` for the names of `api` (name -> module of the
    package that defines it). A name is imported once, then kept in the package's globals."""

    def __getattr__(name: str):
        if name not in api:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(import_module(f".{api[name]}", package), name)
        setattr(import_module(package), name, value)  # later look-ups skip this function
        return value

    def __dir__():
        return sorted(set(vars(import_module(package))) | set(api))

    return __getattr__, __dir__
