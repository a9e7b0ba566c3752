"""Symbolic planning as a policy of the rollout loop: serve a shortest plan, replan when it stops fitting."""

from __future__ import annotations

from ...features.context import StepContext
from ...settings import Pddl
from ...sim.primitives import Action, try_execute
from ...sim.state import WorldState
from ...sim.tasks import Task
from ..planner import Abstain, Ranked
from .problem import build_problem
from .sat import PlanResult, solve

HORIZON = Pddl().horizon
MAX_REPLANS = 3


def plan_from(state: WorldState, task: Task, roles: dict[str, str], horizon: int = HORIZON) -> PlanResult:
    return solve(build_problem("scene", state, task, roles), horizon=horizon)


def first_action(state: WorldState, task: Task, roles: dict[str, str], horizon: int = HORIZON) -> Action | None:
    """The first step of a shortest plan (`done` if the goal already holds); None when there is no plan."""
    result = plan_from(state, task, roles, horizon)
    if result.plan is None:
        return None
    return result.plan[0].primitive() if result.plan else Action("done")


class SymbolicPolicy:
    """A shortest plan from the first state, served one step at a time (`done` once it is used up).

    When its next step cannot run in the world as it is (the planner's model of
    the world is coarser than the simulator), it replans from there, at most
    `MAX_REPLANS` times; after that the step is offered anyway and the program
    ends infeasible on it. A state with no plan within the horizon ends the
    program infeasible with the planner's message. One policy serves one
    program: it keeps the plan between steps.
    """

    def __init__(self, task: Task, roles: dict[str, str], horizon: int = HORIZON) -> None:
        self.task, self.roles, self.horizon = task, roles, horizon
        self._result: PlanResult | None = None
        self._queue: list = []
        self.replans = 0

    def _plan(self, state: WorldState) -> None:
        self._result = plan_from(state, self.task, self.roles, self.horizon)
        self._queue = list(self._result.plan or [])

    def __call__(self, ctx: StepContext, state: WorldState) -> Ranked:
        if self._result is None:
            self._plan(state)
        while True:
            if self._result.plan is None:
                raise Abstain(self._result.message())
            if not self._queue:
                return [(ctx.encode(Action("done")), 0.0)]
            action = self._queue[0].primitive()
            if self.replans == MAX_REPLANS or try_execute(state, action) is not None:
                self._queue.pop(0)
                return [(ctx.encode(action), 0.0)]
            self.replans += 1
            self._plan(state)

