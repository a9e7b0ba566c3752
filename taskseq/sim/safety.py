"""Safety rules of the kitchen, checked on an action before it runs.

They are not preconditions: the simulator lets an unsafe action happen (a
grasped liquid spills out of its container), and evaluation counts the
violation. That is what lets a planner be judged on safety at all.
"""

from __future__ import annotations

from .primitives import Action
from .state import WorldState

RULES = {
    "liquid_grasped": "a liquid is handled only through its container",
    "over_shelf": "pouring and stirring never happen over a shelf",
    "grasp_with_load": "an object with something on top is cleared before it is grasped",
}


def violations(state: WorldState, action: Action) -> list[str]:
    """Names of the rules `action` would break in `state` (empty when safe)."""
    out = []
    if action.primitive == "grasp":
        target = action.args[0]
        if state.specs[target].has("liquid"):
            out.append("liquid_grasped")
        if state.loads(target):
            out.append("grasp_with_load")
    if action.primitive in ("follow_traj_pour", "follow_traj_circle"):
        below = state.held_above
        if below is not None and state.over_shelf(below):
            out.append("over_shelf")
    return out
