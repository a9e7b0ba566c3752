"""Methods on people's sequences, with whole environments held out: next-step accuracy and closed-loop runs.

Folds hold out environments by file number, kitchen and living room of one
number together, so a held-out fold's rooms were never trained on. Two
evaluations per held-out sequence:

- next step with the people's history: at every kept step (and the `done`
  after the last), given the state the person reached and their last two
  steps, is the method's first step the person's? (verb, arguments, both);
- closed loop: from the environment's initial state the method chooses every
  step itself, in the domain, until it chooses `done` or takes `max_steps`;
  `plain` takes the first ranked step (a refused step changes nothing),
  `feasible` the first the domain lets run. A run is scored by the share of the
  objective's goal it reaches (`derive_goals`) and by its normalised edit
  distance to the nearest person's sequence of its environment and objective.

People are a ceiling, not a baseline: each held-out person's own sequence is
scored the same way, its edit distance taken to the other people of its
environment and objective (leave one out).
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass

from .features import DONE, line_of
from .grounding import ActionError, ActionIndex, Grounded, Step, UnknownObject
from .methods import VeilMethod, training_steps
from .metrics import goal_share, nearest_edit_distance
from .plan import DomainFiles
from .release import Release, environment_file
from .replay import Replay
from .state import State, StepRefused, World, step

POLICIES = ("plain", "feasible")
GOAL_SHARE = 0.5  # a lifted fact is part of an objective's goal when this share of its training sequences reach it
Lifted = tuple[str, ...]


def env_number(env_id: str) -> int:
    found = environment_file(env_id)
    if found is None:
        raise ValueError(f"unknown environment id {env_id!r}")
    return found[1]


def environment_folds(replays: Sequence[Replay], n_folds: int) -> list[frozenset[int]]:
    """Environment file numbers held out by each fold: numbers in order, dealt round the folds."""
    numbers = sorted({env_number(r.point.env_id) for r in replays})
    if not 2 <= n_folds <= len(numbers):
        raise ValueError(f"n_folds must be between 2 and the {len(numbers)} environment numbers, got {n_folds}")
    return [frozenset(n for i, n in enumerate(numbers) if i % n_folds == k) for k in range(n_folds)]


def split(replays: Sequence[Replay], held_out: frozenset[int]) -> tuple[list[Replay], list[Replay]]:
    """(training, held-out) replays: no sequence of a held-out environment number trains."""
    train = [r for r in replays if env_number(r.point.env_id) not in held_out]
    test = [r for r in replays if env_number(r.point.env_id) in held_out]
    return train, test


# goals ----------------------------------------------------------------------------------------------------------
def lift(state: State) -> frozenset[Lifted]:
    """The state's facts about objects with object names replaced by categories; the robot's transient
    relations (near, grasping) are left out, since no objective asks for them."""
    cat = {n: o.category for n, o in state.world.objects.items()}
    out = set()
    for f in state.facts:
        if f[0] == "state" and f[1] in cat:
            out.add(("state", cat[f[1]], f[2]))
        elif f[0] in ("On", "In") and f[1] in cat and f[2] in cat:
            out.add((f[0], cat[f[1]], cat[f[2]]))
    return frozenset(out)


def derive_goals(train: Sequence[Replay]) -> dict[str, frozenset[Lifted]]:
    """Each objective's goal: the lifted facts that its training sequences make true (absent at the start,
    present at the end) in at least `GOAL_SHARE` of them."""
    counts: dict[str, Counter[Lifted]] = {}
    totals: Counter[str] = Counter()
    for r in train:
        if not r.kept:
            continue
        objective = r.point.objective
        totals[objective] += 1
        counts.setdefault(objective, Counter()).update(lift(r.final) - lift(r.initial))
    return {o: frozenset(f for f, c in counts[o].items() if c >= GOAL_SHARE * totals[o]) for o in sorted(totals)}


# next step ------------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class NextStep:
    seq_id: str
    env_id: str
    verb: bool
    args: bool
    both: bool


def next_steps(method: VeilMethod, test: Sequence[Replay]) -> list[NextStep]:
    out = []
    for r in test:
        for state, history, objective, person in training_steps([r]):
            guess = next(iter(method.ranked(state, history, objective)), Step(DONE))
            verb, args = guess.verb == person.verb, (guess.a1, guess.a2) == (person.a1, person.a2)
            out.append(NextStep(r.point.seq_id, r.point.env_id, verb, args, verb and args))
    return out


# closed loop ----------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Run:
    seq_id: str
    env_id: str
    objective: str
    steps: tuple[Step, ...]
    refused: int
    stopped: bool  # chose `done` before `max_steps`
    goal_share: float | None  # None where the training sequences give this objective no goal (`derive_goals`)
    edit_distance: float | None  # None where no person demonstrated this environment and objective
    exact: bool


class Executor:
    """Runs steps in the release's domain: a step's line grounded as the importer grounds people's.

    A step's grounding depends on its environment's names only, never on the state, so it is made once per
    (environment, step) and kept: searches and lookaheads try the same steps in many states. Its outcome depends
    on the state's facts too; lookaheads try the same step in the same state again and again (about three times
    in five), so outcomes are kept as well, up to `KEPT_OUTCOMES` of them, then dropped all at once and kept
    anew (a state holds about ten facts). A kept outcome is returned in the asking state's world."""

    KEPT_OUTCOMES = 200_000

    def __init__(self, release: Release | DomainFiles) -> None:
        self.index = ActionIndex(release.domain)
        self.arities = {k: tuple(len(p) for p in v) for k, v in release.instructions.items()}
        self._grounded: dict[tuple[str, Step], Grounded | None] = {}
        self._outcomes: dict[tuple[str, frozenset, Step], State | None] = {}

    def grounded(self, world: World, s: Step) -> Grounded | None:
        """The domain action and arguments of `s` in `world`, or None when no action executes it there."""
        key = (world.env_id, s)
        if key not in self._grounded:
            try:
                self._grounded[key] = self.index.ground(line_of(s), world.names, self.arities)
            except (ActionError, UnknownObject):
                self._grounded[key] = None
        return self._grounded[key]

    def after(self, state: State, s: Step) -> State | None:
        """The state after `s`, or None when the domain refuses it."""
        key = (state.world.env_id, state.facts, s)
        if key in self._outcomes:
            kept = self._outcomes[key]
            return kept if kept is None or kept.world is state.world else State(state.world, kept.facts)
        g = self.grounded(state.world, s)
        result = None if g is None else step(state, g.action, g.args)
        if len(self._outcomes) >= self.KEPT_OUTCOMES:  # dropped whole: the outcomes are the same either way
            self._outcomes.clear()
        outcome = self._outcomes[key] = None if isinstance(result, StepRefused) else result
        return outcome


def rollout(method: VeilMethod, executor: Executor, start: State, objective: str, policy: str,
            max_steps: int) -> tuple[list[Step], State, int, bool]:
    """The steps a method takes from `start`, the state they reach, how many were refused, whether it stopped."""
    if policy not in POLICIES:
        raise ValueError(f"policy must be one of {POLICIES}, got {policy!r}")
    state, taken, refused = start, [], 0
    for _ in range(max_steps):
        chosen, after = None, None
        for candidate in method.ranked(state, taken, objective):
            if candidate.verb == DONE:
                return taken, state, refused, True
            after = executor.after(state, candidate)
            if after is not None or policy == "plain":
                chosen = candidate
                break
        if chosen is None:  # nothing the domain lets run
            break
        taken.append(chosen)
        if after is None:
            refused += 1
        else:
            state = after
    return taken, state, refused, False


def states_of(executor: Executor, start: State, steps: Sequence[Step]) -> list[State]:
    """The states a run visited: before each step and after the last (a refused step changes nothing)."""
    states = [start]
    for s in steps:
        states.append(executor.after(states[-1], s) or states[-1])
    return states


def people_of(replays: Iterable[Replay]) -> dict[tuple[str, str], list[tuple[str, tuple[Step, ...]]]]:
    """(environment, objective) -> [(sequence id, its kept steps)]."""
    out: dict[tuple[str, str], list[tuple[str, tuple[Step, ...]]]] = {}
    for r in replays:
        if r.kept:
            out.setdefault((r.point.env_id, r.point.objective), []).append((r.point.seq_id, r.kept))
    return out


def score_run(r: Replay, steps: Sequence[Step], final: State, refused: int, stopped: bool,
              goals: dict[str, frozenset[Lifted]], people: dict, leave_out: bool = False) -> Run:
    """A run of `r`'s environment and objective scored against the goal and the people (without `r` itself
    when `leave_out`)."""
    others = [s for seq, s in people.get((r.point.env_id, r.point.objective), [])
              if not (leave_out and seq == r.point.seq_id)]
    words = [str(s) for s in steps]
    refs = [[str(s) for s in o] for o in others]
    return Run(r.point.seq_id, r.point.env_id, r.point.objective, tuple(steps), refused, stopped,
               goal_share(lift(final), goal) if (goal := goals.get(r.point.objective)) else None,
               nearest_edit_distance(words, refs) if refs else None, any(words == ref for ref in refs))


def closed_loop(method: VeilMethod, executor: Executor, test: Sequence[Replay], goals: dict[str, frozenset[Lifted]],
                policy: str, max_steps: int, progress: Callable[[Iterable], Iterable] = iter) -> list[Run]:
    people = people_of(test)
    runs = []
    for r in progress(test):
        if not r.kept:
            continue
        steps, final, refused, stopped = rollout(method, executor, r.initial, r.point.objective, policy, max_steps)
        runs.append(score_run(r, steps, final, refused, stopped, goals, people))
    return runs


def people_runs(test: Sequence[Replay], goals: dict[str, frozenset[Lifted]]) -> list[Run]:
    """Each held-out person's own sequence, scored as a run (edit distance to the other people)."""
    people = people_of(test)
    return [score_run(r, r.kept, r.final, 0, True, goals, people, leave_out=True) for r in test if r.kept]
