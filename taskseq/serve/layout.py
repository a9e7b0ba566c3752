"""Environment files from a short layout: new objects by size and attributes, where furniture and items stand.

The benchmark's environments are built from its catalog; a layout lists its
own objects (any id, name, size, flags and shelf levels, in the simulator's
categories), may reuse catalog objects by id (`obj10` is the trash can), and
places them as the catalog does: furniture along the wall at an x, items on
furniture (level, sideways offset, back row), on other items, or inside
containers, each item `at` what holds it. The result is the environment file `taskseq plan --env` and
`taskseq serve` read: every object with its 14 attributes, and the state.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import yaml

from ..demonstrations.records import spec_to_dict, state_to_dict
from ..sim.catalog import OBJECTS_BY_ID, EnvironmentSpec, Placement, build_environment, on_furniture
from ..sim.objects import BINARY_ATTRIBUTES, CATEGORIES, FURNITURE, ObjectSpec
from .environments import SAFE_NAME

OBJECT_FIELDS = {"id": True, "name": True, "category": True, "size": True, "flags": False, "levels": False}
ITEM_FIELDS = {"id": True, "at": True, "level": False, "dx": False, "back": False}  # YAML reads `on` as true


def _fields(where: str, entry: Any, allowed: dict[str, bool]) -> dict[str, Any]:
    if not isinstance(entry, dict):
        raise ValueError(f"{where}: expected a mapping with {', '.join(allowed)}")
    missing = [k for k, required in allowed.items() if required and k not in entry]
    unknown = sorted(set(entry) - set(allowed))
    if missing:
        raise ValueError(f"{where}: missing field {missing[0]!r}")
    if unknown:
        raise ValueError(f"{where}: unknown field {unknown[0]!r} (known: {', '.join(allowed)})")
    return entry


def _number(at: str, value: Any, what: str = "a number") -> float:
    """A finite number of the layout. Text that reads as one is taken: YAML 1.1, which PyYAML reads, takes `-6e-1`
    for text (its exponent form needs a dot). Bools are not numbers here, though Python counts them as such."""
    if isinstance(value, str):
        try:
            number = float(value)
        except ValueError:
            number = math.nan
        if math.isfinite(number):
            return number
    elif not isinstance(value, bool) and isinstance(value, (int, float)) and math.isfinite(value):
        return float(value)
    raise ValueError(f"{at}: expected {what}, got {value!r}")


def _numbers(at: str, value: Any, what: str, count: int | None = None) -> tuple[float, ...]:
    if not isinstance(value, list) or (count is not None and len(value) != count):
        raise ValueError(f"{at}: expected {what}, got {value!r}")
    return tuple(_number(at, v, what) for v in value)


def _whole(at: str, value: Any) -> int:
    if isinstance(value, bool) or not isinstance(value, int):
        raise ValueError(f"{at}: expected a whole number, got {value!r}")
    return value


def environment_from_layout(layout: Any, where: str = "layout") -> dict[str, Any]:
    """The environment file's content; every error names the field of the layout that is wrong."""
    layout = _fields(where, layout, {"objects": False, "furniture": True, "items": False, "robot_x": False})
    objects = dict(OBJECTS_BY_ID)
    for i, entry in enumerate(layout.get("objects") or []):
        at = f"{where}: objects[{i}]"
        entry = _fields(at, entry, OBJECT_FIELDS)
        oid = str(entry["id"])
        if not SAFE_NAME.match(oid):
            raise ValueError(f"{at}.id: {oid!r}: use letters, digits, _ and - only")
        if oid in objects and oid not in OBJECTS_BY_ID:
            raise ValueError(f"{at}.id: {oid} is listed twice")
        name = str(entry["name"])
        if not name.strip() or name != name.strip() or set(name) & set("(),"):
            raise ValueError(f"{at}.name: {name!r}: a task names an object by its name (`pour(green_tea)`), so a "
                             "name has no '(', ')' or ',' and no space at either end")
        if str(entry["category"]) not in CATEGORIES:
            raise ValueError(f"{at}.category: unknown category {entry['category']!r}; one of "
                             f"{', '.join(sorted(CATEGORIES))}")
        unknown = sorted(set(map(str, entry.get("flags") or ())) - set(BINARY_ATTRIBUTES))
        if unknown:
            raise ValueError(f"{at}.flags: unknown flag {unknown[0]!r}; any of {', '.join(BINARY_ATTRIBUTES)}")
        size = _numbers(f"{at}.size", entry["size"], "[width, length, height] in metres", 3)
        levels = _numbers(f"{at}.levels", entry.get("levels") or [], "a list of shelf heights in metres")
        try:
            objects[oid] = ObjectSpec(oid, name, str(entry["category"]), size, frozenset(entry.get("flags") or ()),
                                      levels)
        except (TypeError, ValueError) as err:
            raise ValueError(f"{at}: {err}") from None
    furniture = layout["furniture"]
    if not isinstance(furniture, dict) or not furniture:
        raise ValueError(f"{where}: furniture: expected a mapping of object id to x (m)")
    items = []
    for i, entry in enumerate(layout.get("items") or []):
        at = f"{where}: items[{i}]"
        entry = _fields(at, entry, ITEM_FIELDS)
        back = entry.get("back", False)
        if not isinstance(back, bool):
            raise ValueError(f"{at}.back: expected true or false, got {back!r}")
        items.append(Placement(str(entry["id"]), str(entry["at"]), _whole(f"{at}.level", entry.get("level", 0)),
                               _number(f"{at}.dx", entry.get("dx", 0.0), "an offset in metres"), back))
    for oid in [*furniture, *(p.obj for p in items)]:
        if oid not in objects:
            raise ValueError(f"{where}: {oid!r} is placed but is neither listed in objects nor a catalog object")
    placed_ids = {*map(str, furniture), *(p.obj for p in items)}
    for i, entry in enumerate(layout.get("objects") or []):
        if str(entry["id"]) not in placed_ids:
            raise ValueError(f"{where}: objects[{i}]: {entry['id']} is listed but placed nowhere; give it an x under "
                             "furniture, or an entry under items")
    for i, placed in enumerate(items):
        at = f"{where}: items[{i}]"
        if placed.on not in objects:
            raise ValueError(f"{at}.at: {placed.on!r} is neither listed in objects nor a catalog object")
        if placed.on not in placed_ids:
            raise ValueError(f"{at}.at: {placed.on} is placed nowhere itself; give it an x under furniture, or an "
                             "entry under items before this one")
        spec, base = objects[placed.obj], objects[placed.on]
        if spec.has("liquid") and not (base.has("container") and base.category not in FURNITURE):
            raise ValueError(f"{at}.at: {placed.obj} is a liquid; it goes in a container (a bottle, a cup, a pot), "
                             f"not on {base.name}")
        _check_placement(at, placed, spec, base)
    spec = EnvironmentSpec(where, tuple((str(k), _number(f"{where}: furniture.{k}", x, "an x in metres"))
                                        for k, x in furniture.items()), tuple(items),
                           _number(f"{where}: robot_x", layout.get("robot_x", 0.0), "an x in metres"))
    try:
        state = build_environment(spec, objects=objects)
    except (IndexError, KeyError) as err:
        raise ValueError(f"{where}: items: a level or object that does not exist ({err})") from None
    return {"objects": [spec_to_dict(state.specs[o]) for o in state.specs], "state": state_to_dict(state)}


def _check_placement(at: str, placed: Placement, spec: ObjectSpec, base: ObjectSpec) -> None:
    """A level the object under it has, and an offset that keeps the item over it (`item_pose` takes any)."""
    levels = len(base.surface_heights())
    if not 0 <= placed.level < levels:
        raise ValueError(f"{at}.level: {placed.level}: {base.id} ({base.name}) has "
                         + (f"levels 0 to {levels - 1}" if levels > 1 else "one level, 0"))
    inside = not on_furniture(base) and base.has("container") and not base.has("large_surface")
    room = (base.w - spec.w) / 2
    if not inside and room < -1e-9:
        raise ValueError(f"{at}: {placed.obj} ({spec.w:g} m wide) is wider than {base.id} ({base.name}, "
                         f"{base.w:g} m) and cannot stand on it")
    if not inside and abs(placed.dx) > room + 1e-9:
        raise ValueError(f"{at}.dx: {placed.dx:g} m puts {placed.obj} off {base.id} ({base.name}): at most "
                         f"{room:.3f} m either way")


def write_environment(layout_path: Path, output: Path) -> int:
    """Read a YAML (or JSON) layout, write the environment file; returns its number of objects."""
    from ..runtime.atomic import write_text_atomic

    try:
        layout = yaml.safe_load(Path(layout_path).read_text(encoding="utf-8"))
    except yaml.YAMLError as err:
        mark = getattr(err, "problem_mark", None)  # where the parser stopped, when it knows
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark is not None else ""
        raise ValueError(f"{layout_path}: not valid YAML{where}: {getattr(err, 'problem', None) or err}") from None
    env = environment_from_layout(layout, str(layout_path))
    write_text_atomic(output, json.dumps(env, indent=1) + "\n")
    return len(env["objects"])
