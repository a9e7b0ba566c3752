"""The world state: where every box is, what rests on what, the robot and its gripper.

A pose is the centre of the box's bottom face, so an object resting on a
surface at height z has pose z equal to that height.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from .objects import ObjectSpec

ON = "on"
INSIDE = "inside"

# Horizontal distance (m) from the robot base to an object's footprint within
# which the arm can grasp it or place something on it.
REACH = 0.8
# How far in front of the furniture the robot parks when it moves close.
STANDOFF = 0.35
# Geometry tolerance (m): touching boxes collide, rounding does not separate them.
EPS = 1e-6


def footprint_distance(box: tuple[float, ...], point: tuple[float, float]) -> float:
    """Horizontal distance from `point` to the nearest point of a box's footprint (`WorldState.box` order)."""
    xmin, ymin, _, xmax, ymax, _ = box
    dx = max(xmin - point[0], 0.0, point[0] - xmax)
    dy = max(ymin - point[1], 0.0, point[1] - ymax)
    return math.hypot(dx, dy)


def within_reach(box: tuple[float, ...], point: tuple[float, float]) -> bool:
    """Whether a robot based at `point` reaches a box (`WorldState.box` order): the one reach threshold."""
    return footprint_distance(box, point) <= REACH + EPS


@dataclass
class WorldState:
    """Mutable state; primitives copy it before changing it."""

    specs: dict[str, ObjectSpec]
    poses: dict[str, tuple[float, float, float]]
    support: dict[str, tuple[str, str]]  # child -> (parent, relation)
    robot: tuple[float, float]
    held: str | None = None
    held_above: str | None = None
    stirred: set[str] = field(default_factory=set)

    def copy(self) -> WorldState:
        return WorldState(
            specs=self.specs,
            poses=dict(self.poses),
            support=dict(self.support),
            robot=self.robot,
            held=self.held,
            held_above=self.held_above,
            stirred=set(self.stirred),
        )

    def key(self) -> tuple:
        """What the primitives change, hashable: two states that share their `specs` (every state of one program
        does) and have equal keys are the same world. Dict order counts, so equal keys also list objects alike."""
        return (tuple(self.poses.items()), tuple(self.support.items()), self.robot, self.held, self.held_above,
                frozenset(self.stirred))

    # --- relations -------------------------------------------------------
    def children(self, parent: str, relation: str | None = None) -> list[str]:
        return sorted(
            c for c, (p, r) in self.support.items() if p == parent and (relation is None or r == relation)
        )

    def loads(self, obj: str) -> list[str]:
        """Objects resting on top of `obj` (not inside it)."""
        return self.children(obj, ON)

    def liquids_in(self, obj: str) -> list[str]:
        return [c for c in self.children(obj, INSIDE) if self.specs[c].has("liquid")]

    def container_of(self, obj: str) -> str | None:
        parent = self.support.get(obj)
        return parent[0] if parent and parent[1] == INSIDE else None

    def ancestors(self, obj: str) -> list[str]:
        chain = []
        cur = obj
        while cur in self.support:
            cur = self.support[cur][0]
            chain.append(cur)
        return chain

    def descendants(self, obj: str) -> list[str]:
        out: list[str] = []
        stack = [obj]
        while stack:
            cur = stack.pop()
            for child in self.children(cur):
                out.append(child)
                stack.append(child)
        return out

    def furniture_under(self, obj: str) -> str | None:
        """The first table, shelf or floor below `obj` (itself if it is furniture)."""
        for cand in [obj, *self.ancestors(obj)]:
            if self.specs[cand].category in ("table", "shelf", "floor"):
                return cand
        return None

    def over_shelf(self, obj: str) -> bool:
        """True when `obj` rests, directly or through others, on a multi-surface object."""
        return any(self.specs[a].has("multi_surface") for a in self.ancestors(obj))

    # --- geometry --------------------------------------------------------
    def box(self, obj: str) -> tuple[float, float, float, float, float, float]:
        """(xmin, ymin, zmin, xmax, ymax, zmax) of `obj`."""
        x, y, z = self.poses[obj]
        w, l, h = self.specs[obj].size  # noqa: E741
        return (x - w / 2, y - l / 2, z, x + w / 2, y + l / 2, z + h)

    def overlap_top(self, a: str, b: str) -> bool:
        """Footprints share area when seen from above."""
        ba, bb = self.box(a), self.box(b)
        return all(ba[i] < bb[i + 3] - EPS and bb[i] < ba[i + 3] - EPS for i in range(2))

    def distance(self, obj: str) -> float:
        """Horizontal distance from the robot base to the object's centre."""
        x, y, _ = self.poses[obj]
        return math.hypot(x - self.robot[0], y - self.robot[1])

    def reach_distance(self, obj: str) -> float:
        """Horizontal distance from the robot base to the nearest point of the footprint."""
        return footprint_distance(self.box(obj), self.robot)

    def reachable(self, obj: str) -> bool:
        return within_reach(self.box(obj), self.robot)

    def shelved(self) -> set[str]:
        """Every object `over_shelf` holds for, found in one walk down from the multi-surface objects."""
        below: dict[str, list[str]] = {}
        for child, (parent, _) in self.support.items():
            below.setdefault(parent, []).append(child)
        out: set[str] = set()
        stack = [o for o, spec in self.specs.items() if spec.has("multi_surface") and o in below]
        while stack:
            for child in below.get(stack.pop(), ()):
                if child not in out:
                    out.add(child)
                    stack.append(child)
        return out

    def approach_point(self, obj: str) -> tuple[float, float]:
        """Where the robot parks to work on `obj`: in front of its furniture, level with it."""
        x, _, _ = self.poses[obj]
        base = self.furniture_under(obj)
        if base is None or self.specs[base].category == "floor":
            base = obj
        _, ymin, _, _, _, _ = self.box(base)
        return (round(x, 6), round(ymin - STANDOFF, 6))
