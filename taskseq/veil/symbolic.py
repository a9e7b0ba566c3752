"""The symbolic planner: a breadth-first search in the release's domain toward an objective's derived goal.

It is the baseline that knows what the learned methods must infer: the goal
itself (`evaluate.derive_goals`, from the training sequences' end states) and
the domain's preconditions and effects (`state.step`). From the state it is
in, it searches the shortest sequence of steps the domain lets run after
which every fact of the goal holds, and proposes that sequence's first step;
it stops (`done`) once the goal holds. An objective whose training sequences
give it no goal asks it for nothing, so it stops at once there.

Two limits keep a search small, both fixed before any run was scored:

- the objects it may act on are those of the categories that at least
  `RELEVANT_SHARE` of the objective's training sequences name in a step (the
  "which objects matter" a planner's author writes down), and those of the
  categories the goal names;
- at most `max_nodes` states are expanded; when no state within them reaches
  the whole goal, it follows the shortest path to the state that reaches the
  largest share of it found, then stops.

It predicts no next step of a person: it plans from where it stands, and a
search per state of every held-out sequence would cost more than the whole
evaluation. Its rows give closed-loop figures only.
"""

from __future__ import annotations

import itertools
from collections import Counter, deque
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field

from .evaluate import Executor, Lifted, derive_goals, lift
from .features import DONE, SIGNATURES
from .grounding import Grounded, Step
from .metrics import goal_share
from .replay import Replay
from .state import Fact, State, StepRefused, World, step

RELEVANT_SHARE = 0.25  # a category is acted on when this share of the objective's training sequences name it


def relevant_categories(train: Sequence[Replay], share: float = RELEVANT_SHARE) -> dict[str, frozenset[str]]:
    """Each objective's categories (lower case) that at least `share` of its training sequences name in a step."""
    named: dict[str, Counter[str]] = {}
    totals: Counter[str] = Counter()
    for r in train:
        if not r.kept:
            continue
        objects = r.initial.world.objects
        totals[r.point.objective] += 1
        named.setdefault(r.point.objective, Counter()).update(
            {objects[a].category.lower() for s in r.kept for a in (s.a1, s.a2) if a is not None})
    return {o: frozenset(c for c, n in named[o].items() if n >= share * totals[o]) for o in sorted(totals)}


def groundings(executor: Executor, world: World, objects: Sequence[str]) -> list[Grounded]:
    """Every step over `objects` (each verb with its arity, ordered pairs for two) that an action executes."""
    out = []
    for verb, arity in SIGNATURES:
        if verb == DONE:
            continue
        for args in itertools.permutations(objects, arity):
            g = executor.grounded(world, Step(verb, *args))
            if g is not None:
                out.append(g)
    return out


@dataclass(frozen=True)
class Plan:
    """What a search found: the steps, how much of the goal they reach, and what the search cost."""

    steps: tuple[Step, ...]
    share: float  # of the goal, after the last step
    expanded: int  # states the search expanded


def search(start: State, goal: frozenset[Lifted], moves: Sequence[Grounded], max_nodes: int) -> Plan:
    """The shortest run of `moves` from `start` after which the whole goal holds (moves tried in their order, so
    ties go the same way every time); past `max_nodes` expansions, the shortest run to the best share found."""
    parent: dict[frozenset[Fact], tuple[frozenset[Fact], Step] | None] = {start.facts: None}
    best_share, best = goal_share(lift(start), goal), start.facts
    frontier, expanded = deque([start]), 0
    while frontier and best_share < 1.0 and expanded < max_nodes:
        state = frontier.popleft()
        expanded += 1
        for g in moves:
            after = step(state, g.action, g.args)
            if isinstance(after, StepRefused) or after.facts in parent:
                continue
            parent[after.facts] = (state.facts, g.step)
            share = goal_share(lift(after), goal)
            if share > best_share:
                best_share, best = share, after.facts
                if share == 1.0:
                    break
            frontier.append(after)
    steps = []
    node = best
    while (link := parent[node]) is not None:
        node, s = link
        steps.append(s)
    return Plan(tuple(reversed(steps)), best_share, expanded)


@dataclass
class SymbolicPlanner:
    """`methods.VeilMethod` of the search above; `fit` derives the goals and the objects each objective acts on."""

    executor: Executor
    max_nodes: int = 20000
    name: str = "symbolic_planner"
    predicts_next_step = False  # closed loop only (module docstring)
    goals_: dict[str, frozenset[Lifted]] = field(init=False, repr=False)
    relevant_: dict[str, frozenset[str]] = field(init=False, repr=False)
    _next: dict[tuple[str, str, frozenset[Fact]], Step] = field(init=False, repr=False, default_factory=dict)

    def fit(self, train: Sequence[Replay]) -> SymbolicPlanner:
        self.goals_ = derive_goals(train)
        self.relevant_ = relevant_categories(train)
        self._next = {}
        return self

    def plan(self, state: State, objective: str) -> Plan:
        """The search from `state` toward the objective's goal over its relevant objects."""
        goal = self.goals_.get(objective, frozenset())
        named = {c.lower() for fact in goal for c in (fact[1:2] if fact[0] == "state" else fact[1:])}
        wanted = self.relevant_.get(objective, frozenset()) | named
        objects = [n for n, o in state.world.objects.items() if o.category.lower() in wanted]
        return search(state, goal, groundings(self.executor, state.world, objects), self.max_nodes)

    def ranked(self, state: State, history: Sequence[Step], objective: str) -> Iterator[Step]:
        goal = self.goals_.get(objective)
        if not goal or goal_share(lift(state), goal) == 1.0:
            yield Step(DONE)
            return
        key = (state.world.env_id, objective, state.facts)
        if key not in self._next:
            # every state along the plan gets the plan's next step from there, so a run that follows it
            # searches once; the plan's last state gets `done` (the goal holds, or the search's best is reached)
            # (an entry already there stays: what a state is given never depends on which search reached it first)
            here: State | None = state
            for s in self.plan(state, objective).steps:
                assert here is not None  # the search ran each step in the domain: it runs again
                self._next.setdefault((state.world.env_id, objective, here.facts), s)
                here = self.executor.after(here, s)
            assert here is not None
            self._next.setdefault((state.world.env_id, objective, here.facts), Step(DONE))
        yield self._next[key]
