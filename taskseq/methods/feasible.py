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

from taskseq.methods.builtin import DaggerSettings
from taskseq.methods.spec import MethodSpec, register

SPEC = register(MethodSpec("feasible", "ours + relations + dagger + feasible steps",
                           lambda b: b.mrf("relations", dagger_rounds=b.settings.dagger_rounds), policy="feasible",
                           settings=DaggerSettings))
