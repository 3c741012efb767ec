"""A subpackage's public names, loaded from their modules on first use (SciPy's lazy loading).

A subpackage's ``__init__`` lists its names by home module and takes `attach`'s ``__all__``,
``__getattr__`` and ``__dir__``: importing the subpackage imports none of its modules, and
``dtdyn.linear.chain_response`` is the very object ``dtdyn.chain_response`` is (`dtdyn` puts the
keyword-checked function into the home module before any first use)."""
from __future__ import annotations

import importlib

__all__: list[str] = []


def attach(package: str, homes: dict[str, list[str]]):
    """``__all__``, ``__getattr__`` and ``__dir__`` for ``package``, whose public names live in
    its modules ``homes`` (module name -> the names it defines)."""
    where = {name: module for module, names in homes.items() for name in names}

    def __getattr__(name: str):
        if name not in where:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        return getattr(importlib.import_module(f"{package}.{where[name]}"), name)

    def __dir__() -> list[str]:
        return sorted(set(importlib.import_module(package).__dict__) | set(where))

    return list(where), __getattr__, __dir__
