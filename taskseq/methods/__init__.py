"""Every method of Table I, one spec each, in one package: the built-in ones and those added beside them.

`spec.py` is what a method is (`MethodSpec`: name, label, factory, policy,
its own settings with their defaults; the experiments that run it are its
entry of params.yaml's `methods` section) and the registry of them;
`builtin.py` holds the ten built-in methods in the tables' order, and every
other module of this package adds one method, named as the module. A method's
module is imported when its spec is asked for (`method_spec`), every one when
the whole list is (`specs`), so a stage loads the code of the methods it runs
and no other; nothing outside the package imports a method's module. The
labels the tables print are kept in `labels.json` (`method_labels`), which
`scripts/stage_deps.py` writes from the specs, so the stages that only write
tables load no method's code. `lineup.py` configures the methods for a run from params.yaml's
`methods` section and each method's C (`taskseq.selection`, which reads
selection.json). `docs/adding-a-method.md` walks through adding one.
"""

from __future__ import annotations

from .builtin import BASELINES, PAPER_METHODS, PAPER_MODEL
from .lineup import Lineup
from .spec import Build, MethodSpec, load, method_labels, method_names, method_spec, register, specs

__all__ = ["BASELINES", "PAPER_METHODS", "PAPER_MODEL", "Build", "Lineup", "MethodSpec", "load", "method_labels",
           "method_names", "method_spec", "register", "specs"]
