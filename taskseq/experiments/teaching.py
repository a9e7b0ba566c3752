"""What people's demonstrations buy: the planner's success on the other tasks of the environments they taught.

Two uses, one protocol. `taskseq people` compares the planner trained on a
world's benchmark with the same planner trained also on people's
demonstrations, in the environments people demonstrated, on the tasks they
did not demonstrate. `taskseq teach` measures the same with a scripted
person: the demonstrator drives the server's record writer in environments
held out of the benchmark's training data, k tasks each, and the planner is
judged on a fixed set of the other tasks of those environments. The records
a person makes go through the web app's record writer before training; the
stages do that (`stages/teach.py`), so nothing here imports the web app.

A task counts as held out only if the scripted demonstrator can do it there
(so success is possible), and success is `Program.success`: stopped by
choice, goal reached, no safety rule broken.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import asdict, dataclass

import numpy as np

from ..evaluate.methods import Method
from ..features.context import StepContext
from ..features.dataset import StepMeta
from ..learn.estimator import StepScorer
from ..plan.planner import plan
from ..settings import Learner
from ..sim.primitives import Action
from ..sim.scenarios import Scenario, room_scenarios
from ..sim.state import WorldState
from ..sim.tasks import Task
from . import outcome_cache
from .crossval import SequenceOutcome, judge, outcome_of


@dataclass(frozen=True)
class Outcome:
    """The planner's result on the held-out tasks of one environment, in all and by task kind."""

    env_id: str
    n_tasks: int
    n_success: int
    by_kind: dict[str, tuple[int, int]]  # task name -> (tasks, successes)

    @property
    def success(self) -> float:
        return 100.0 * self.n_success / self.n_tasks if self.n_tasks else float("nan")


def fit(contexts: list[StepContext], C: float, learner: Learner) -> StepScorer:
    """The full model at C (the one the `select` stage chose for it) on these steps."""
    return StepScorer("full", C=C, tol=learner.tol, max_iter=learner.max_iter, n_slacks=learner.n_slacks).fit(
        contexts)


def success_on(planner: StepScorer, env_id: str, state: WorldState, tasks: Iterable[Task],
               max_steps: int) -> Outcome:
    by_kind: dict[str, tuple[int, int]] = {}
    for task in tasks:
        ok = plan(planner, state, task, max_steps=max_steps).success
        n, k = by_kind.get(task.name, (0, 0))
        by_kind[task.name] = (n + 1, k + int(ok))
    return Outcome(env_id, sum(n for n, _ in by_kind.values()), sum(k for _, k in by_kind.values()), by_kind)


def pooled(outcomes: list[Outcome], kind: str | None = None) -> float:
    """Success over every held-out task of the environments together, or every task of one kind (%)."""
    counts = [o.by_kind.get(kind, (0, 0)) if kind else (o.n_tasks, o.n_success) for o in outcomes]
    n = sum(c[0] for c in counts)
    return 100.0 * sum(c[1] for c in counts) / n if n else float("nan")


def teaching_order(tasks: list[tuple[Task, list[Action]]], rng: np.random.Generator) -> list[int]:
    """Which tasks a scripted person demonstrates first: a seeded order, one task kind after another, so
    two or three demonstrations cover different kinds (a pour, a pick-and-place, ...)."""
    order = [int(i) for i in rng.permutation(len(tasks))]
    by_kind: dict[str, list[int]] = {}
    for i in order:
        by_kind.setdefault(tasks[i][0].name, []).append(i)
    kinds = sorted(by_kind, key=lambda k: order.index(by_kind[k][0]))
    out = []
    while any(by_kind.values()):
        for k in kinds:
            if by_kind[k]:
                out.append(by_kind[k].pop(0))
    return out


@dataclass(frozen=True)
class Taught:
    """One held-out room of a teaching run: where it is, the tasks a person shows first (in order) and the rest."""

    env_id: str
    state: WorldState
    shown: tuple[tuple[Task, tuple[Action, ...]], ...]  # the first max(k) tasks of the teaching order, one sequence
    tested: tuple[Scenario, ...]  # every other task the demonstrator can do there, with all its sequences


def rooms_to_teach(rooms: dict[str, WorldState], most: int, rng: np.random.Generator) -> list[Taught]:
    """Per room (in the mapping's order), what a person shows and what is judged: the room's scenarios
    (`sim.scenarios.room_scenarios`) in `teaching_order`; the first `most` are shown, the rest tested, so the
    tested tasks are the same for every k up to `most` and never one that was shown."""
    out = []
    for env_id, state in rooms.items():
        candidates = room_scenarios(env_id, state)
        order = teaching_order([(s.task, list(s.demonstrations[0])) for s in candidates], rng)
        out.append(Taught(env_id, state, tuple((candidates[i].task, candidates[i].demonstrations[0])
                                               for i in order[:most]),
                          tuple(candidates[i] for i in order[most:])))
    return out


def weighted(contexts: list[StepContext], meta: list[StepMeta], taught: list[StepContext],
             taught_meta: list[StepMeta], weight: int) -> tuple[list[StepContext], list[StepMeta]]:
    """The training steps with each taught step counted `weight` times (its room's own ways, made to weigh against
    the many steps of other rooms)."""
    if weight < 1:
        raise ValueError(f"teach.weight must be at least 1 (times a taught step counts), got {weight}")
    return contexts + taught * weight, meta + taught_meta * weight


def judged(make: Callable[[], Method], method: Method, scenarios: Iterable[Scenario],
           max_steps: int) -> list[SequenceOutcome]:
    """The fitted method's (made by `make`) program for each scenario, judged against its demonstrations (read back
    from the outcome cache when it is on and holds them)."""
    tested = {s.id: s for s in scenarios}
    return outcome_cache.read_or_run(
        "teaching", make, method, ([], [], tested, frozenset(tested), None),
        {"order": list(tested), "max_steps": max_steps},
        lambda: [judge(s, method.run(s, max_steps)) for s in tested.values()],
        lambda result: [asdict(o) for o in result], lambda entry: [outcome_of(o) for o in entry])
