"""The methods as a run configures them: each spec with its entry of params.yaml and its C from selection.json.

A stage builds one `Lineup` from what it read (the `methods` section, the
selection file, the learner and its own settings) and asks it for unfitted
methods: every one (Table I), those an experiment runs, or some by name.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from functools import partial

from ..evaluate.methods import Method, ScorerMethod
from ..selection import Selection
from ..settings import Crossval, Learner, Methods, Pddl, Procedural, parse_section
from .spec import Build, MethodSpec, method_names, method_spec


@dataclass(frozen=True)
class Lineup:
    """Every method of Table I, configured. Raises `ValueError` for a method params.yaml names that no spec has
    and, when a method is asked for (every stage asks for those it runs before any work), for a setting it does
    not have: checking every method's settings would load every method's module, and a stage loads only the
    modules of the methods it runs."""

    methods: Methods  # params.yaml's `methods` section
    selection: Selection = field(default_factory=Selection)  # each method's C
    learner: Learner = Learner()
    crossval: Crossval = Crossval()
    horizon: int = Pddl.horizon
    store: str | None = None  # the model store the MRF methods load their fold models from
    procedural: Procedural = Procedural()  # params.yaml's `procedural`: where a method draws training rooms from

    def __post_init__(self) -> None:
        known = method_names()
        unknown = [name for name, _ in self.methods.entries if name not in known]
        if unknown:
            raise ValueError(f"params.yaml: methods.{unknown[0]} is no method of Table I; known: {', '.join(known)}")

    def settings_of(self, name: str) -> object:
        """Method `name`'s own settings: its spec's defaults, with what params.yaml sets (checked when a stage
        asks for the method, before any work)."""
        entry, spec = self.methods.entry(name), method_spec(name)
        return parse_section(spec.settings, dict(entry.settings) if entry else {}, f"methods.{name}")

    def names(self, experiment: str | None = None) -> list[str]:
        """Every method (experiment None: Table I, in its order), or those `experiment` runs, in params.yaml's
        order (no method's module imported)."""
        if experiment is None:
            return method_names()
        return [name for name, entry in self.methods.entries if experiment in entry.experiments]

    def factory(self, name: str) -> Callable[[], Method]:
        """An unfitted method `name`, made afresh on each call."""
        spec: MethodSpec = method_spec(name)
        C = None if spec.tuned_as is None else self.selection.of(spec.tuned_as)
        build = Build(name, spec.policy, C, self.learner, self.crossval, self.horizon, self.store,
                      self.settings_of(name), self.procedural)
        return partial(spec.make, build)

    def factories(self, names: Sequence[str] | None = None) -> dict[str, Callable[[], Method]]:
        """Unfitted methods by name: `names` in that order, or every method of Table I."""
        every = method_names()
        unknown = [n for n in names or () if n not in every]
        if unknown:
            raise ValueError(f"unknown methods {unknown}; known: {', '.join(every)}")
        return {name: self.factory(name) for name in (every if names is None else names)}

    def mrf(self, names: Sequence[str] | None = None) -> dict[str, Callable[[], ScorerMethod]]:
        """The MRF methods (those the `fold_models` stage trains), or those of `names`, which must all be."""
        makes = self.factories(names)
        if names is None:
            return {n: m for n, m in makes.items() if method_spec(n).C_from is not None
                    and isinstance(m(), ScorerMethod)}
        wrong = [n for n, m in makes.items() if not isinstance(m(), ScorerMethod)]
        if wrong:
            raise ValueError(f"{', '.join(wrong)}: not MRF methods (only those have fold models)")
        return makes

    def running(self, experiment: str) -> dict[str, Callable[[], ScorerMethod]]:
        """The MRF methods `experiment` runs, in params.yaml's order."""
        return self.mrf(self.names(experiment))

    def at_C(self, C: float) -> Lineup:
        """The same methods, every one at C (the `select` stage's candidates)."""
        return replace(self, selection=Selection.uniform(C, tuple(method_names())))
