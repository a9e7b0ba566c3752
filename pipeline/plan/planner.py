"""The dynamic planner: score every candidate in the current state, execute the best, repeat.

This is the paper's Program 3: the loop looks at the environment afresh at
every step, so an object that moved, or a step that did something else than
expected, changes the next choice.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from ..features.context import StepContext, step_context
from ..learn.mrf import MRFModel
from ..sim.primitives import Action, PreconditionError, execute
from ..sim.safety import violations
from ..sim.state import WorldState
from ..sim.tasks import Task, goal_reached

DONE = "done"
STEP_CAP = "step_cap"
INFEASIBLE = "infeasible"


@dataclass
class PlanStep:
    action: Action
    score: float
    alternatives: list[tuple[Action, float]]  # the next best candidates, best first
    unsafe: list[str] = field(default_factory=list)  # safety rules the action breaks


@dataclass
class Program:
    task: Task
    steps: list[PlanStep]
    status: str  # DONE, STEP_CAP or INFEASIBLE
    initial: WorldState
    final: WorldState
    error: str | None = None

    @property
    def actions(self) -> list[Action]:
        return [s.action for s in self.steps]

    @property
    def goal_reached(self) -> bool:
        return goal_reached(self.task, self.initial, self.final)

    @property
    def safe(self) -> bool:
        return not any(s.unsafe for s in self.steps)

    @property
    def success(self) -> bool:
        """Stopped by choice, goal reached and no safety rule broken."""
        return self.status == DONE and self.goal_reached and self.safe


Perceive = Callable[[StepContext], StepContext]
Choose = Callable[[list[Action], list[Action]], int]


Rank = Callable[[StepContext], list[tuple[tuple[int, int, int], float]]]


def plan(model: MRFModel, w: np.ndarray, state: WorldState, task: Task, max_steps: int = 20,
         top_k: int = 3, perceive: Perceive | None = None, choose: Choose | None = None) -> Program:
    """Run the loop in the simulator until `done`, an infeasible step, or `max_steps` primitives.

    `perceive` changes what the model sees of each step (attribute noise);
    `choose(history, ranked actions)` lets an observer pick among the top
    `top_k` candidates (human feedback); by default the best one is taken.
    """
    return run_loop(lambda ctx: model.top_k(ctx, w, top_k), state, task, max_steps, perceive, choose)


def run_loop(rank: Rank, state: WorldState, task: Task, max_steps: int = 20, perceive: Perceive | None = None,
             choose: Choose | None = None) -> Program:
    """The dynamic-planning loop for any ranking of a step's candidates, best first."""
    task.check_objects(state)
    initial, steps = state, []
    while True:
        ctx = step_context(state, task, [s.action for s in steps])
        if perceive is not None:
            ctx = perceive(ctx)
        ranked = rank(ctx)
        if choose is not None:
            pick = choose([s.action for s in steps], [ctx.action(y) for y, _ in ranked])
            ranked = [ranked[pick]] + ranked[:pick] + ranked[pick + 1 :]
        (best, score), rest = ranked[0], ranked[1:]
        action = ctx.action(best)
        if action.primitive == DONE:
            return Program(task, steps, DONE, initial, state)
        if len(steps) == max_steps:
            return Program(task, steps, STEP_CAP, initial, state)
        step = PlanStep(action, score, [(ctx.action(y), s) for y, s in rest], violations(state, action))
        steps.append(step)
        try:
            state = execute(state, action)
        except PreconditionError as err:
            return Program(task, steps, INFEASIBLE, initial, state, str(err))
