"""Varied starting states: training programs that begin where another one ended.

A demonstration starts with an empty hand; a chained program (a recipe's
second step) starts with the first one's pot still in hand, somewhere else in
the room. For every training scenario this adds one scenario that starts in
its demonstrated final state: the next scenario of the same environment (in id
order, wrapping round) whose task the demonstrator can still do from there.
Only the scenarios handed in are used, so held-out environments stay unseen.
"""

from __future__ import annotations

from collections.abc import Sequence

from ..features.context import StepContext, step_context
from ..sim.demonstrator import NoDemonstration, demonstrate
from ..sim.primitives import PreconditionError, execute
from ..sim.scenarios import Scenario
from ..sim.state import WorldState
from ..sim.tasks import Task, goal_reached
from .expert import DONE


def _final(scenario: Scenario) -> WorldState:
    state = scenario.initial
    for action in scenario.demonstrations[0]:
        state = execute(state, action)
    return state


def _chain(env_id: str, state: WorldState, task: Task) -> Scenario | None:
    if any(a not in state.specs for a in task.args) or goal_reached(task, state, state):
        return None
    try:
        scripts = demonstrate(state, task)
    except (NoDemonstration, PreconditionError):
        return None
    return Scenario(env_id, task, state, tuple(tuple(s) for s in scripts))


# What a process has chained and featurised already, by the given scenario object (kept here, so its id stays
# its own): the folds of one world train on overlapping scenarios, and a worker fits them one after another.
_CHAINED: dict[int, tuple[Scenario, WorldState, dict[Task, Scenario | None]]] = {}
_CONTEXTS: dict[int, tuple[Scenario, list[StepContext]]] = {}
# Scenarios at most in either, past which both are emptied together: a process that goes through many worlds
# keeps the last (about 110 kB a chained scenario with its steps: 2,500 hold the 1,130 of a 130-room world)
_REMEMBERED = 2_500


def _make_room() -> None:
    """Empty both memos when either is full, before a new entry goes in.

    Every entry holds its scenario, so no id is given to another object while
    its entry is kept; emptying both at once frees every scenario they hold.
    """
    if len(_CHAINED) >= _REMEMBERED or len(_CONTEXTS) >= _REMEMBERED:
        _CHAINED.clear()
        _CONTEXTS.clear()


def _chained_after(first: Scenario, task: Task) -> Scenario | None:
    """`_chain` from where `first`'s demonstration ended, once per process for a given scenario and task."""
    _make_room()
    if id(first) not in _CHAINED:
        _CHAINED[id(first)] = (first, _final(first), {})
    _, end, by_task = _CHAINED[id(first)]
    if task not in by_task:
        by_task[task] = _chain(first.env_id, end, task)
    return by_task[task]


def chained_scenarios(scenarios: Sequence[Scenario]) -> list[Scenario]:
    """One scenario per given scenario that starts where its first demonstration ended (where one exists)."""
    by_env: dict[str, list[Scenario]] = {}
    for sc in sorted(scenarios, key=lambda s: s.id):
        by_env.setdefault(sc.env_id, []).append(sc)
    out = []
    for group in by_env.values():
        for i, first in enumerate(group):
            for second in group[i + 1 :] + group[:i]:
                if second.task != first.task and (chained := _chained_after(first, second.task)) is not None:
                    out.append(chained)
                    break
    return out


def chained_contexts(scenario: Scenario) -> list[StepContext]:
    """`demonstration_contexts` of a scenario `chained_scenarios` returned, made once per process.

    The same chained scenario comes back for most folds of a world (its first
    scenario and the next one in its room are both training scenarios), and
    its steps' features were a seventh of a chained fit at 130 rooms.
    """
    _make_room()
    if id(scenario) not in _CONTEXTS:
        _CONTEXTS[id(scenario)] = (scenario, demonstration_contexts(scenario))
    return _CONTEXTS[id(scenario)][1]


def demonstration_contexts(scenario: Scenario) -> list[StepContext]:
    """Teacher-forced steps of every demonstration of `scenario`, each sequence closed by `done`."""
    out = []
    for demo in scenario.demonstrations:
        state = scenario.initial
        for k, label in enumerate([*demo, DONE]):
            out.append(step_context(state, scenario.task, list(demo[:k]), gold=label))
            if k < len(demo):
                state = execute(state, demo[k])
    return out
