"""Why a closed-loop program fails: one kind per program, read at its first divergence.

A program is compared with the demonstration it agrees with longest. Exact
matches and other successful programs are not failures. A program stopped by
the step cap is a `step_cap` whatever went before (it never ended); one that
reached the goal but broke a safety rule on the way is an `unsafe_step`.
Otherwise the kind is that of the first step where it leaves the demonstration: the step
could not run (`infeasible_step`), broke a safety rule (`unsafe_step`), the
planner chose `done` while the demonstration went on (`stopped_early`) or went
on after the demonstration ended (`stopped_late`), chose the demonstrated
primitive with another object (`wrong_object`) or another primitive
(`wrong_primitive`). A program that follows a demonstration to the end yet
fails (the goal needs more in this state) is `stopped_early` too.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Sequence

from ..plan.planner import INFEASIBLE, STEP_CAP
from ..sim.primitives import Action

KINDS = ("exact", "other_success", "wrong_object", "wrong_primitive", "infeasible_step", "unsafe_step",
         "stopped_early", "stopped_late", "step_cap")
FAILURES = KINDS[2:]


def _common_prefix(a: Sequence[Action], b: Sequence[Action]) -> int:
    k = 0
    while k < min(len(a), len(b)) and a[k] == b[k]:
        k += 1
    return k


def classify(actions: Sequence[Action], status: str, unsafe_steps: Sequence[int], success: bool,
             demonstrations: Sequence[Sequence[Action]], goal_reached: bool = False) -> str:
    """The kind of a program (`actions` executed, `status` of the loop) against the scenario's demonstrations."""
    actions = tuple(actions)
    if any(actions == tuple(d) for d in demonstrations):
        return "exact"
    if success:
        return "other_success"
    if status == STEP_CAP:
        return "step_cap"
    if goal_reached and unsafe_steps:
        return "unsafe_step"
    demo = max(demonstrations, key=lambda d: _common_prefix(actions, d))
    k = _common_prefix(actions, demo)
    if k == len(actions):  # the program stopped (chose done) or broke off where the demonstration goes on
        return "stopped_early"
    if status == INFEASIBLE and k == len(actions) - 1:
        return "infeasible_step"
    if k in unsafe_steps:
        return "unsafe_step"
    if k >= len(demo):
        return "stopped_late"
    ours, theirs = actions[k], demo[k]
    return "wrong_object" if ours.primitive == theirs.primitive else "wrong_primitive"


def failure_counts(kinds: Sequence[str]) -> dict[str, int]:
    """How many programs of each kind, every kind present (zeros included), in `KINDS` order."""
    c = Counter(kinds)
    unknown = set(c) - set(KINDS)
    if unknown:
        raise ValueError(f"unknown program kinds {sorted(unknown)}")
    return {k: c.get(k, 0) for k in KINDS}
