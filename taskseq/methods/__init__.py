"""Methods added beside Table I's, one module each.

Importing this package imports every module in it, in name order, and each
registers its method with `@register(name, label)`
(`taskseq.evaluate.registry`); then the registry's list is whole. The stages
that run or print every method import this package; nothing below them
does, so the methods import the registry and the registry imports none of
them. From then on a method has a row in Table I (per world and over
worlds), a child run in MLflow, and, when it is an MRF method, its fold
models in the model store. `docs/extending.md` walks through adding one.
"""

from __future__ import annotations

import importlib
import pkgutil

from ..evaluate import registry


def load() -> None:
    """Import every module of this package (each registers its method), in name order; then mark the list whole."""
    for module in sorted(pkgutil.iter_modules(__path__), key=lambda m: m.name):
        importlib.import_module(f"{__name__}.{module.name}")
    registry.completed()


load()
