"""PDDL problems from simulator states, and their ground actions.

A problem lists the objects that matter to the goal (see `relevant_objects`),
their attribute predicates, geometric facts computed from the scene, the state
fluents and the goal. `ground_actions` instantiates the domain in
`domain.pddl` over those objects, evaluating every static condition, so what
the SAT encoder sees is plain STRIPS with negative preconditions.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from ...sim.primitives import Action, has_room, receives_inside
from ...sim.state import WorldState
from ...sim.tasks import Task

DOMAIN_PATH = Path(__file__).with_name("domain.pddl")
Atom = tuple[str, ...]

ATTRIBUTE_PREDICATES = {
    "movable": "movable", "container": "container", "liquid": "liquid", "large-surface": "large_surface",
    "multi-surface": "multi_surface", "cylinder": "cylinder", "box-shape": "box", "handle": "handle",
}


@dataclass(frozen=True)
class GroundAction:
    name: str
    args: tuple[str, ...]
    pre: frozenset[Atom]
    pre_not: frozenset[Atom]
    add: frozenset[Atom]
    delete: frozenset[Atom]

    def primitive(self) -> Action:
        """The simulator's primitive this action is."""
        if self.name == "drop":
            return Action("release", self.args[:1])
        if self.name == "follow_traj_circle":
            return Action("follow_traj_circle", self.args[:1])
        if self.name == "follow_traj_pour":
            return Action("follow_traj_pour", self.args[:2])
        return Action(self.name, self.args)

    def pddl(self) -> str:
        return f"({' '.join((self.name, *self.args))})"


@dataclass
class Problem:
    name: str
    objects: list[str]
    statics: set[Atom] = field(default_factory=set)
    init: set[Atom] = field(default_factory=set)
    goal: set[Atom] = field(default_factory=set)

    def to_pddl(self) -> str:
        facts = sorted(self.statics | self.init)
        lines = [f"(define (problem {self.name})", "  (:domain kitchen)",
                 f"  (:objects {' '.join(self.objects)} - obj)", "  (:init"]
        lines += [f"    ({' '.join(f)})" for f in facts]
        lines += ["  )", "  (:goal (and"]
        lines += [f"    ({' '.join(g)})" for g in sorted(self.goal)]
        lines += ["  ))", ")"]
        return "\n".join(lines) + "\n"


def relevant_objects(state: WorldState, task: Task, goal_objects: list[str]) -> list[str]:
    """The task's and goal's objects, what holds or contains them, what rests on them, and all furniture.

    Leaving out the rest keeps the SAT encoding small; objects left out can
    neither block the goal nor be needed for it.
    """
    keep: set[str] = {o for o, s in state.specs.items() if s.category in ("floor", "table", "shelf")}
    frontier = [*task.args, *goal_objects]
    if state.held:
        frontier.append(state.held)
    while frontier:
        o = frontier.pop()
        if o in keep:
            continue
        keep.add(o)
        frontier += state.children(o)  # loads and contents
        container = state.container_of(o)
        if container:
            frontier.append(container)
    return sorted(keep)


def goal_atoms(state: WorldState, task: Task, goal_objects: dict[str, str]) -> set[Atom]:
    """The goal of `task`; `goal_objects` names the role objects (stirrer, vessel, bin)."""
    a = task.args[0]
    if task.name == "stir":
        return {("stirred", a, goal_objects["stirrer"])}
    if task.name in ("pour", "pour_to"):
        target = task.args[1] if task.name == "pour_to" else goal_objects["vessel"]
        return {("in", a, target)}
    if task.name == "throw_away":
        return {("in", a, goal_objects["bin"]), ("hand-empty",)}
    b = task.args[1]
    return {("in" if receives_inside(state, b) else "on", a, b), ("hand-empty",)}


def build_problem(name: str, state: WorldState, task: Task, goal_objects: dict[str, str]) -> Problem:
    objs = relevant_objects(state, task, list(goal_objects.values()))
    specs = state.specs
    statics: set[Atom] = set()
    for o in objs:
        for pred, flag in ATTRIBUTE_PREDICATES.items():
            if specs[o].has(flag):
                statics.add((pred, o))
        if receives_inside(state, o):
            statics.add(("receives-inside", o))
    for p in objs:
        if p == state.held:
            continue
        parked = state.copy()
        parked.robot = state.approach_point(p)
        statics |= {("reach-after", p, o) for o in objs if o != state.held and parked.reachable(o)}
    for a in objs:
        if not specs[a].has("movable"):
            continue
        for b in objs:
            surface = specs[b].has("large_surface") or specs[b].has("container")
            if b != a and surface and has_room(state, a, b):
                statics.add(("room-on", a, b))
            if b != a and specs[b].has("container") and max(specs[a].w, specs[a].l) >= specs[b].h:
                statics.add(("long-enough", a, b))
    init: set[Atom] = set()
    for o in objs:
        if o != state.held and state.reachable(o):
            init.add(("near", o))
        parent = state.support.get(o)
        if parent and parent[0] in objs:
            init.add(("in" if parent[1] == "inside" else "on", o, parent[0]))
    if state.held is None:
        init.add(("hand-empty",))
    else:
        init.add(("holding", state.held))
        if state.held in state.support:
            init.add(("anchored",))
        if state.held_above in objs:
            init.add(("above", state.held, state.held_above))
    stirrers = [o for o in objs if specs[o].has("movable")]
    init |= {("stirred", liquid, s) for liquid in state.stirred if liquid in objs for s in stirrers}
    return Problem(name, objs, statics, init, goal_atoms(state, task, goal_objects))


def ground_actions(problem: Problem) -> list[GroundAction]:
    """Every action of the domain over the problem's objects whose static preconditions hold."""
    objs, st = problem.objects, problem.statics

    def has(*atom: str) -> bool:
        return tuple(atom) in st

    def rest(a: str, b: str) -> Atom:
        return ("in" if has("receives-inside", b) else "on", a, b)

    out: list[GroundAction] = []
    F = frozenset
    for p in objs:
        reached = [o for o in objs if has("reach-after", p, o)]
        out.append(GroundAction("move_close", (p,), F(), F({("holding", p), ("anchored",)}),
                                F(("near", o) for o in reached),
                                F(("near", o) for o in objs if o not in reached)))
    movable = [o for o in objs if has("movable", o)]
    for o in movable:
        out.append(GroundAction("grasp", (o,), F({("hand-empty",), ("near", o)}), F(("on", y, o) for y in objs),
                                F({("holding", o)}),
                                F({("hand-empty",)} | {(r, o, x) for x in objs for r in ("on", "in")})))
        out.append(GroundAction("release", (o,), F({("holding", o), ("anchored",)}), F(),
                                F({("hand-empty",), ("near", o)}), F({("holding", o), ("anchored",)})))
        for b in objs:
            if b == o:
                continue
            if has("room-on", o, b):
                out.append(GroundAction("place_above", (o, b), F({("holding", o), ("near", b)}), F({("anchored",)}),
                                        F({("anchored",), rest(o, b)}), F(("above", o, x) for x in objs)))
                out.append(GroundAction("drop", (o, b), F({("holding", o), ("above", o, b)}), F(),
                                        F({("hand-empty",), ("near", o), rest(o, b)}),
                                        F({("holding", o), ("above", o, b)})))
            out.append(GroundAction("hold_above", (o, b), F({("holding", o), ("near", b)}), F({("anchored",)}),
                                    F({("above", o, b)}), F(("above", o, x) for x in objs if x != b)))
    liquids = [o for o in objs if has("liquid", o)]
    containers = [o for o in objs if has("container", o)]
    for s in movable:
        for v in containers:
            if v != s and has("long-enough", s, v):
                for liq in liquids:
                    if liq not in (s, v):
                        out.append(GroundAction("follow_traj_circle", (s, v, liq),
                                                F({("holding", s), ("above", s, v), ("in", liq, v)}), F(),
                                                F({("stirred", liq, s)}), F()))
    for a in containers:
        if not has("movable", a):
            continue
        for b in containers:
            if b != a:
                for liq in liquids:
                    if liq not in (a, b):
                        out.append(GroundAction("follow_traj_pour", (a, b, liq),
                                                F({("holding", a), ("above", a, b), ("in", liq, a)}), F(),
                                                F({("in", liq, b)}), F({("in", liq, a)})))
    return out
