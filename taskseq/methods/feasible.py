"""ours + relations + dagger + feasible steps: the best added model, asking the robot's controllers first.

The same fold models as `ours + relations + dagger` (the store holds them
once: the training settings are the same), run with the `feasible` policy
(`plan.planner.feasible`): at each step the best-scored candidate whose
preconditions hold in the world as it is. It answers how much of the
remaining failure is steps the robot could have refused before sending them.
The policy is a field of the method, so a model file trained as this method
records it and `taskseq plan` plans with it.
"""

from __future__ import annotations

from taskseq.evaluate.methods import MRFMethod
from taskseq.evaluate.registry import MethodSettings, register


@register("feasible", label="ours + relations + dagger + feasible steps")
def make(settings: MethodSettings) -> MRFMethod:
    return MRFMethod(features="relations", dagger_rounds=settings.learner.dagger_rounds, name="feasible",
                     store=settings.store, policy="feasible", **settings.learner.ssvm)
