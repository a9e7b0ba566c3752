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


def chained_scenarios(scenarios: Sequence[Scenario]) -> list[Scenario]:
    """One scenario per given scenario that starts where its first demonstration ended (where one exists)."""
    by_env: dict[str, list[Scenario]] = {}
    for sc in sorted(scenarios, key=lambda s: s.id):
        by_env.setdefault(sc.env_id, []).append(sc)
    out = []
    for env_id, group in by_env.items():
        for i, first in enumerate(group):
            end = _final(first)
            for second in group[i + 1 :] + group[:i]:
                if second.task != first.task and (chained := _chain(env_id, end, second.task)) is not None:
                    out.append(chained)
                    break
    return out


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
