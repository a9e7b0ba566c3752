"""ours + relations + choice cues: the relations model, with bits for the object that stands out among like ones.

Where a task leaves the object open, the demonstrator takes the smallest
empty vessel that holds the liquid, the shortest stirrer that sticks out of
the cup, the bin nearest the object. The relation features compare each
object with the task's objects one at a time; the cues (`features.cues`)
add the comparison among the candidates: the smallest of the empty
containers that hold enough, the shortest of the thin objects that reach out,
the nearest of each kind. Feature set `choice` is `relations` plus these
two blocks (`learn.mrf.CUE_FAMILY`).
"""

from __future__ import annotations

from taskseq.methods.spec import MethodSpec, register

SPEC = register(MethodSpec("choice", "ours + relations + choice cues", lambda b: b.mrf("choice")))
