"""What the domain MRF sees of a VEIL step: each object as a row of attributes, never its name.

An object's row holds its relations to the robot (near, grasped), whether it
rests on or in something or holds something, its affordances (`Objects.xml`),
its boolean states that hold now, and, with `categories=True`, its category as
one-hot columns. The columns come from the release's own catalogue, which
describes the domain (every category, affordance and state name it defines),
so a step's row does not depend on which sequences were trained on. A pair of
objects carries the relations between them (one on or in the other, the same
category).

Labels are `(verb, a1, a2)` over `SIGNATURES`: a verb with its arity (`pour`
takes one argument or two, so it has two signatures), and `done`, the step a
person's sequence ends with: the planner stops when it scores best.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from .grounding import VERBS, Step
from .mrf import StepInput
from .release import Catalog
from .state import ROBOT, State, World

DONE = "done"
_TWO = frozenset({"keep_on", "keep_inside", "add", "insert", "scoop", "squeeze", "place"})
SIGNATURES: tuple[tuple[str, int], ...] = tuple(
    [(v, 2 if v in _TWO else 0 if v == "wait" else 1) for v in VERBS] + [("pour", 2), (DONE, 0)])
SIGNATURE_INDEX = {s: i for i, s in enumerate(SIGNATURES)}
ARITIES = tuple(a for _, a in SIGNATURES)
ROBOT_COLUMNS = ("near", "grasped", "on_something", "in_something", "holds_on", "holds_in")
PAIR_COLUMNS = ("a1_on_a2", "a1_in_a2", "a2_on_a1", "a2_in_a1", "same_category")


@dataclass(frozen=True)
class Vocabulary:
    """The columns of an object's row, fixed by the domain's catalogue (and whether categories are seen)."""

    affordances: tuple[str, ...]
    states: tuple[str, ...]
    categories: tuple[str, ...]
    objectives: tuple[str, ...]
    _worlds: dict[int, tuple[World, np.ndarray, dict]] = field(default_factory=dict, init=False, repr=False,
                                                              compare=False, hash=False)

    def __getstate__(self) -> dict:
        """Pickled without the rows kept per world: they are keyed by the worlds' ids in this process."""
        return {k: v for k, v in self.__dict__.items() if k != "_worlds"} | {"_worlds": {}}

    @classmethod
    def of(cls, catalog: Catalog, objectives: Sequence[str], categories: bool) -> Vocabulary:
        cats = catalog.categories.values()
        return cls(tuple(sorted({a for c in cats for a in c.affordances})),
                   tuple(sorted({name for c in cats for name, _ in c.defaults})),
                   tuple(sorted(c.name for c in cats)) if categories else (),
                   tuple(sorted(set(objectives))))

    @property
    def columns(self) -> tuple[str, ...]:
        return (ROBOT_COLUMNS + tuple(f"affords_{a}" for a in self.affordances)
                + tuple(f"state_{s}" for s in self.states) + tuple(f"is_{c}" for c in self.categories))

    def rows(self, state: State) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(N, K) object rows of `state`, and its (M, 2) related pairs with their (M, R) relation rows."""
        base, same_category = self._world_rows(state.world)
        index = {n: i for i, n in enumerate(state.world.objects)}
        rows = base.copy()
        s0 = len(ROBOT_COLUMNS) + len(self.affordances)
        sta = {s.lower(): s0 + i for i, s in enumerate(self.states)}
        pairs = {k: v.copy() for k, v in same_category.items()}

        def relate(x: int, y: int, column: int) -> None:
            pairs.setdefault((x, y), np.zeros(len(PAIR_COLUMNS)))[column] = 1.0

        for fact in state.facts:
            kind = fact[0]
            if kind == "state":
                if fact[1] in index and (j := sta.get(fact[2].lower())) is not None:
                    rows[index[fact[1]], j] = 1.0
            elif kind in ("Near", "Grasping") and fact[1] == ROBOT and fact[2] in index:
                rows[index[fact[2]], 0 if kind == "Near" else 1] = 1.0
            elif kind in ("On", "In") and fact[1] in index and fact[2] in index:
                x, y = index[fact[1]], index[fact[2]]
                rows[x, 2 if kind == "On" else 3] = 1.0
                rows[y, 4 if kind == "On" else 5] = 1.0
                relate(x, y, 0 if kind == "On" else 1)
                relate(y, x, 2 if kind == "On" else 3)
        keys = sorted(pairs)
        pair_index = np.array(keys, dtype=int).reshape(-1, 2)
        pair_rows = np.array([pairs[k] for k in keys]).reshape(-1, len(PAIR_COLUMNS))
        return rows, pair_index, pair_rows

    def _world_rows(self, world: World) -> tuple[np.ndarray, dict[tuple[int, int], np.ndarray]]:
        """What an environment's every state shares: the rows' affordance and category columns, and the pairs
        of the same category. Made once per world (a run asks for thousands of its states)."""
        kept = self._worlds.get(id(world))
        if kept is not None and kept[0] is world:
            return kept[1], kept[2]
        index = {n: i for i, n in enumerate(world.objects)}
        rows = np.zeros((len(index), len(self.columns)))
        a0 = len(ROBOT_COLUMNS)
        c0 = a0 + len(self.affordances) + len(self.states)
        aff = {a: a0 + i for i, a in enumerate(self.affordances)}
        cat = {c.lower(): c0 + i for i, c in enumerate(self.categories)}
        by_category: dict[str, list[int]] = {}
        for name, info in world.objects.items():
            i = index[name]
            for a in info.affordances:
                if a in aff:
                    rows[i, aff[a]] = 1.0
            if (j := cat.get(info.category.lower())) is not None:
                rows[i, j] = 1.0
            by_category.setdefault(info.category.lower(), []).append(i)
        same: dict[tuple[int, int], np.ndarray] = {}
        for members in by_category.values():
            for x in members:
                for y in members:
                    if x != y:
                        same.setdefault((x, y), np.zeros(len(PAIR_COLUMNS)))[4] = 1.0
        self._worlds[id(world)] = (world, rows, same)  # the world kept with its rows: its id stays its own
        return rows, same

    def step_input(self, state: State, history: Sequence[Step], objective: str) -> StepInput:
        """The model's view of `state` after the steps `history`, working toward `objective`."""
        rows, pair_index, pair_rows = self.rows(state)
        index = {n: i for i, n in enumerate(state.world.objects)}
        hist = np.zeros((len(index), 4))
        prev = [len(SIGNATURES), len(SIGNATURES)]
        for back, s in enumerate(reversed(history[-2:])):
            prev[back] = signature_of(s)
            for slot, name in enumerate((s.a1, s.a2)):
                if name is not None and name in index:
                    hist[index[name], 2 * back + slot] = 1.0
        if objective not in self.objectives:
            raise ValueError(f"objective {objective!r} is not one this model knows ({', '.join(self.objectives)})")
        return StepInput(rows, hist, pair_index, pair_rows, self.objectives.index(objective), (prev[0], prev[1]),
                         bool(state.grasped()))


def signature_of(step: Step) -> int:
    arity = (step.a1 is not None) + (step.a2 is not None)
    return SIGNATURE_INDEX[(step.verb, arity)]


def label_of(step: Step, state: State) -> tuple[int, int, int]:
    """The (verb, a1, a2) label of a person's step in `state`'s object order."""
    names = list(state.world.objects)
    return (signature_of(step), names.index(step.a1) if step.a1 is not None else -1,
            names.index(step.a2) if step.a2 is not None else -1)


def step_of(label: Sequence[int], names: Sequence[str]) -> Step:
    """The step a label names among a state's objects `names` (in the world's order)."""
    verb, _ = SIGNATURES[int(label[0])]
    a1, a2 = (names[int(a)] if int(a) >= 0 else None for a in label[1:3])
    return Step(verb, a1, a2)


def line_of(step: Step) -> str:
    """The release's action line for a step (`keep X On Y`, `pour X`, `wait`), as `grounding` reads it."""
    if step.verb in ("keep_on", "keep_inside"):
        return f"keep {step.a1} {'On' if step.verb == 'keep_on' else 'Inside'} {step.a2}"
    return " ".join(w for w in (step.verb, step.a1, step.a2) if w is not None)
