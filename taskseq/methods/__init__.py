"""Every method of Table I, one spec each, in one package: the built-in ones and those added beside them.

`spec.py` is what a method is (`MethodSpec`: name, label, factory, policy,
its own settings with their defaults; the experiments that run it are its
entry of params.yaml's `methods` section);
`builtin.py` holds the ten built-in methods in the tables' order, and every
other module of this package adds one method. Importing the package imports
them all (the built-in ones first, then the rest by name), so the list is
whole whenever anyone reads it; nothing outside the package imports a
method's module. `lineup.py` configures the methods for a run from
params.yaml's `methods` section and each method's C (`taskseq.selection`,
which reads selection.json). `docs/adding-a-method.md` walks through adding
one.
"""

from __future__ import annotations

import importlib
import pkgutil

from .builtin import BASELINES, PAPER_METHODS, PAPER_MODEL
from .lineup import Lineup
from .spec import Build, MethodSpec, method_labels, register, specs

MACHINERY = {"builtin", "lineup", "spec"}  # the package's modules that add no method of their own


def load() -> None:
    """Import every module of this package that adds a method, in name order (each registers its spec)."""
    for module in sorted(pkgutil.iter_modules(__path__), key=lambda m: m.name):
        if module.name not in MACHINERY:
            importlib.import_module(f"{__name__}.{module.name}")


load()

__all__ = ["BASELINES", "PAPER_METHODS", "PAPER_MODEL", "Build", "Lineup", "MethodSpec", "load", "method_labels",
           "register", "specs"]
