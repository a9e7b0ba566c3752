"""A Table I method as one spec: its name, label, estimator factory, policy, and own settings with defaults.

Every method, built in (`builtin.py`) or added (a module of its own beside it),
registers one `MethodSpec` here with `register`. The package's `__init__`
imports every module of the package before anyone can ask for the list, so
the list is whole whenever it is read, and this module imports none of them.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import MISSING, dataclass, fields, is_dataclass
from typing import Any

from ..evaluate.methods import Method, ScorerMethod
from ..plan.planner import POLICIES
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


def register(spec: MethodSpec) -> MethodSpec:
    """Add a method to Table I: built-in ones in the tables' order, then added ones by module name."""
    if spec.name in _SPECS and _SPECS[spec.name] != spec:
        raise ValueError(f"method {spec.name!r} is registered twice")
    _SPECS[spec.name] = spec
    return spec


def specs() -> dict[str, MethodSpec]:
    """Every method's spec by name, in the tables' order."""
    return dict(_SPECS)


def method_labels() -> dict[str, str]:
    """Every method's label, in the tables' order."""
    return {name: spec.label for name, spec in _SPECS.items()}
