"""Readers of the release's XML files: `Objects.xml`, the environments, `data.xml`, `ControllerInstructions.xml`.

Every reader validates as it reads: a malformed file (bad XML, a missing element, an unknown environment id, a
non-numeric position) raises `VeilFormatError` naming the file, the line and the element, so that an import can
check the whole release before writing anything.

Environment ids (checked on the release's 360 training points, docs/veil.md): `kitchen_scenario_environment_number_N`
is `Environments/kitchen/kitchenN.xml` and `living_room_scenario_environment_numberN` is
`Environments/livingRoom/livingRoom(10-N).xml`, as the release's PROVENANCE.md states. Under this mapping every
object named by a sequence (8,066 names) is an object of its environment when names are compared without case
(as the fixture's `Bench_1` in a sequence, `bench_1` in the file); under `livingRoomN.xml` many are not.
"""

from __future__ import annotations

import re
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

from .pddl import Domain, read_domain
from .xmltree import Node, VeilFormatError, child_text, read_xml

ROOMS = ("kitchen", "livingRoom")
_KITCHEN_ID = re.compile(r"kitchen_scenario_environment_number_(\d+)")
_LIVING_ID = re.compile(r"living_room_scenario_environment_number(\d+)")
_INSTANCE = re.compile(r"_\d+$")  # `Beaker_1` is instance 1 of `Beaker`
_TRAILING = re.compile(r"[_\d]+$")  # `Crate2_1` is a `Crate`


def environment_file(env_id: str) -> tuple[str, int] | None:
    """(room, file number) of an environment id, or None when the id has neither form (module docstring)."""
    if m := _KITCHEN_ID.fullmatch(env_id):
        return "kitchen", int(m[1])
    if m := _LIVING_ID.fullmatch(env_id):
        return "livingRoom", 10 - int(m[1])
    return None


def environment_id(room: str, number: int) -> str:
    """The inverse of `environment_file`: the id `data.xml` gives the environment file `room`/`number`."""
    if room == "kitchen":
        return f"kitchen_scenario_environment_number_{number}"
    return f"living_room_scenario_environment_number{10 - number}"


class NameIndex:
    """Object names of one environment, looked up without case, and failing that without case and underscores.

    Sequences name objects as their environment does but for case (`Bench_1`, `bench_1`); the domain's
    object-specific actions and constants drop an underscore too (`keep_On_HotPlate1`, `(On ?x HotPlate1)` for
    the object `HotPlate_1`). The looser key is used only when it names one object of the environment.
    """

    def __init__(self, names: Iterable[str]) -> None:
        self.names = tuple(names)
        self.exact = {n.lower(): n for n in self.names}
        loose: dict[str, list[str]] = {}
        for n in self.names:
            loose.setdefault(loose_key(n), []).append(n)
        self.loose = {k: v[0] for k, v in loose.items() if len(v) == 1}

    def strict(self, name: str) -> str | None:
        """The environment's spelling of `name` compared without case (how sequences name objects)."""
        return self.exact.get(name.lower())

    def resolve(self, name: str) -> str | None:
        """As `strict`, else compared also without underscores when that names one object (the domain's names)."""
        return self.exact.get(name.lower()) or self.loose.get(loose_key(name))


def loose_key(name: str) -> str:
    return name.lower().replace("_", "")


# Objects.xml ----------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Category:
    """An object category of `Objects.xml`, merged over every <object> naming it (the release declares
    several categories more than once, as the fixture does `Teapot`): default state values (None when the file
    gives no default) and affordances."""

    name: str
    defaults: tuple[tuple[str, str | None], ...]
    affordances: frozenset[str]
    line: int


@dataclass(frozen=True)
class Catalog:
    """The categories of `Objects.xml` by lower-cased name, and the file-level state declarations (name -> type)."""

    categories: dict[str, Category]
    declared_types: dict[str, str]
    path: str

    def category_of(self, name: str) -> tuple[str, Category | None]:
        """An object's category from its name: the whole name, else the name without its instance suffix `_N`,
        else without any trailing digits and underscores, matched without case (`Beaker_1` -> `Beaker`,
        `A_1B_1` -> `A_1B`, `HotPlateKnob_1` -> `HotPlateKnob_1` when that is a category, `Crate2_1` -> `Crate`). A name
        with no category in the file (the release's buttons and a few others) gets its base name (`Crate_1` -> `Crate`)
        as category and None: no affordances and no default states."""
        candidates = [name, _INSTANCE.sub("", name), _TRAILING.sub("", name)]
        for c in candidates:
            found = self.categories.get(c.lower())
            if found is not None:
                return found.name, found
        base = _INSTANCE.sub("", name)
        return base or name, None


def _states(path: Path, parent: Node) -> list[tuple[str, str | None]]:
    """(state, default) pairs under `parent`: from <state><stateName/><default/></state>, or a <stateName> held
    directly by a <property> (the release has one)."""
    out = []
    for st in parent.iter("state"):
        name, _ = child_text(path, st, "stateName")
        if not name:
            raise VeilFormatError(path, st.line, "<state>", "empty <stateName>")
        d = st.first("default")
        out.append((name, d.text if d is not None else None))
    for prop in parent.iter("property"):
        for sn in prop.all("stateName"):
            out.append((sn.text, None))
    return out


def read_objects(path: Path | str) -> Catalog:
    """Read `Objects.xml`. Its structure is irregular and read as it is: an <object> has one or more <name>s;
    its <affordances> sit inside <attributes> or beside it; its <state>s sit inside <attributes><property> or
    directly under <object>; a <property> may hold a <stateName> directly."""
    path = Path(path)
    root = read_xml(path)
    if root.tag != "objects":
        raise VeilFormatError(path, root.line, f"<{root.tag}>", "expected the root element <objects>")
    declared: dict[str, str] = {}
    merged: dict[str, tuple[str, dict[str, str | None], set[str], int]] = {}
    for child in root.children:
        if child.tag == "attributes":  # file-level declarations of state names with their types
            for st in child.iter("state"):
                name, _ = child_text(path, st, "stateName")
                t = st.first("type")
                declared[name] = t.text if t is not None else ""
            continue
        if child.tag != "object":
            continue
        names = [n for n in child.all("name")]
        if not names or any(not n.text for n in names):
            raise VeilFormatError(path, child.line, "<object>", "has no <name> (or an empty one)")
        states = _states(path, child)
        affordances = {a.text for a in child.iter("affordance") if a.text}
        for n in names:
            key = n.text.lower()
            if key not in merged:
                merged[key] = (n.text, {}, set(), n.line)
            _, defaults, affs, _ = merged[key]
            for s, d in states:
                if d is not None or s not in defaults:
                    defaults[s] = d
            affs |= affordances
    cats = {k: Category(name, tuple(sorted(defaults.items())), frozenset(affs), line)
            for k, (name, defaults, affs, line) in merged.items()}
    return Catalog(dict(sorted(cats.items())), declared, str(path))


# environments ---------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class EnvObject:
    """An object placed in an environment file: position and rotation (Unity units, y up) and its listed states
    (values as written: `True`, `False`, `1`, `2`, `Low`, ...)."""

    name: str
    position: tuple[float, float, float]
    rotation: tuple[float, float, float]
    states: tuple[tuple[str, str], ...]
    line: int


@dataclass(frozen=True)
class Environment:
    env_id: str
    room: str
    number: int
    path: str
    objects: tuple[EnvObject, ...]

    @property
    def names(self) -> NameIndex:
        return NameIndex(o.name for o in self.objects)


def _triple(path: Path, node: Node, tag: str) -> tuple[float, float, float]:
    """Three numbers written `(x, y, z)`, `x,y,z` or `x,y,z,` (all three occur in the release)."""
    text, line = child_text(path, node, tag)
    parts = text.strip().strip("()").split(",")
    if len(parts) == 4 and not parts[3].strip():  # the release writes `0,0,0,` for some rotations
        parts = parts[:3]
    try:
        values = tuple(float(p) for p in parts)
    except ValueError:
        values = ()
    if len(values) != 3:
        raise VeilFormatError(path, line, f"<{tag}>", f"expected three numbers such as (1, 2.5, -3), not {text!r}")
    return values  # type: ignore[return-value]


def read_environment(path: Path | str, room: str, number: int) -> Environment:
    """Read one environment file; two objects whose names differ only by case are an error (sequences name
    objects without case)."""
    path = Path(path)
    root = read_xml(path)
    if root.tag != "environment":
        raise VeilFormatError(path, root.line, f"<{root.tag}>", "expected the root element <environment>")
    objects = []
    seen: dict[str, int] = {}
    for node in root.all("object"):
        name, line = child_text(path, node, "name")
        if not name:
            raise VeilFormatError(path, line, "<name>", "empty object name")
        if name.lower() in seen:
            raise VeilFormatError(path, line, "<name>", f"object {name!r} already named at line {seen[name.lower()]}")
        seen[name.lower()] = line
        states = []
        for st in node.all("state"):
            sname, _ = child_text(path, st, "statename")
            value, _ = child_text(path, st, "statevalue")
            states.append((sname, value))
        objects.append(EnvObject(name, _triple(path, node, "position"), _triple(path, node, "rotation"),
                                 tuple(states), node.line))
    if not objects:
        raise VeilFormatError(path, root.line, "<environment>", "holds no <object>")
    return Environment(environment_id(room, number), room, number, str(path), tuple(objects))


def read_environments(root: Path | str) -> dict[str, Environment]:
    """Every `Environments/<room>/<room>N.xml` under the release folder, by environment id, in id order."""
    root = Path(root)
    envs: dict[str, Environment] = {}
    for room in ROOMS:
        for f in sorted((root / "Environments" / room).glob(f"{room}*.xml")):
            m = re.fullmatch(rf"{room}(\d+)\.xml", f.name)
            if m is None:
                continue
            env = read_environment(f, room, int(m[1]))
            envs[env.env_id] = env
    return dict(sorted(envs.items()))


# data.xml -------------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class RawAction:
    """One <action> of a sequence: its text, the text segment it is aligned to (count of <change_of_alignment/>
    before it) and its line."""

    text: str
    segment: int
    line: int


@dataclass(frozen=True)
class Point:
    """One <point> of `data.xml`: id (`p001`, its order in the file), text, environment id, objective."""

    seq_id: str
    text: str
    env_id: str
    objective: str
    actions: tuple[RawAction, ...]
    n_segments: int
    line: int


def read_points(path: Path | str) -> list[Point]:
    path = Path(path)
    root = read_xml(path)
    points = []
    nodes = root.all("point")
    if not nodes:
        raise VeilFormatError(path, root.line, f"<{root.tag}>", "holds no <point>")
    width = max(3, len(str(len(nodes))))
    for i, node in enumerate(nodes, start=1):
        text, _ = child_text(path, node, "text")
        env_id, env_line = child_text(path, node, "environment")
        if environment_file(env_id) is None:
            raise VeilFormatError(path, env_line, "<environment>", f"unknown environment id {env_id!r}")
        objective, _ = child_text(path, node, "objective")
        seq = node.first("action_sequence")
        if seq is None:
            raise VeilFormatError(path, node.line, "<point>", "has no <action_sequence>")
        segment = 0
        actions = []
        for a in seq.children:
            if a.tag == "change_of_alignment":
                segment += 1
            elif a.tag == "action":
                if not a.text:
                    raise VeilFormatError(path, a.line, "<action>", "empty action")
                actions.append(RawAction(" ".join(a.text.split()), segment, a.line))
            else:
                raise VeilFormatError(path, a.line, f"<{a.tag}>", "expected <action> or <change_of_alignment/>")
        points.append(Point(f"p{i:0{width}d}", " ".join(text.split()), env_id, objective.strip(), tuple(actions),
                            segment + 1, node.line))
    return points


# ControllerInstructions.xml -------------------------------------------------------------------------------------
def read_instructions(path: Path | str) -> dict[str, tuple[tuple[str, ...], ...]]:
    """Instruction name -> its parameter-type lists (`wait` and `pour` are overloaded), lower-cased."""
    path = Path(path)
    root = read_xml(path)
    out: dict[str, list[tuple[str, ...]]] = {}
    for ins in root.all("Instruction"):
        name, _ = child_text(path, ins, "Name")
        out.setdefault(name.lower(), []).append(tuple(p.text.lower() for p in ins.all("Parameter")))
    if not out:
        raise VeilFormatError(path, root.line, f"<{root.tag}>", "holds no <Instruction>")
    return {k: tuple(v) for k, v in sorted(out.items())}


# the whole release ----------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Release:
    root: str
    catalog: Catalog
    domain: Domain
    instructions: dict[str, tuple[tuple[str, ...], ...]]
    environments: dict[str, Environment]
    points: tuple[Point, ...]


def read_release(root: Path | str) -> Release:
    """Read and check every file of a release folder; every point's environment must exist."""
    root = Path(root)
    if not root.is_dir():
        raise VeilFormatError(root, 0, "(folder)", "is not a folder")
    catalog = read_objects(root / "Objects.xml")
    domain = read_domain(root / "domainKnowledge.pddl")
    instructions = read_instructions(root / "ControllerInstructions.xml")
    envs = read_environments(root)
    points = read_points(root / "data.xml")
    for p in points:
        if p.env_id not in envs:
            room, number = environment_file(p.env_id)  # type: ignore[misc]
            raise VeilFormatError(root / "data.xml", p.line, "<environment>",
                                  f"environment {p.env_id!r} has no file Environments/{room}/{room}{number}.xml")
    return Release(str(root), catalog, domain, instructions, envs, tuple(points))
