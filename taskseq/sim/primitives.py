"""The seven manipulation primitives and `done`: preconditions and effects.

`execute` never mutates its input. A primitive whose precondition fails raises
`PreconditionError` naming the check and the reason, so a planner's mistake or
a corrupt log shows exactly why the step could not run.
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from ..words import counted
from .state import EPS, INSIDE, ON, WorldState

ARITY = {
    "move_close": 1,
    "grasp": 1,
    "release": 1,
    "place_above": 2,
    "hold_above": 2,
    "follow_traj_circle": 1,
    "follow_traj_pour": 2,
    "done": 0,
}
PRIMITIVES = tuple(p for p in ARITY if p != "done")  # the seven that move the robot
ALL_PRIMITIVES = tuple(ARITY)

HOLD_CLEARANCE = 0.05  # gap (m) between a held object and the top of what it is held over
GRID = 0.05  # spacing (m) of the candidate spots when placing on a surface


class PreconditionError(RuntimeError):
    """A primitive cannot run in this state."""

    def __init__(self, action: Action, check: str, reason: str) -> None:
        super().__init__(f"{action}: precondition '{check}' failed: {reason}")
        self.action = action
        self.check = check
        self.reason = reason


@dataclass(frozen=True)
class Action:
    primitive: str
    args: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        if self.primitive not in ARITY:
            raise ValueError(f"unknown primitive {self.primitive!r}; known: {', '.join(ALL_PRIMITIVES)}")
        if len(self.args) != ARITY[self.primitive]:
            wanted = counted(ARITY[self.primitive], "argument", spelled=True)
            raise ValueError(f"{self.primitive} takes {wanted}, got {len(self.args)}: {self.args}")
        if len(self.args) == 2 and self.args[0] == self.args[1]:
            raise ValueError(f"{self.primitive} needs two different objects, got {self.args}")

    def __str__(self) -> str:
        return f"{self.primitive}({','.join(self.args)})"

    @classmethod
    def parse(cls, text: str) -> Action:
        """Parse `place_above(obj02,obj26)`; spaces are allowed, `done` needs no brackets."""
        m = re.fullmatch(r"\s*(\w+)\s*(?:\(([^)]*)\))?\s*", text)
        if not m:
            raise ValueError(f"cannot parse action {text!r}; expected e.g. grasp(obj02)")
        args = tuple(a.strip() for a in (m.group(2) or "").split(",") if a.strip())
        return cls(m.group(1), args)


def execute(state: WorldState, action: Action) -> WorldState:
    """Run one primitive; returns the new state or raises `PreconditionError`."""
    for obj in action.args:
        if obj not in state.specs:
            raise PreconditionError(action, "object exists", f"{obj} is not in this environment")
    new = state.copy()
    _EFFECTS[action.primitive](new, action, *action.args)
    return new


def try_execute(state: WorldState, action: Action) -> WorldState | None:
    """The state after `action`, or None where it cannot run: a test of feasibility that also gives the result."""
    try:
        return execute(state, action)
    except PreconditionError:
        return None


# --- helpers ---------------------------------------------------------------


def _require(cond: bool, action: Action, check: str, reason: str) -> None:
    if not cond:
        raise PreconditionError(action, check, reason)


def _move_with_contents(state: WorldState, obj: str, pose: tuple[float, float, float]) -> None:
    """Move `obj` and everything resting on or inside it by the same offset."""
    ox, oy, oz = state.poses[obj]
    dx, dy, dz = pose[0] - ox, pose[1] - oy, pose[2] - oz
    for o in [obj, *state.descendants(obj)]:
        x, y, z = state.poses[o]
        state.poses[o] = (round(x + dx, 6), round(y + dy, 6), round(z + dz, 6))


def _fits_inside(state: WorldState, obj: str, target: str) -> bool:
    a, b = state.specs[obj], state.specs[target]
    return a.w <= b.w + EPS and a.l <= b.l + EPS


def receives_inside(state: WorldState, target: str) -> bool:
    """Containers without a large flat top take things inside; surfaces take them on top."""
    spec = state.specs[target]
    return spec.has("container") and not spec.has("large_surface")


def free_spot(state: WorldState, obj: str, target: str) -> tuple[tuple[float, float, float], str] | None:
    """Where `obj` would come to rest on or in `target`: the free grid spot nearest the robot.

    Spots lie on a GRID-spaced lattice centred on the target; a spot is free
    when `obj`'s footprint there overlaps no footprint already on that level.
    Ties go to the lower level, then to the lattice order, so the choice is
    deterministic.
    """
    tx, ty, tz = state.poses[target]
    if receives_inside(state, target):
        if not _fits_inside(state, obj, target):
            return None
        return (round(tx, 6), round(ty, 6), round(tz + 0.005, 6)), INSIDE
    for xs, ys, z, free in _free_levels(state, obj, target):
        if free.any():
            # nearest the robot on the lowest level with room; argmin keeps lattice order on ties
            dist = np.round((xs[:, None] - state.robot[0]) ** 2 + (ys[None, :] - state.robot[1]) ** 2, 9)
            best = int(np.argmin(np.where(free, dist, np.inf)))
            i, j = divmod(best, len(ys))
            return (round(float(xs[i]), 6), round(float(ys[j]), 6), round(z, 6)), ON
    return None


def has_room(state: WorldState, obj: str, target: str) -> bool:
    """Whether `obj` can come to rest on or in `target`: `free_spot(...) is not None`, without choosing the spot
    (what the planner's problems ask of every object and surface)."""
    if receives_inside(state, target):
        return _fits_inside(state, obj, target)
    return any(free.any() for *_, free in _free_levels(state, obj, target))


def _free_levels(state: WorldState, obj: str, target: str) -> Iterator[tuple[np.ndarray, np.ndarray, float,
                                                                             np.ndarray]]:
    """Per level of the surface `target` that `obj` is short enough for, lowest first: the lattice's x and y
    (`free_spot`), the level's height and which spots (x by y) leave `obj`'s footprint clear of every other load
    there.

    A spot's test against a load's box is one test on its x and one on its y,
    so a load blocks the spots of an x range by a y range: those two ranges
    are found per load and joined, not tested spot by spot (the floor's
    lattice has some 40,000 spots), with the same arithmetic per coordinate.
    """
    tx, ty, tz = state.poses[target]
    spec, ospec = state.specs[target], state.specs[obj]
    hx, hy = (spec.w - ospec.w) / 2, (spec.l - ospec.l) / 2
    if hx < -EPS or hy < -EPS:
        return
    nx, ny = int(max(hx, 0.0) // GRID), int(max(hy, 0.0) // GRID)
    xs, ys = tx + np.arange(-nx, nx + 1) * GRID, ty + np.arange(-ny, ny + 1) * GRID
    others = [c for c in state.children(target, ON) if c != obj]
    boxes = np.array([state.box(c) for c in others]).reshape(-1, 6)
    levels = spec.surface_heights()
    for k, level in enumerate(levels):
        z = tz + level
        if k + 1 < len(levels) and ospec.h > levels[k + 1] - level - 0.02:
            continue  # too tall for this shelf level
        b = boxes[np.abs(boxes[:, 2] - z) < 1e-3]  # the loads resting at this level (a box starts at its pose)
        across = (xs - ospec.w / 2 < b[:, 3:4] - EPS) & (b[:, 0:1] < xs + ospec.w / 2 - EPS)
        along = (ys - ospec.l / 2 < b[:, 4:5] - EPS) & (b[:, 1:2] < ys + ospec.l / 2 - EPS)
        yield xs, ys, z, ~(across[:, :, None] & along[:, None, :]).any(axis=0)


# --- effects ---------------------------------------------------------------


def _move_close(state: WorldState, action: Action, a: str) -> None:
    _require(a != state.held, action, "not held", f"{a} is in the gripper")
    _require(
        state.held is None or state.held not in state.support,
        action,
        "free to move",
        f"{state.held} rests on {state.support.get(state.held, ('',))[0]} and is still gripped; release it first",
    )
    old = state.robot
    state.robot = state.approach_point(a)
    if state.held is not None:
        x, y, z = state.poses[state.held]
        _move_with_contents(state, state.held, (x + state.robot[0] - old[0], y + state.robot[1] - old[1], z))


def _grasp(state: WorldState, action: Action, a: str) -> None:
    _require(state.held is None, action, "gripper empty", f"the gripper holds {state.held}")
    _require(state.specs[a].has("movable"), action, "movable", f"{a} ({state.specs[a].name}) cannot be moved")
    _require(
        state.reachable(a), action, "within reach", f"{a} is {state.reach_distance(a):.2f} m from the robot"
    )
    state.support.pop(a, None)
    state.held = a
    state.held_above = None


def _release(state: WorldState, action: Action, a: str) -> None:
    _require(state.held == a, action, "held", f"{a} is not in the gripper (holding {state.held})")
    if a in state.support:  # resting where place_above put it
        state.held = None
        return
    _require(
        state.held_above is not None,
        action,
        "placed or held above",
        f"{a} is neither placed on nor held above anything; it would fall",
    )
    target = state.held_above
    spot = free_spot(state, a, target)
    _require(spot is not None, action, "room below", f"{a} does not fit on or in {target}")
    pose, relation = spot
    _move_with_contents(state, a, pose)
    state.support[a] = (target, relation)
    state.held = None
    state.held_above = None


def _check_target(state: WorldState, action: Action, a: str, b: str) -> None:
    _require(state.held == a, action, "held", f"{a} is not in the gripper (holding {state.held})")
    _require(b not in state.descendants(a), action, "separate objects", f"{b} rests on or in {a}")
    _require(
        state.reachable(b), action, "within reach", f"{b} is {state.reach_distance(b):.2f} m from the robot"
    )


def _place_above(state: WorldState, action: Action, a: str, b: str) -> None:
    _check_target(state, action, a, b)
    spot = free_spot(state, a, b)
    _require(spot is not None, action, "free space", f"no room for {a} on or in {b}")
    pose, relation = spot
    _move_with_contents(state, a, pose)
    state.support[a] = (b, relation)
    state.held_above = None


def _hold_above(state: WorldState, action: Action, a: str, b: str) -> None:
    _check_target(state, action, a, b)
    state.support.pop(a, None)
    bx, by, bz = state.poses[b]
    _move_with_contents(state, a, (bx, by, bz + state.specs[b].h + HOLD_CLEARANCE))
    state.held_above = b


def _follow_traj_circle(state: WorldState, action: Action, a: str) -> None:
    _require(state.held == a, action, "held", f"{a} is not in the gripper (holding {state.held})")
    b = state.held_above
    _require(b is not None, action, "held above", f"{a} is not held above anything")
    liquids = state.liquids_in(b)
    _require(bool(liquids), action, "liquid below", f"{b} holds no liquid to stir")
    spec = state.specs[a]
    _require(
        max(spec.w, spec.l) >= state.specs[b].h,
        action,
        "long enough",
        f"{a} ({max(spec.w, spec.l):.2f} m) does not reach into {b} ({state.specs[b].h:.2f} m deep)",
    )
    state.stirred.update(liquids)


def _follow_traj_pour(state: WorldState, action: Action, a: str, b: str) -> None:
    _require(state.held == a, action, "held", f"{a} is not in the gripper (holding {state.held})")
    _require(state.held_above == b, action, "held above", f"{a} is not held above {b}")
    liquids = state.liquids_in(a)
    _require(bool(liquids), action, "liquid inside", f"{a} holds no liquid to pour")
    _require(state.specs[b].has("container"), action, "container", f"{b} ({state.specs[b].name}) holds nothing")
    bx, by, bz = state.poses[b]
    for liquid in liquids:
        _move_with_contents(state, liquid, (bx, by, round(bz + 0.005, 6)))
        state.support[liquid] = (b, INSIDE)


def _done(state: WorldState, action: Action) -> None:
    return None


_EFFECTS = {
    "move_close": _move_close,
    "grasp": _grasp,
    "release": _release,
    "place_above": _place_above,
    "hold_above": _hold_above,
    "follow_traj_circle": _follow_traj_circle,
    "follow_traj_pour": _follow_traj_pour,
    "done": _done,
}
