"""ours + relations + choice cues + chained starts + safety lookahead: the method for programs run one after another.

A chained recipe (`recipes` stage) starts each program where the last one
left the room, often with something still in the hand. The choice-cue model
trained also on chained starts (`imitation.starts`: per training scenario, a
demonstration that starts where it ended) has seen such states; the
`lookahead` policy (`plan.planner.lookahead`) keeps the plan that follows
from one of them safe. Measured on the development world before it was
added: recipes without feedback 11 of 12, against 6 for `chained` and 9 for
the choice cues with or without the lookahead (docs/model.md, "Safety
lookahead"). It is the `recipes` stage's added method; it also has its
Table I row, where it pays for the chained starts as `chained` does.
"""

from __future__ import annotations

from taskseq.methods.spec import MethodSpec, register

SPEC = register(MethodSpec("choice_chained_lookahead",
                           "ours + relations + choice cues + chained starts + safety lookahead",
                           lambda b: b.mrf("choice", chained_starts=True), policy="lookahead"))
