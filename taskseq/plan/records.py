"""What a program did, and whether it succeeded: stopped by choice, goal reached and no safety rule broken.

A program is the record of one closed-loop rollout (`plan.planner.run_loop`):
its steps, the world before each, and why it stopped. Every success rate of
the reports counts `Program.success`, defined here once.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from ..sim.primitives import Action
from ..sim.state import WorldState
from ..sim.tasks import Task, goal_reached

DONE = "done"
STEP_CAP = "step_cap"
INFEASIBLE = "infeasible"


@dataclass
class PlanStep:
    action: Action
    score: float
    alternatives: list[tuple[Action, float]]  # the policy's other proposals in its order (a lookahead may have
    # passed over better-scored ones)
    unsafe: list[str] = field(default_factory=list)  # safety rules the action breaks


def reached(program: Program) -> bool:
    """The task's goal holds in the world the program left, judged against the world it started from."""
    return goal_reached(program.task, program.states[0], program.states[-1])


def unbroken(program: Program) -> bool:
    """No step broke a safety rule."""
    return not any(step.unsafe for step in program.steps)


def succeeded(program: Program) -> bool:
    """Stopped by choice (`done`, neither the step cap nor an infeasible step), goal reached and no safety rule
    broken."""
    return program.status == DONE and reached(program) and unbroken(program)


@dataclass
class Program:
    """What a rollout did: its steps and the world before each, and why it stopped.

    `states[k]` is the world before step k, and the last one the world the
    program left: len(steps) + 1 states, or len(steps) when the last step was
    infeasible (it changed nothing). Recordings and metrics read these states,
    so nothing is executed a second time.
    """

    task: Task
    steps: list[PlanStep]
    status: str  # DONE, STEP_CAP or INFEASIBLE
    states: list[WorldState]
    error: str | None = None

    @property
    def initial(self) -> WorldState:
        return self.states[0]

    @property
    def final(self) -> WorldState:
        return self.states[-1]

    @property
    def actions(self) -> list[Action]:
        return [s.action for s in self.steps]

    # plain functions, so that each is one definition and mutation testing reaches them (it leaves decorated
    # functions alone)
    goal_reached = property(reached)
    safe = property(unbroken)
    success = property(succeeded)
