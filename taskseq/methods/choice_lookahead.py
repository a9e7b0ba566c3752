"""ours + relations + choice cues + safety lookahead: the choice-cue models, imagining what a step leads to.

The same fold models as `ours + relations + choice cues` (the store holds
them once), run with the `lookahead` policy (`plan.planner.lookahead`): of the three
best-scored runnable steps, the first whose next four imagined steps, each
the model's own best runnable choice, break no safety rule (stopping counts
as safe; when none is, the best). The failures it
answers are programs in which every single step looked right and the plan as
a whole was unsafe: a vessel on a shelf poured into where it stands, because
the step that would have fetched it first scored just below the step that
grasps the jug. It asks more of the robot than `feasible` does: a model of
its primitives' effects to imagine with, and the kitchen's safety rules.
"""

from __future__ import annotations

from taskseq.methods.spec import MethodSpec, register

SPEC = register(MethodSpec("choice_lookahead", "ours + relations + choice cues + safety lookahead",
                           lambda b: b.mrf("choice"), policy="lookahead"))
