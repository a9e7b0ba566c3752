"""The benchmark world: 43 objects and the 13 environments built from them.

Furniture stands along a wall (its back edge at y = depth); the robot starts
1.5 m in front of it. Items rest on furniture at a level and a sideways
offset, on other items (stacks), or inside containers (liquids). The seed of
`build_environment` only jitters item positions by a centimetre or so, so
every seed gives the same kind of scene and the demonstrator's choices stay
forced by attributes and geometry.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from .objects import ObjectSpec
from .state import INSIDE, ON, WorldState

F = frozenset


def _o(i: int, name: str, category: str, size: tuple[float, float, float], flags: str, levels=()) -> ObjectSpec:
    return ObjectSpec(f"obj{i:02d}", name, category, size, F(flags.split()), tuple(levels))


OBJECTS: tuple[ObjectSpec, ...] = (
    # furniture
    _o(1, "floor", "floor", (10.0, 10.0, 0.01), "box large_surface"),
    _o(2, "kitchen_table", "table", (1.6, 0.9, 0.75), "box large_surface"),
    _o(3, "dining_table", "table", (2.0, 1.0, 0.74), "box large_surface"),
    _o(4, "coffee_table", "table", (1.0, 0.6, 0.45), "box large_surface"),
    _o(5, "side_table", "table", (0.6, 0.5, 0.62), "cylinder large_surface"),
    _o(6, "counter", "table", (2.4, 0.65, 0.9), "box large_surface"),
    _o(7, "bookshelf", "shelf", (0.9, 0.35, 1.8), "box large_surface multi_surface", (0.45, 0.85, 1.25, 1.65)),
    _o(8, "kitchen_shelf", "shelf", (1.2, 0.4, 1.5), "box large_surface multi_surface", (0.5, 0.8, 1.1, 1.4)),
    _o(9, "wall_cabinet", "shelf", (1.0, 0.32, 1.3), "box large_surface multi_surface", (0.4, 0.7, 1.0)),
    # bins
    _o(10, "trash_can", "bin", (0.4, 0.4, 0.65), "cylinder container"),
    _o(11, "recycling_bin", "bin", (0.5, 0.38, 0.6), "box container"),
    _o(12, "wastebasket", "bin", (0.3, 0.3, 0.35), "cylinder container movable"),
    # vessels one drinks or serves from
    _o(13, "mug", "mug", (0.085, 0.12, 0.10), "cylinder container handle movable"),
    _o(14, "cup", "cup", (0.075, 0.075, 0.09), "cylinder container movable"),
    _o(15, "glass", "glass", (0.065, 0.065, 0.14), "cylinder container movable"),
    _o(16, "bowl", "bowl", (0.16, 0.16, 0.075), "cylinder container movable"),
    _o(17, "teacup", "teacup", (0.09, 0.115, 0.065), "cylinder container handle movable"),
    _o(18, "pot", "pot", (0.24, 0.33, 0.16), "cylinder container handle movable"),
    _o(19, "large_mug", "mug", (0.1, 0.14, 0.12), "cylinder container handle movable"),
    # containers liquids come in
    _o(20, "water_bottle", "bottle", (0.07, 0.07, 0.25), "cylinder container movable"),
    _o(21, "milk_carton", "carton", (0.095, 0.07, 0.24), "box container movable"),
    _o(22, "juice_pitcher", "pitcher", (0.13, 0.18, 0.22), "cylinder container handle movable"),
    _o(23, "soda_can", "can", (0.066, 0.066, 0.122), "cylinder container movable"),
    _o(24, "kettle", "kettle", (0.17, 0.25, 0.2), "cylinder container handle movable"),
    _o(25, "coffee_pot", "pitcher", (0.14, 0.2, 0.18), "container handle movable"),
    _o(26, "sugar_jar", "jar", (0.1, 0.1, 0.14), "cylinder container movable"),
    # liquids (sugar pours like one)
    _o(27, "water", "liquid", (0.06, 0.06, 0.06), "cylinder liquid movable"),
    _o(28, "milk", "liquid", (0.08, 0.06, 0.07), "box liquid movable"),
    _o(29, "juice", "liquid", (0.07, 0.07, 0.08), "cylinder liquid movable"),
    _o(30, "soda", "liquid", (0.06, 0.06, 0.05), "cylinder liquid movable"),
    _o(31, "tea", "liquid", (0.08, 0.08, 0.05), "cylinder liquid movable"),
    _o(32, "coffee", "liquid", (0.07, 0.07, 0.07), "liquid movable"),
    _o(33, "sugar", "liquid", (0.06, 0.06, 0.04), "cylinder liquid movable"),
    # stirrers of several lengths
    _o(34, "teaspoon", "stirrer", (0.03, 0.14, 0.015), "movable"),
    _o(35, "tablespoon", "stirrer", (0.04, 0.19, 0.02), "movable"),
    _o(36, "long_spoon", "stirrer", (0.035, 0.28, 0.02), "movable"),
    _o(37, "chopstick", "stirrer", (0.008, 0.24, 0.008), "cylinder movable"),
    # other things
    _o(38, "spatula", "item", (0.08, 0.3, 0.02), "box movable"),
    _o(39, "book", "item", (0.16, 0.23, 0.035), "box movable"),
    _o(40, "magazine", "item", (0.21, 0.28, 0.006), "box movable"),
    _o(41, "tray", "item", (0.42, 0.3, 0.03), "box movable large_surface"),
    _o(42, "cereal_box", "item", (0.07, 0.19, 0.28), "box container movable"),
    _o(43, "crumpled_paper", "item", (0.07, 0.07, 0.06), "movable"),
)
OBJECTS_BY_ID = {o.id: o for o in OBJECTS}

FRONT_GAP = 0.08  # distance (m) from a surface's front edge to the items on it
ROBOT_START_Y = -1.5


@dataclass(frozen=True)
class Placement:
    """An item on furniture (level, sideways offset), on another item, or inside a container."""

    obj: str
    on: str
    level: int = 0
    dx: float = 0.0
    back: bool = False  # second row, further from the robot


def _p(obj: int, on: int, level: int = 0, dx: float = 0.0, back: bool = False) -> Placement:
    return Placement(f"obj{obj:02d}", f"obj{on:02d}", level, dx, back)


@dataclass(frozen=True)
class EnvironmentSpec:
    id: str
    furniture: tuple[tuple[str, float], ...]  # (object, x of its centre); floor is implicit
    items: tuple[Placement, ...]
    robot_x: float = 0.0


def _env(i: int, furniture: dict[int, float], items: list[Placement], robot_x: float = 0.0) -> EnvironmentSpec:
    return EnvironmentSpec(
        f"env{i:02d}", tuple((f"obj{k:02d}", x) for k, x in furniture.items()), tuple(items), robot_x
    )


ENVIRONMENTS: tuple[EnvironmentSpec, ...] = (
    _env(1, {2: 0.0, 8: 2.2, 10: -1.2}, [
        _p(20, 2, dx=-0.15), _p(27, 20), _p(14, 2, dx=0.55), _p(34, 2, dx=0.25), _p(40, 2, dx=-0.5),
        _p(43, 40, dx=-0.05), _p(37, 40, dx=0.06), _p(13, 2, dx=0.1, back=True), _p(31, 13),
        _p(16, 8, 0, -0.3), _p(35, 8, 0, 0.3), _p(17, 8, 2, 0.2), _p(32, 17), _p(22, 8, 1, -0.2), _p(29, 22),
    ]),
    _env(2, {3: 0.0, 7: -1.9, 5: 1.8, 11: 2.9}, [
        _p(22, 3, dx=-0.3), _p(29, 22), _p(17, 3, dx=0.4), _p(13, 3, dx=0.8), _p(33, 13), _p(36, 3, dx=0.1),
        _p(39, 3, dx=-0.8), _p(34, 39, dx=-0.04), _p(43, 39, dx=0.045), _p(14, 3, dx=-0.2, back=True),
        _p(30, 14), _p(15, 7, 1, 0.2), _p(42, 7, 0, -0.2), _p(21, 7, 2, 0.0), _p(28, 21), _p(23, 5),
    ], robot_x=0.5),
    _env(3, {6: 0.0, 9: 2.05, 10: -1.8}, [
        _p(24, 6, dx=-0.9), _p(31, 24), _p(37, 6, dx=-0.55), _p(35, 6, dx=-0.2), _p(15, 6, dx=0.2),
        _p(41, 6, dx=0.85), _p(19, 41, dx=-0.1), _p(32, 19), _p(34, 41, dx=0.1),
        _p(20, 6, dx=-0.6, back=True), _p(27, 20), _p(14, 9, 1, -0.25), _p(23, 9, 0, 0.25), _p(30, 23),
        _p(16, 9, 0, -0.2), _p(33, 16),
    ]),
    _env(4, {4: 0.0, 2: 2.0, 8: -1.2, 12: 3.3}, [
        _p(21, 4, dx=0.0), _p(28, 21), _p(16, 4, dx=0.3), _p(40, 4, dx=-0.3), _p(43, 40, dx=-0.05),
        _p(36, 40, dx=0.06), _p(39, 4, dx=0.2, back=True),
        _p(34, 2, dx=-0.5), _p(18, 2, dx=0.0), _p(31, 18), _p(13, 2, dx=-0.25), _p(32, 13),
        _p(17, 8, 2, 0.0), _p(20, 8, 1, -0.3), _p(27, 20),
    ], robot_x=1.0),
    _env(5, {3: 0.0, 6: 2.6, 11: -1.55, 10: 4.3}, [
        _p(20, 6, dx=-0.7), _p(27, 20), _p(23, 6, dx=0.6), _p(30, 23), _p(35, 6, dx=0.0),
        _p(15, 3, dx=-0.7), _p(14, 3, dx=-0.25), _p(31, 14), _p(37, 3, dx=0.0), _p(17, 3, dx=0.3),
        _p(41, 3, dx=0.75), _p(13, 41, dx=-0.1), _p(32, 13), _p(43, 41, dx=0.1), _p(38, 3, dx=0.0, back=True),
    ], robot_x=1.0),
    _env(6, {2: 0.0, 7: 1.35, 9: -2.1, 12: 3.0}, [
        _p(26, 2, dx=0.2), _p(33, 26), _p(25, 2, dx=-0.5), _p(32, 25), _p(34, 2, dx=-0.1),
        _p(40, 2, dx=0.5), _p(23, 40, dx=-0.05), _p(43, 40, dx=0.06), _p(42, 2, dx=0.25, back=True),
        _p(14, 7, 2, -0.2), _p(36, 7, 0, 0.2), _p(39, 7, 1, 0.15), _p(17, 7, 1, -0.2), _p(31, 17),
        _p(19, 9, 1, 0.2), _p(21, 9, 0, -0.2), _p(28, 21),
    ]),
    _env(7, {6: 0.0, 5: 1.75, 8: -2.4, 10: 3.2}, [
        _p(22, 6, dx=0.5), _p(29, 22), _p(13, 6, dx=-0.9), _p(37, 6, dx=-0.2), _p(16, 6, dx=0.15),
        _p(15, 6, dx=-0.55), _p(27, 15), _p(41, 6, dx=0.95), _p(43, 41, dx=-0.1), _p(35, 41, dx=0.1),
        _p(21, 8, 1, 0.3), _p(28, 21), _p(19, 8, 0, -0.3), _p(17, 8, 2, 0.0), _p(31, 17),
    ]),
    _env(8, {3: 0.0, 4: 2.2, 7: -1.6, 11: 3.4}, [
        _p(24, 3, dx=-0.3), _p(31, 24), _p(14, 3, dx=0.75), _p(30, 14), _p(36, 3, dx=0.35),
        _p(41, 3, dx=-0.75), _p(39, 41, dx=-0.1), _p(15, 41, dx=0.12), _p(17, 4, dx=0.2),
        _p(34, 4, dx=-0.25), _p(43, 4, dx=0.0, back=True), _p(23, 7, 2, 0.1), _p(26, 7, 1, -0.2), _p(33, 26),
    ], robot_x=0.5),
    _env(9, {2: 0.0, 6: 2.2, 9: -2.0, 10: 4.2, 12: -3.2}, [
        _p(15, 2, dx=-0.6), _p(39, 2, dx=0.15), _p(40, 2, dx=0.55), _p(35, 40, dx=-0.06), _p(37, 40, dx=0.06),
        _p(14, 2, dx=-0.25), _p(28, 14), _p(25, 6, dx=0.4), _p(32, 25), _p(13, 6, dx=-0.5), _p(24, 6, dx=-0.1),
        _p(31, 24), _p(20, 9, 1, -0.2), _p(27, 20), _p(16, 9, 0, 0.25),
    ], robot_x=1.0),
    _env(10, {4: 0.2, 3: 2.0, 8: 4.2, 11: -1.3}, [
        _p(14, 4, dx=0.3), _p(36, 4, dx=-0.3), _p(43, 4, dx=0.0), _p(21, 3, dx=-0.3), _p(28, 21),
        _p(19, 3, dx=0.5), _p(31, 19), _p(34, 3, dx=0.1), _p(41, 3, dx=-0.75),
        _p(17, 41, dx=-0.12), _p(16, 41, dx=0.1), _p(26, 8, 1, -0.3), _p(33, 26), _p(42, 8, 0, 0.3),
        _p(13, 8, 2, 0.25), _p(29, 13),
    ], robot_x=1.5),
    _env(11, {6: 0.0, 7: 2.4, 5: -1.75, 12: -3.0, 11: 3.6}, [
        _p(23, 6, dx=-0.45), _p(30, 23), _p(15, 6, dx=0.85), _p(18, 6, dx=0.4), _p(37, 6, dx=-0.1),
        _p(41, 6, dx=-0.9), _p(40, 41, dx=-0.1), _p(34, 41, dx=0.12), _p(14, 6, dx=0.0, back=True), _p(32, 14),
        _p(22, 7, 0, 0.1), _p(29, 22), _p(13, 7, 1, -0.2), _p(35, 7, 0, -0.25),
    ]),
    _env(12, {2: 0.0, 4: -2.0, 9: 1.4, 10: 3.3}, [
        _p(24, 2, dx=-0.55), _p(31, 24), _p(16, 2, dx=-0.15), _p(33, 16), _p(36, 2, dx=0.15), _p(39, 2, dx=0.55),
        _p(34, 39, dx=-0.04), _p(43, 39, dx=0.045), _p(17, 2, dx=0.2, back=True), _p(25, 4, dx=0.3), _p(32, 25),
        _p(23, 4, dx=0.0, back=True), _p(15, 4, dx=-0.3), _p(14, 9, 1, 0.0), _p(38, 9, 0, 0.0),
        _p(13, 9, 2, 0.2), _p(28, 13),
    ]),
    _env(13, {3: 0.0, 8: 2.3, 6: -2.6, 12: 3.5, 10: -4.3}, [
        _p(21, 6, dx=0.5), _p(28, 21), _p(36, 6, dx=-0.3), _p(43, 3, dx=0.5, back=True), _p(19, 6, dx=-0.8),
        _p(30, 19), _p(20, 3, dx=-0.3), _p(27, 20), _p(17, 3, dx=0.55), _p(35, 3, dx=0.1), _p(40, 3, dx=-0.75),
        _p(42, 40, dx=-0.05), _p(38, 40, dx=0.06), _p(15, 3, dx=0.2, back=True), _p(13, 8, 1, 0.3), _p(31, 13),
        _p(34, 8, 0, -0.3), _p(24, 8, 0, 0.2), _p(32, 24),
    ]),
)
ENVIRONMENTS_BY_ID = {e.id: e for e in ENVIRONMENTS}


def build_environment(env: EnvironmentSpec, rng: np.random.Generator | None = None,
                      objects: Mapping[str, ObjectSpec] = OBJECTS_BY_ID) -> WorldState:
    """The initial state of `env`; `rng` jitters item positions by up to a centimetre.

    `objects` are the objects it may place by id: the catalog's, or a user's layout's (`serve.layout`).
    """
    floor = OBJECTS_BY_ID["obj01"]
    specs = {floor.id: floor}
    poses = {floor.id: (0.0, 0.0, -floor.h)}  # the floor's top face is at z = 0
    support: dict[str, tuple[str, str]] = {}
    for obj, x in env.furniture:
        spec = objects[obj]
        specs[obj] = spec
        poses[obj] = (x, spec.l / 2, 0.0)
        support[obj] = (floor.id, ON)
    for pl in env.items:
        spec = objects[pl.obj]
        if pl.obj in specs:
            raise ValueError(f"{env.id}: {pl.obj} placed twice")
        if pl.on not in specs:
            raise ValueError(f"{env.id}: {pl.obj} placed on {pl.on}, which is not placed before it")
        jitter = float(rng.uniform(-0.01, 0.01)) if rng is not None and on_furniture(specs[pl.on]) else 0.0
        pose, relation = item_pose(poses[pl.on], specs[pl.on], spec, pl, jitter)
        specs[pl.obj] = spec
        poses[pl.obj] = pose
        support[pl.obj] = (pl.on, relation)
    state = WorldState(specs=specs, poses=poses, support=support, robot=(env.robot_x, ROBOT_START_Y))
    _check_layout(env.id, state)
    return state


def on_furniture(spec: ObjectSpec) -> bool:
    """Items on tables and shelves stand in rows at a level; anything else holds its load centred on itself."""
    return spec.category in ("table", "shelf")


def item_pose(base: tuple[float, float, float], bspec: ObjectSpec, spec: ObjectSpec, pl: Placement,
              jitter: float = 0.0) -> tuple[tuple[float, float, float], str]:
    """Where the placed item `spec` stands on or in `bspec` (whose pose is `base`), and how it is held there."""
    if on_furniture(bspec):
        y = base[1] - bspec.l / 2 + FRONT_GAP + spec.l / 2 + (0.3 if pl.back else 0.0)
        pose, relation = (base[0] + pl.dx + jitter, y, base[2] + bspec.surface_heights()[pl.level]), ON
    elif bspec.has("container") and not bspec.has("large_surface"):
        pose, relation = (base[0], base[1], base[2] + 0.005), INSIDE
    else:
        pose, relation = (base[0] + pl.dx, base[1], base[2] + bspec.h), ON
    return tuple(round(v, 6) for v in pose), relation


def _check_layout(env_id: str, state: WorldState) -> None:
    """Items side by side on one surface must not overlap; a catalog typo shows here."""
    ids = sorted(state.specs)
    for i, a in enumerate(ids):
        for b in ids[i + 1 :]:
            sa, sb = state.support.get(a), state.support.get(b)
            side_by_side = sa and sb and sa[0] == sb[0] and sa[1] == ON
            if side_by_side and abs(state.poses[a][2] - state.poses[b][2]) < 1e-6 and state.overlap_top(a, b):
                where = "the floor" if state.specs[sa[0]].category == "floor" else sa[0]
                raise ValueError(f"{env_id}: {a} and {b} overlap on {where}")
