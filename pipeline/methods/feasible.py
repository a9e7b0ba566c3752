"""ours + relations + dagger + feasible steps: the best added model, asking the robot's controllers first.

The same fold models as `ours + relations + dagger` (the store holds them
once: the training settings are the same), run with `plan.planner.feasible`:
at each step the best-scored candidate whose preconditions hold in the world
as it is. It answers how much of the remaining failure is steps the robot
could have refused before sending them.
"""

from __future__ import annotations

from dataclasses import dataclass

from pipeline.evaluate.methods import MRFMethod
from pipeline.evaluate.registry import MethodSettings, register
from pipeline.plan.planner import Program, feasible, run_loop
from pipeline.sim.scenarios import Scenario


@dataclass
class FeasibleStepsMethod(MRFMethod):
    """An MRF method whose programs take only steps that can run; fitting and teacher-forced steps as its base."""

    def run(self, scenario: Scenario, max_steps: int) -> Program:
        return run_loop(feasible(self.planner_), scenario.initial, scenario.task, max_steps)


@register("feasible", label="ours + relations + dagger + feasible steps")
def make(settings: MethodSettings) -> FeasibleStepsMethod:
    return FeasibleStepsMethod(features="relations", dagger_rounds=settings.learner.dagger_rounds, name="feasible",
                               store=settings.store, **settings.learner.ssvm)
