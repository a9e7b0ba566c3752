"""Table I's methods by name: the built-in ones' labels, and the methods that modules register.

It imports nothing of the methods: a module of `taskseq.methods` imports
this one and registers its method here (`register`), never the other way
round. Whoever needs every method (the stages that run or print them)
imports the package `taskseq.methods`, which imports each of its modules and
then marks the list whole (`completed`); asking for the list before that is
an error, not a Table I silently short of its added rows.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

# The built-in methods, in the tables' order, as the tables print them.
BUILT_IN_LABELS = {
    "chance": "chance",
    "multiclass": "multiclass",
    "symb_plan_svm": "symb-plan-svm",
    "symb_plan_manual": "symb-plan-manual",
    "only_edge": "only edge features",
    "only_clique": "only clique features",
    "full": "ours - full",
    # beyond the paper: relation features, then those with one kind of training data beyond the logs each;
    # their rows sit below the paper-faithful ones in every table
    "relations": "ours + relations",
    "chained": "ours + relations + chained starts",
    "dagger": "ours + relations + dagger",
}

# the paper's rows of Table I; every other method is an addition beside them. Its baselines come first.
PAPER_METHODS = ("chance", "multiclass", "symb_plan_svm", "symb_plan_manual", "only_edge", "only_clique", "full")
BASELINES = PAPER_METHODS[:4]
PAPER_MODEL = "full"  # the paper's own model, as published


@dataclass(frozen=True)
class MethodSettings:
    """What a method's factory is given: the settings in force (`taskseq.settings`) and the model store."""

    crossval: Any  # settings.Crossval: baselines' seeds and C
    learner: Any  # settings.Learner: the structural SVM's settings, C as `select` chose it
    horizon: int  # longest plan of symbolic planners
    store: str | None  # folder of fold models (`fold_models` stage); an MRF method loads its models from it


@dataclass(frozen=True)
class AddedMethod:
    name: str  # its key in every table, file and run
    label: str  # its row name in the tables
    make: Callable[[MethodSettings], Any]  # an unfitted method (`taskseq.evaluate.methods.Method`)


_ADDED: dict[str, AddedMethod] = {}
_complete = False  # every module of `taskseq.methods` has registered


def register(name: str, label: str) -> Callable[[Callable[[MethodSettings], Any]], Callable[[MethodSettings], Any]]:
    """Decorate a factory `make(settings) -> method` to add the method to Table I as `name`, printed `label`."""
    if not name.isidentifier():
        raise ValueError(f"method name {name!r} must be a Python identifier (it names files and runs)")

    def add(make: Callable[[MethodSettings], Any]) -> Callable[[MethodSettings], Any]:
        if name in BUILT_IN_LABELS or (name in _ADDED and _ADDED[name].make is not make):
            raise ValueError(f"method {name!r} is registered twice")
        _ADDED[name] = AddedMethod(name, label, make)
        return make

    return add


def completed() -> None:
    """Mark the list of added methods whole: `taskseq.methods` calls it once each of its modules has registered."""
    global _complete
    _complete = True


def added_methods() -> dict[str, AddedMethod]:
    """Every method the modules of `taskseq.methods` register, by name (in name order).

    Raises `RuntimeError` until `taskseq.methods` has been imported.
    """
    if not _complete:
        raise RuntimeError("the added methods are not registered yet: import taskseq.methods first (its modules "
                           "register them)")
    return dict(sorted(_ADDED.items()))


def method_labels() -> dict[str, str]:
    """Every method's label, built-in ones first in Table I's order, then the added ones by name."""
    return {**BUILT_IN_LABELS, **{name: m.label for name, m in added_methods().items()}}
