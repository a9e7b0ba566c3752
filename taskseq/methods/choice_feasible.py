"""ours + relations + choice cues + feasible steps: the choice-cue models, asking the robot's controllers first.

The same fold models as `ours + relations + choice cues` (the store holds
them once: the training settings are the same), run with the `feasible`
policy (`plan.planner.feasible`): at each step the best-scored candidate
whose preconditions hold in the world as it is. It is to the choice cues what
`ours + relations + dagger + feasible steps` is to DAgger: the share of the
remaining failures that are steps the robot could have refused before
sending them. The policy is a field of the method, so a model file trained
as this method records it and `taskseq plan` plans with it.
"""

from __future__ import annotations

from taskseq.methods.spec import MethodSpec, register

SPEC = register(MethodSpec("choice_feasible", "ours + relations + choice cues + feasible steps",
                           lambda b: b.mrf("choice"), policy="feasible"))
