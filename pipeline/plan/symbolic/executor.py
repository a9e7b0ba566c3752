"""Symbolic planning in the simulator: plan, execute, replan when a step fails."""

from __future__ import annotations

from ...settings import Pddl
from ...sim.primitives import Action, PreconditionError, execute
from ...sim.safety import violations
from ...sim.state import WorldState
from ...sim.tasks import Task
from ..planner import DONE, INFEASIBLE, STEP_CAP, PlanStep, Program
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


def run_symbolic(state: WorldState, task: Task, roles: dict[str, str], max_steps: int = 20,
                 horizon: int = HORIZON) -> Program:
    """Execute a shortest plan step by step; if a step turns out infeasible, replan from where the robot is."""
    initial, steps, replans = state, [], 0
    result = plan_from(state, task, roles, horizon)
    queue = list(result.plan or [])
    while True:
        if result.plan is None:
            return Program(task, steps, INFEASIBLE, initial, state, result.message())
        if not queue:
            return Program(task, steps, DONE, initial, state)
        if len(steps) == max_steps:
            return Program(task, steps, STEP_CAP, initial, state)
        action = queue.pop(0).primitive()
        try:
            after = execute(state, action)
        except PreconditionError as err:
            replans += 1
            if replans > MAX_REPLANS:
                steps.append(PlanStep(action, 0.0, [], violations(state, action)))
                return Program(task, steps, INFEASIBLE, initial, state, str(err))
            result = plan_from(state, task, roles, horizon)
            queue = list(result.plan or [])
            continue
        steps.append(PlanStep(action, 0.0, [], violations(state, action)))
        state = after
