"""Environments drawn from a distribution: the `procedural` world family.

The paper-shaped benchmark (`catalog.py`) is the same 13 rooms in every world
seed. Here the world seed draws the rooms themselves: which furniture stands
along the wall and where, which objects there are, how big each one is, and
where it rests. Objects are catalog objects with their sizes varied, or
objects of kinds the catalog never had (a tumbler, a jug, a ladle, a pedal
bin), drawn from size ranges, with the flags that can vary for the kind (its
shape, a handle) drawn too. Attributes follow from the drawn size and flags, as
for every object, so the model meets attribute vectors it never saw in training.

The distribution is fixed here (the new kinds) and in `settings.Procedural`; the
reasons for each value are in docs/world.md. A drawn room is kept only when it
passes the world's checks (`check_fits` and the catalog's overlap check) and
the demonstrator can do every one of the five tasks in it; a room that fails
is drawn again, and every redraw is counted by reason (`DrawReport`).
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterator
from dataclasses import dataclass, field, replace

import numpy as np

from ..settings import Procedural
from .catalog import OBJECTS, OBJECTS_BY_ID, EnvironmentSpec, Placement, build_environment, item_pose, on_furniture
from .objects import POURERS, VESSELS, ObjectSpec
from .state import ON, WorldState

SHELF_CLEARANCE = 0.02  # an item on a shelf level stays this far below the next level (as `free_spot` requires)
WALL_GAP = (0.2, 0.8)  # gap (m) between neighbouring furniture along the wall, as in the catalog's rooms
MAX_REDRAWS = 200  # attempts at one room before the distribution is declared unable to produce it


# Flags an object of a new kind may have or lack. The rest define what the kind is for (a vessel receives
# liquid, a cutting board carries a load, a liquid is poured), so they never vary; `movable` varies for bins
# only, since everything else is there to be picked up.
SHAPES = ("cylinder", "box")
VARIABLE_FLAGS = frozenset({*SHAPES, "handle"})


@dataclass(frozen=True)
class Kind:
    """An object kind the catalog never had: a name, a category the simulator knows, size ranges (m) and flags.

    `flags` every object of the kind has. `shapes` gives the probability of each shape flag (`""`: neither, a
    tapered or flat object), one drawn per object; empty when the shape is fixed in `flags`. `maybe` gives,
    for the other flags that can vary for the kind, the probability that an object has the flag. Why each
    value: docs/world.md, "Drawn rooms".
    """

    name: str
    category: str
    flags: str
    width: tuple[float, float]
    length: tuple[float, float]  # (0, 0): round, as long as it is wide
    height: tuple[float, float]
    shapes: tuple[tuple[str, float], ...] = ()
    maybe: tuple[tuple[str, float], ...] = ()

    def __post_init__(self) -> None:
        fixed = set(self.flags.split())
        varying = {f for f, _ in self.maybe} | ({*SHAPES} if self.shapes else set())
        allowed = VARIABLE_FLAGS | ({"movable"} if self.category == "bin" else set())
        if varying - allowed:
            raise ValueError(f"kind {self.name}: {sorted(varying - allowed)} define the kind and cannot vary")
        if fixed & varying:
            raise ValueError(f"kind {self.name}: {sorted(fixed & varying)} both fixed and drawn")
        if self.shapes and ({s for s, _ in self.shapes} - {*SHAPES, ""}
                            or abs(sum(p for _, p in self.shapes) - 1) > 1e-9):
            raise ValueError(f"kind {self.name}: shapes must be cylinder, box or '' with probabilities summing to 1")
        if not all(0 < p < 1 for _, p in self.maybe):
            raise ValueError(f"kind {self.name}: the probability of a drawn flag must lie in (0, 1)")

    def draw_flags(self, rng: np.random.Generator) -> frozenset[str]:
        """The fixed flags, one shape drawn from `shapes`, and each flag of `maybe` with its probability."""
        flags = set(self.flags.split())
        if self.shapes:
            shapes, probs = zip(*self.shapes, strict=True)
            flags.add(shapes[int(rng.choice(len(shapes), p=probs))])
        flags.update(f for f, p in self.maybe if rng.uniform() < p)
        return frozenset(flags - {""})


NEW_KINDS: dict[str, tuple[Kind, ...]] = {
    "vessel": (
        Kind("tumbler", "tumbler", "container movable", (0.06, 0.085), (0, 0), (0.09, 0.14),
             shapes=(("cylinder", 0.7), ("", 0.3))),
        Kind("beaker", "beaker", "cylinder container movable", (0.07, 0.1), (0, 0), (0.1, 0.16),
             maybe=(("handle", 0.25),)),
        Kind("ramekin", "ramekin", "container movable", (0.08, 0.12), (0, 0), (0.04, 0.06),
             shapes=(("cylinder", 0.8), ("box", 0.2)), maybe=(("handle", 0.15),)),
        Kind("soup_mug", "mug", "container handle movable", (0.1, 0.12), (0.13, 0.16), (0.09, 0.12),
             shapes=(("cylinder", 0.85), ("", 0.15))),
    ),
    "pourer": (
        Kind("jug", "jug", "container movable", (0.11, 0.15), (0.15, 0.2), (0.18, 0.25),
             shapes=(("cylinder", 0.6), ("box", 0.1), ("", 0.3)), maybe=(("handle", 0.85),)),
        Kind("flask", "flask", "container movable", (0.06, 0.09), (0, 0), (0.2, 0.3),
             shapes=(("cylinder", 0.7), ("", 0.3)), maybe=(("handle", 0.1),)),
        Kind("thermos", "thermos", "cylinder container movable", (0.08, 0.1), (0, 0), (0.25, 0.32),
             maybe=(("handle", 0.4),)),
    ),
    "stirrer": (
        Kind("stir_stick", "stirrer", "movable", (0.005, 0.012), (0.15, 0.25), (0.005, 0.01),
             shapes=(("cylinder", 0.4), ("", 0.6))),
        Kind("dessert_spoon", "stirrer", "movable", (0.03, 0.04), (0.16, 0.2), (0.015, 0.02)),
        Kind("ladle", "stirrer", "handle movable", (0.07, 0.09), (0.28, 0.35), (0.05, 0.07)),
    ),
    "bin": (
        Kind("pedal_bin", "bin", "container", (0.3, 0.4), (0, 0), (0.4, 0.55),
             shapes=(("cylinder", 0.6), ("box", 0.4)), maybe=(("movable", 0.3),)),
        Kind("crate_bin", "bin", "box container", (0.3, 0.4), (0.25, 0.35), (0.25, 0.35),
             maybe=(("movable", 0.8), ("handle", 0.5))),
    ),
    "item": (
        Kind("notebook", "item", "box movable", (0.15, 0.21), (0.21, 0.3), (0.01, 0.02)),
        Kind("napkin", "item", "movable", (0.1, 0.15), (0.1, 0.15), (0.005, 0.01)),
        Kind("remote", "item", "box movable", (0.04, 0.06), (0.15, 0.2), (0.02, 0.03)),
        Kind("cutting_board", "item", "box movable large_surface", (0.25, 0.4), (0.2, 0.3), (0.015, 0.03),
             maybe=(("handle", 0.35),)),
    ),
    "liquid": (
        Kind("lemonade", "liquid", "cylinder liquid movable", (0.05, 0.08), (0, 0), (0.04, 0.08)),
        Kind("broth", "liquid", "liquid movable", (0.05, 0.08), (0.05, 0.08), (0.04, 0.07)),
        Kind("cocoa", "liquid", "cylinder liquid movable", (0.05, 0.07), (0, 0), (0.04, 0.06)),
    ),
}

_FLAT = ("book", "magazine", "notebook")  # items other things are stacked on
_SURFACE_ITEMS = ("tray", "cutting_board")  # movable large surfaces that carry a load


def _catalog(*categories: str) -> tuple[ObjectSpec, ...]:
    return tuple(o for o in OBJECTS if o.category in categories)


CATALOG_KINDS: dict[str, tuple[ObjectSpec, ...]] = {
    "table": _catalog("table"),
    "shelf": _catalog("shelf"),
    "bin": _catalog("bin"),
    "vessel": _catalog(*VESSELS),
    "pourer": _catalog(*POURERS),
    "stirrer": _catalog("stirrer"),
    "item": _catalog("item"),
    "liquid": _catalog("liquid"),
}


@dataclass
class DrawReport:
    """What drawing a world cost: rooms kept, and redraws by reason."""

    environments: int = 0
    redraws: Counter[str] = field(default_factory=Counter)

    def as_dict(self) -> dict[str, object]:
        return {"environments": self.environments, "redraws": sum(self.redraws.values()),
                "redraws_by_reason": dict(sorted(self.redraws.items()))}


class Redraw(Exception):
    """This room cannot be kept; `reason` is what the report counts it under."""

    def __init__(self, reason: str, detail: str) -> None:
        super().__init__(f"{reason}: {detail}")
        self.reason = reason


def check_fits(state: WorldState) -> list[str]:
    """Everything fits where it stands: within its support's top face, under the next shelf level, inside its
    container; an empty list when it does."""
    problems = []
    for obj, (parent, relation) in sorted(state.support.items()):
        spec, pspec = state.specs[obj], state.specs[parent]
        if pspec.category == "floor":
            continue
        x0, y0, z0, x1, y1, _ = state.box(obj)
        px0, py0, _, px1, py1, _ = state.box(parent)
        if relation != ON:
            if spec.w > pspec.w or spec.l > pspec.l or spec.h > pspec.h:
                problems.append(f"{obj} is larger than {parent}, which holds it")
            continue
        if x0 < px0 - 1e-6 or x1 > px1 + 1e-6 or y0 < py0 - 1e-6 or y1 > py1 + 1e-6:
            problems.append(f"{obj} overhangs {parent}")
        levels = pspec.surface_heights()
        if pspec.category == "shelf":
            level = min(range(len(levels)), key=lambda k: abs(state.poses[parent][2] + levels[k] - z0))
            top = max(state.box(o)[5] for o in [obj, *state.descendants(obj)])
            if level + 1 < len(levels) and top > state.poses[parent][2] + levels[level + 1] - SHELF_CLEARANCE + 1e-6:
                problems.append(f"{obj} does not fit under level {level + 1} of {parent}")
    return problems


def _uniform(rng: np.random.Generator, bounds: tuple[float, float]) -> float:
    return round(float(rng.uniform(*bounds)), 3)


def _count(rng: np.random.Generator, bounds: tuple[int, ...]) -> int:
    return int(rng.integers(bounds[0], bounds[1] + 1))


class _Room:
    """One room being drawn: its objects, furniture and placements, with fresh ids."""

    def __init__(self, env_id: str, dist: Procedural, rng: np.random.Generator) -> None:
        self.env_id, self.dist, self.rng = env_id, dist, rng
        self.objects: dict[str, ObjectSpec] = {"obj01": OBJECTS_BY_ID["obj01"]}
        self.items: list[Placement] = []

    def _id(self) -> str:
        return f"{self.env_id}_{len(self.objects):02d}"

    def varied(self, spec: ObjectSpec, keep_height: bool = False) -> ObjectSpec:
        """A catalog object with each dimension scaled by up to the distribution's spread."""
        s = self.dist.size_spread
        w, l, h = (round(v * float(self.rng.uniform(1 - s, 1 + s)), 3) for v in spec.size)  # noqa: E741
        oid = self._id()
        self.objects[oid] = replace(spec, id=oid, size=(w, l, spec.h if keep_height else h))
        return self.objects[oid]

    def new(self, kind: Kind) -> ObjectSpec:
        w = _uniform(self.rng, kind.width)
        l = _uniform(self.rng, kind.length) if kind.length != (0, 0) else w  # noqa: E741
        oid = self._id()
        self.objects[oid] = ObjectSpec(oid, kind.name, kind.category, (w, l, _uniform(self.rng, kind.height)),
                                       kind.draw_flags(self.rng))
        return self.objects[oid]

    def draw(self, kind: str) -> ObjectSpec:
        """An object of `kind`: new with probability `new_objects` (where new kinds exist), else a varied one."""
        if kind in NEW_KINDS and self.rng.uniform() < self.dist.new_objects:
            return self.new(NEW_KINDS[kind][int(self.rng.integers(len(NEW_KINDS[kind])))])
        pool = CATALOG_KINDS[kind]
        return self.varied(pool[int(self.rng.integers(len(pool)))], keep_height=kind == "shelf")

    def liquid_in(self, container: ObjectSpec) -> None:
        """A liquid sized to fit inside `container`."""
        liquid = self.draw("liquid")
        w, l, h = liquid.size  # noqa: E741
        inner = 0.9 * min(container.w, container.l)
        fitted = replace(liquid, size=(min(w, inner), min(l, inner), min(h, 0.8 * container.h)))
        self.objects[liquid.id] = fitted
        self.items.append(Placement(fitted.id, container.id))


def _furniture(room: _Room) -> tuple[tuple[tuple[str, float], ...], float]:
    """Furniture along the wall in a drawn order with drawn gaps; the robot starts in front of a table."""
    dist, rng = room.dist, room.rng
    pieces = ([room.draw("table") for _ in range(_count(rng, dist.tables))]
              + [room.draw("shelf") for _ in range(_count(rng, dist.shelves))]
              + [room.draw("bin") for _ in range(_count(rng, dist.bins))])
    pieces = [pieces[i] for i in rng.permutation(len(pieces))]
    xs, x = [], 0.0
    for i, spec in enumerate(pieces):
        if i:
            x += pieces[i - 1].w / 2 + _uniform(rng, WALL_GAP) + spec.w / 2
        xs.append(x)
    tables = [x for spec, x in zip(pieces, xs, strict=True) if spec.category == "table"]
    robot_x = round(tables[int(rng.integers(len(tables)))] + float(rng.uniform(-0.5, 0.5)), 2)
    return tuple((spec.id, round(x, 3)) for spec, x in zip(pieces, xs, strict=True)), robot_x


def _spots(room: _Room, furniture: tuple[tuple[str, float], ...], spec: ObjectSpec) -> Iterator[Placement]:
    """Placements of `spec` to try, in a drawn order: a surface of the furniture, or the top of a flat item."""
    rng, objects = room.rng, room.objects
    hosts = [o for o, _ in furniture if on_furniture(objects[o])]
    flats = [p.obj for p in room.items if objects[p.obj].name in _FLAT + _SURFACE_ITEMS]
    stack = bool(flats) and spec.w < 0.15 and spec.l < 0.3 and rng.uniform() < room.dist.stacks
    for _ in range(40):
        if stack:
            host = objects[flats[int(rng.integers(len(flats)))]]
            room_x = max((host.w - spec.w) / 2, 0.0)
            yield Placement(spec.id, host.id, dx=round(float(rng.uniform(-room_x, room_x)), 3))
            continue
        host = objects[hosts[int(rng.integers(len(hosts)))]]
        level = int(rng.integers(len(host.surface_heights())))
        back = host.category == "table" and rng.uniform() < 0.3
        room_x = (host.w - spec.w) / 2
        if room_x > 0:
            yield Placement(spec.id, host.id, level, round(float(rng.uniform(-room_x, room_x)), 3), back)


def _fits(state: WorldState, spec: ObjectSpec, pl: Placement) -> bool:
    """`spec` placed at `pl` stays on its host and overlaps nothing already at that height there."""
    trial = state.copy()
    trial.specs = {**state.specs, spec.id: spec}
    trial.poses[spec.id], relation = item_pose(state.poses[pl.on], state.specs[pl.on], spec, pl)
    trial.support[spec.id] = (pl.on, relation)
    if check_fits(trial):
        return False
    z = trial.poses[spec.id][2]
    return not any(abs(trial.poses[o][2] - z) < 1e-6 and trial.overlap_top(o, spec.id)
                   for o in state.children(pl.on, ON))


def _place(room: _Room, furniture: tuple[tuple[str, float], ...], spec: ObjectSpec) -> None:
    state = build_environment(EnvironmentSpec(room.env_id, furniture, tuple(room.items)), objects=room.objects)
    for pl in _spots(room, furniture, spec):
        if _fits(state, spec, pl):
            room.items.append(pl)
            return
    raise Redraw("no room for an object", spec.name)


def draw_room(env_id: str, dist: Procedural, rng: np.random.Generator) -> tuple[EnvironmentSpec, dict[str, ObjectSpec]]:
    """One room and its objects; raises `Redraw` when something does not fit."""
    room = _Room(env_id, dist, rng)
    furniture, robot_x = _furniture(room)
    counts = [("item", _count(rng, dist.items)), ("pourer", _count(rng, dist.pourers)),
              ("vessel", _count(rng, dist.vessels)), ("stirrer", _count(rng, dist.stirrers))]
    filled = _count(rng, dist.filled_vessels)
    for kind, n in counts:
        for i in range(n):
            spec = room.draw(kind)
            _place(room, furniture, spec)
            if kind == "pourer" or (kind == "vessel" and i < filled):
                room.liquid_in(spec)
    env = EnvironmentSpec(env_id, furniture, tuple(room.items), robot_x)
    state = build_environment(env, objects=room.objects)  # the catalog's overlap check runs here
    problems = check_fits(state)
    if problems:
        raise Redraw("does not fit", problems[0])
    return env, room.objects
