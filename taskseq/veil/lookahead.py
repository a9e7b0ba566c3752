"""The MRF with a goal lookahead: before each step, the model's own next choices imagined toward the derived goal.

The learned scorer picks one step at a time and never sees where a run is
heading, so in closed loop it wanders: it grasps what people grasp, then
puts it back, and rarely chooses `done` (reports/veil/tables.md, "stops").
This row keeps the scorer and adds what the symbolic planner is given, the
objective's goal derived from the training sequences (`evaluate.derive_goals`),
used in two ways only:

- when the whole goal holds, the robot stops (`done`);
- of the model's `width` best steps (`done` and steps the domain lets run),
  it takes the one whose imagined continuation reaches the largest share of
  the goal: from the state a step leads to, `depth` more steps, each the
  model's own best runnable one, stopping at `done` or where the goal holds.
  Ties go to the model's order, so where imagination sees no difference the
  model's first choice stands, `done` included.

`depth` is the paper world's lookahead's (`plan.planner`: 4, chosen on its
development world); the evaluation chooses `width` inside each fold's training
environments (`experiment.choose_width`), the paper world's 3 by default. An
objective without a derived goal is left to the model as it is.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field

from ..plan.planner import LOOKAHEAD_DEPTH, LOOKAHEAD_WIDTH
from .evaluate import Executor, Lifted, derive_goals, lift
from .features import DONE
from .grounding import Step
from .methods import VeilMethod
from .metrics import goal_share
from .replay import Replay
from .state import Fact, State

_Key = tuple[str, frozenset[Fact], tuple[Step, ...], str]


@dataclass
class GoalLookahead:
    """`methods.VeilMethod`: an MRF's ranking reordered by imagined progress toward the goal."""

    name: str
    base: VeilMethod  # an `DomainScorer`
    executor: Executor
    width: int = LOOKAHEAD_WIDTH
    depth: int = LOOKAHEAD_DEPTH
    goals_: dict[str, frozenset[Lifted]] = field(init=False, repr=False)
    _first: dict[_Key, tuple[Step, State]] = field(init=False, repr=False, default_factory=dict)

    def fit(self, train: Sequence[Replay]) -> GoalLookahead:
        self.base.fit(train)
        return self.with_goals(train)

    def with_goals(self, train: Sequence[Replay]) -> GoalLookahead:
        """The goals derived from `train`, around a base already fitted on the same sequences (an evaluation
        that runs the base model too fits it once)."""
        return self.toward(derive_goals(train))

    def toward(self, goals: Mapping[str, frozenset[Lifted]]) -> GoalLookahead:
        """Goals given as they are (a model file's), around a fitted base."""
        self.goals_ = dict(goals)
        self._first = {}
        return self

    def options(self, state: State, history: Sequence[Step], objective: str, n: int) -> list[tuple[Step, State]]:
        """The model's `n` best of `done` and the steps the domain lets run, each with the state it leads to."""
        out: list[tuple[Step, State]] = []
        for s in self.base.ranked(state, history, objective):
            after = state if s.verb == DONE else self.executor.after(state, s)
            if after is not None:
                out.append((s, after))
                if len(out) == n:
                    break
        return out

    def first(self, state: State, history: Sequence[Step], objective: str) -> tuple[Step, State] | None:
        """The model's best runnable step (or `done`), kept: imagined runs from nearby states share most steps.

        Keyed by the last two steps of the history, all an MRF's ranking reads of it (`Vocabulary.step_input`);
        a base reading more of the history would need a longer key."""
        key = (state.world.env_id, state.facts, tuple(history[-2:]), objective)
        if key not in self._first:
            found = self.options(state, history, objective, 1)
            if not found:
                return None
            self._first[key] = found[0]
        return self._first[key]

    def imagined(self, s: Step, after: State, history: Sequence[Step], objective: str,
                 goal: frozenset[Lifted]) -> float:
        """The largest share of the goal on the way: the state after `s`, then up to `depth` imagined steps."""
        best, state, steps = goal_share(lift(after), goal), after, [*history, s]
        for _ in range(self.depth if s.verb != DONE else 0):
            if best == 1.0 or (chosen := self.first(state, steps, objective)) is None or chosen[0].verb == DONE:
                break
            state = chosen[1]
            steps.append(chosen[0])
            best = max(best, goal_share(lift(state), goal))
        return best

    def ranked(self, state: State, history: Sequence[Step], objective: str) -> Iterator[Step]:
        goal = self.goals_.get(objective)
        if not goal:
            yield from self.base.ranked(state, history, objective)
            return
        if goal_share(lift(state), goal) == 1.0:
            chosen = Step(DONE)
        else:
            options = self.options(state, history, objective, self.width)
            if not options:
                yield from self.base.ranked(state, history, objective)
                return
            values = [self.imagined(s, after, history, objective, goal) for s, after in options]
            chosen = options[max(range(len(options)), key=lambda i: (values[i], -i))][0]
        yield chosen
        yield from (s for s in self.base.ranked(state, history, objective) if s != chosen)


LOOKAHEAD = "lookahead"  # a policy name beside `evaluate.POLICIES`: this class around the model, feasible steps


def planner(model: VeilMethod, goals: Mapping[str, frozenset[Lifted]], executor: Executor, policy: str,
            width: int) -> tuple[VeilMethod, str]:
    """The method and the rollout policy that a policy name stands for: `lookahead` wraps `model` in the goal
    lookahead (which proposes runnable steps first) run under `feasible`; the others take `model` as it is."""
    if policy == LOOKAHEAD:
        return GoalLookahead(f"{model.name}_lookahead", model, executor, width=width).toward(goals), "feasible"
    return model, policy
