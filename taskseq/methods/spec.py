"""A Table I method as one spec: its name, label, estimator factory, policy, and own settings with defaults.

Every method, built in (`builtin.py`) or added (a module of its own beside it,
named as the method), registers one `MethodSpec` here with `register`. A
method's module is imported when someone asks for its spec (`method_spec`),
and every one when someone asks for the whole list (`specs`); the names are
known without importing any (`method_names`). So a stage that runs some
methods loads the code of those only, and DVC re-runs it only when that code
changes (`scripts/stage_deps.py`).
"""

from __future__ import annotations

import importlib
import json
import pkgutil
import sys
from collections.abc import Callable, Iterable
from dataclasses import MISSING, dataclass, fields, is_dataclass
from functools import cache
from pathlib import Path
from typing import Any

from ..evaluate.methods import Method, ScorerMethod
from ..plan.planner import POLICIES
from ..runtime.dvc_deps import undeclared
from ..settings import Crossval, Learner, Procedural

OWN = ""  # `MethodSpec.C_from` for a method whose C is its own entry of selection.json


@dataclass(frozen=True)
class NoSettings:
    """The settings of a method that has none of its own."""


@dataclass(frozen=True)
class Build:
    """What a spec's factory is given to make one unfitted method: everything in force for it, resolved."""

    name: str
    policy: str  # how its programs pick a step (`plan.planner.POLICIES`)
    C: float | None  # its slack weight as selection.json gives it (None for a method that takes none)
    learner: Learner  # the structural SVM's other settings (`train` section)
    crossval: Crossval  # the baselines' seeds and C
    horizon: int  # longest plan of symbolic planners
    store: str | None  # folder of fold models (`fold_models` stage); an MRF method loads its models from it
    settings: Any  # its own settings: an instance of the spec's `settings` class, as params.yaml sets them
    procedural: Procedural = Procedural()  # the distribution of rooms a world of drawn rooms is drawn from

    def mrf(self, features: str, **options: Any) -> ScorerMethod:
        """The paper's model with these features, and `options` (`ScorerMethod`'s fields) as the method has them."""
        if self.C is None:
            raise ValueError(f"method {self.name}: an MRF method needs a C (its spec's C_from is None)")
        return ScorerMethod(features=features, C=self.C, tol=self.learner.tol, max_iter=self.learner.max_iter,
                         n_slacks=self.learner.n_slacks, name=self.name, store=self.store, policy=self.policy,
                         **options)


@dataclass(frozen=True)
class MethodSpec:
    """One method of Table I. Its own settings are a frozen dataclass whose defaults hold where params.yaml does not
    set them (`methods.NAME.KEY`); the experiments beside Table I that run it are written once, in its entry of
    params.yaml (`methods.NAME.experiments`; none without an entry); `C_from` names the method whose entry of
    selection.json is its C."""

    name: str  # its key in every table, file, run and the model store: a Python identifier
    label: str  # its row name in the tables
    make: Callable[[Build], Method]  # an unfitted method
    policy: str = "greedy"
    settings: type = NoSettings
    C_from: str | None = OWN  # OWN: its own C; another method's name (the ablations take full's); None: no C

    def __post_init__(self) -> None:
        if not self.name.isidentifier():
            raise ValueError(f"method name {self.name!r} must be a Python identifier (it names files and runs)")
        if self.policy not in POLICIES:
            raise ValueError(f"method {self.name}: unknown policy {self.policy!r}; known: {', '.join(POLICIES)}")
        if not is_dataclass(self.settings) or any(
                f.default is MISSING and f.default_factory is MISSING for f in fields(self.settings)):
            raise ValueError(f"method {self.name}: its settings must be a dataclass with a default for each field")

    @property
    def tuned_as(self) -> str | None:
        """The method whose C selection.json gives this one, or None."""
        return self.name if self.C_from == OWN else self.C_from


_SPECS: dict[str, MethodSpec] = {}
MACHINERY = {"builtin", "lineup", "spec"}  # the package's modules that add no method of their own


def register(spec: MethodSpec) -> MethodSpec:
    """Add a method to Table I. A module of this package that adds one is named as its method (the method
    `noise_trained` is `taskseq/methods/noise_trained.py`), so that a stage loads the modules of exactly the
    methods it runs (`method_spec`)."""
    module = getattr(spec.make, "__module__", "") or ""
    home = module.removeprefix(f"{__package__}.")
    if module.startswith(f"{__package__}.") and home not in MACHINERY and home != spec.name:
        raise ValueError(f"method {spec.name!r} is registered by taskseq/methods/{home}.py: a module that adds a "
                         f"method is named as the method ({spec.name}.py)")
    if spec.name in _SPECS and _SPECS[spec.name] != spec:
        raise ValueError(f"method {spec.name!r} is registered twice")
    _SPECS[spec.name] = spec
    return spec


def added_modules() -> list[str]:
    """The names of the package's modules that add a method, sorted (none of them imported)."""
    package = sys.modules[__package__]  # its __path__ as it is now (a test adds a folder to it)
    return sorted(m.name for m in pkgutil.iter_modules(package.__path__) if m.name not in MACHINERY)


def load() -> None:
    """Import every module of the package that adds a method (each registers its spec)."""
    importlib.import_module(f"{__package__}.builtin")
    for name in added_modules():
        _import_method(name)


def _import_method(name: str) -> None:
    """Import the module that adds method `name`; under `dvc repro`, `ValueError` if the running stage's deps do not
    list it (`runtime.dvc_deps`), before the stage does any work with it."""
    module = importlib.import_module(f"{__package__}.{name}")
    problem = undeclared(module.__file__) if module.__file__ else None
    if problem:
        raise ValueError(f"{problem}; it runs method {name!r} (params.yaml's methods.{name}.experiments). Run "
                         "`python scripts/stage_deps.py`, which writes every stage's code deps, then `dvc repro`")


def method_names() -> list[str]:
    """Every method's name, the built-in ones first in the tables' order, then the added ones by name, without
    importing the added ones (a module's name is its method's)."""
    importlib.import_module(f"{__package__}.builtin")
    builtin = [name for name, spec in _SPECS.items() if spec.make.__module__ == f"{__package__}.builtin"]
    added = [name for name in added_modules() if name not in builtin]
    return builtin + added + [name for name in _SPECS if name not in builtin and name not in added]


def method_spec(name: str) -> MethodSpec:
    """Method `name`'s spec, importing its module if it is an added one and no other; `ValueError` if there is
    no such method."""
    if name not in _SPECS:
        importlib.import_module(f"{__package__}.builtin")
    if name not in _SPECS and name in added_modules():
        _import_method(name)
    if name not in _SPECS:
        raise ValueError(f"no method {name!r}; known: {', '.join(method_names())}")
    return _SPECS[name]


def specs() -> dict[str, MethodSpec]:
    """Every method's spec by name, in the tables' order (`method_names`); imports every method's module."""
    load()
    return {name: method_spec(name) for name in method_names()}


# every method's label as its spec gives it, written by `scripts/stage_deps.py` (tests/test_stages.py fails until it
# agrees with the specs): the stages that only write tables read labels from here, so they load no method's code
# and a change to one method's module does not re-run them
LABELS_FILE = Path(__file__).with_name("labels.json")


def method_labels(names: Iterable[str] | None = None) -> dict[str, str]:
    """The labels of `names` (default: every method, in the tables' order), from `LABELS_FILE`; a method it does
    not list yet (added since the script last ran) from its spec, importing its module."""
    written = _written_labels()
    return {name: written.get(name) or method_spec(name).label for name in (method_names() if names is None else names)}


@cache
def _written_labels() -> dict[str, str]:
    try:
        return json.loads(LABELS_FILE.read_text(encoding="utf-8"))
    except FileNotFoundError:
        return {}


def spec_labels() -> dict[str, str]:
    """Every method's label from its spec, in the tables' order (imports every method's module): what
    `LABELS_FILE` holds."""
    return {name: spec.label for name, spec in specs().items()}
