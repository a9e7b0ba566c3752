"""Immutable symbolic states of a VEIL environment, and the release's parsed actions applied to them.

A `State` is a `World` (the environment's objects: category, affordances, position, non-boolean state values;
shared by every state of a sequence) and a frozenset of facts: ("Near", "Robot", "Beaker_1"),
("Grasping", "Robot", "Beaker_1"), ("On", "Teapot_1", "HotPlate_1"), ("In", "X", "Y"), ("state", "Beaker_1", "Tea").

Initial facts: an object's states are its category's defaults in `Objects.xml` overridden by the values its
environment file lists; a value `True` or a whole number other than 0 is a fact ("state", obj, name) (the
domain's comment: a state predicate holds when its value is 1, is false at 0; a count such as a value of 2
holds while any is left), `False` and `0` are no fact, and any other value (`Low`, `Null`) is
kept as an attribute of the object and makes no fact. The environments give no relations, so
no Near, On or In holds at first.

Meaning of the parsed formulas (`apply`): parameters are bound to the step's arguments; the constant `Robot` is
the robot; any other constant that names an object of the environment (`NameIndex.resolve`: `HotPlate1` is the
object `HotPlate_1`) is that object, except a `state` atom's second argument, which is a state name; a one-place
atom such as (IsGraspable ?o) holds when the object has that affordance or the fact is present; `forall` ranges
over the environment's objects (not the robot); every condition of a step, `when` conditions included, is
evaluated on the state before the step, and the step's deletes are applied before its adds.

One constraint the release leaves out of its domain ("the robot can only grasp two objects", its comment) is
written here once, as `MAX_GRASPED`: a step after which the robot would grasp more objects is refused.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from types import MappingProxyType

from ..words import counted
from .pddl import Action, And, Atom, Eq, ForAll, Formula, Not, Or, When
from .release import Catalog, Environment, NameIndex

ROBOT = "Robot"
MAX_GRASPED = 2  # the release's implicit rule: the robot holds at most two objects at once
TRUE_VALUES = frozenset({"true"})
FALSE_VALUES = frozenset({"false"})

Fact = tuple[str, ...]


@dataclass(frozen=True)
class ObjectInfo:
    """An environment object as the learner sees it; `catalogued` is False when `Objects.xml` has no category
    for its name (then `category` is its base name)."""

    name: str
    category: str
    catalogued: bool
    affordances: frozenset[str]
    position: tuple[float, float, float]
    attributes: tuple[tuple[str, str], ...]


@dataclass(frozen=True, eq=False)
class World:
    """The fixed part of every state of one environment: its objects by name, in file order."""

    env_id: str
    objects: Mapping[str, ObjectInfo]
    names: NameIndex = field(repr=False)

    def __iter__(self) -> Iterator[str]:
        return iter(self.objects)

    def __reduce__(self) -> tuple:
        # a read-only mapping cannot be pickled; a world crosses to worker processes as a plain dict
        return _world, (self.env_id, dict(self.objects), self.names)


def _world(env_id: str, objects: dict[str, ObjectInfo], names: NameIndex) -> World:
    return World(env_id, MappingProxyType(objects), names)


@dataclass(frozen=True)
class State:
    world: World
    facts: frozenset[Fact]

    def holds(self, *fact: str) -> bool:
        return tuple(fact) in self.facts

    def grasped(self) -> tuple[str, ...]:
        """Objects the robot grasps, sorted."""
        return tuple(sorted(f[2] for f in self.facts if f[0] == "Grasping" and f[1] == ROBOT))


class StepRefused(Exception):
    """A step whose precondition (or `MAX_GRASPED`) fails: `reason` in words, `code` for counting."""

    def __init__(self, reason: str, code: str) -> None:
        super().__init__(reason)
        self.reason, self.code = reason, code


def _boolean(value: str) -> bool | None:
    v = value.strip().lower()
    if v.isdigit():  # a count (a value of 2): the state holds while any is left
        return int(v) != 0
    return True if v in TRUE_VALUES else False if v in FALSE_VALUES else None


def build_world(env: Environment, catalog: Catalog) -> World:
    objects = {}
    for o in env.objects:
        category, cat = catalog.category_of(o.name)
        values: dict[str, str | None] = dict(cat.defaults) if cat is not None else {}
        values.update(o.states)
        attributes = tuple(sorted((k, v) for k, v in values.items() if v is not None and _boolean(v) is None))
        objects[o.name] = ObjectInfo(o.name, category, cat is not None,
                                     cat.affordances if cat is not None else frozenset(), o.position, attributes)
    return World(env.env_id, MappingProxyType(objects), env.names)


def initial_state(env: Environment, catalog: Catalog) -> State:
    """The environment's state before any step (module docstring)."""
    world = build_world(env, catalog)
    facts = set()
    for o in env.objects:
        _, cat = catalog.category_of(o.name)
        values: dict[str, str | None] = dict(cat.defaults) if cat is not None else {}
        values.update(o.states)
        facts |= {("state", o.name, k) for k, v in values.items() if v is not None and _boolean(v)}
    return State(world, frozenset(facts))


# evaluation -----------------------------------------------------------------------------------------------------
Binding = Mapping[str, str]


def _term(state: State, term: str, binding: Binding) -> str:
    if term.startswith("?"):
        return binding[term]
    if term == ROBOT:
        return ROBOT
    return state.world.names.resolve(term) or term


def _atom(state: State, atom: Atom, binding: Binding) -> Fact:
    args = [_term(state, a, binding) for a in atom.args]
    if atom.predicate == "state" and len(atom.args) == 2 and not atom.args[1].startswith("?"):
        args[1] = atom.args[1]  # a state name, never an object
    return (atom.predicate, *args)


def _true(state: State, fact: Fact) -> bool:
    if fact in state.facts:
        return True
    if len(fact) == 2:  # an affordance such as (IsGraspable ?o)
        info = state.world.objects.get(fact[1])
        return info is not None and fact[0] in info.affordances
    return False


def _describe(fact: Fact, holds: bool) -> tuple[str, str]:
    """A failed literal in words, and its code: `fact` was required to hold (`holds`) and does not, or the
    reverse."""
    pred, args = fact[0], fact[1:]
    if pred == "Near" and args[0] == ROBOT:
        return (f"the robot is not near {args[1]}", "not near") if holds else (
            f"the robot is already near {args[1]}", "already near")
    if pred == "Grasping" and args[0] == ROBOT:
        return (f"the robot is not grasping {args[1]}", "not grasping") if holds else (
            f"the robot is already grasping {args[1]}", "already grasping")
    if pred == "state":
        return (f"{args[0]} is not {args[1]}", f"not state {args[1]}") if holds else (
            f"{args[0]} is already {args[1]}", f"state {args[1]}")
    if len(args) == 1:
        return (f"{args[0]} is not {pred}", f"not {pred}") if holds else (f"{args[0]} is {pred}", pred)
    text = f"({' '.join(fact)})"
    return (f"{text} does not hold", f"not {pred}") if holds else (f"{text} holds", pred)


def _check(state: State, f: Formula, binding: Binding) -> tuple[str, str] | None:
    """None when `f` holds in `state`, else the first failed literal in words and its code."""
    if isinstance(f, Atom):
        fact = _atom(state, f, binding)
        return None if _true(state, fact) else _describe(fact, True)
    if isinstance(f, Eq):
        left, right = _term(state, f.left, binding), _term(state, f.right, binding)
        return None if left == right else (f"{left} is not {right}", "not equal")
    if isinstance(f, Not):
        if isinstance(f.body, Atom):
            fact = _atom(state, f.body, binding)
            return _describe(fact, False) if _true(state, fact) else None
        if isinstance(f.body, Eq):
            left, right = _term(state, f.body.left, binding), _term(state, f.body.right, binding)
            return (f"{left} is {right}", "equal") if left == right else None
        return ("a negated formula holds", "not") if _check(state, f.body, binding) is None else None
    if isinstance(f, And):
        for part in f.parts:
            failed = _check(state, part, binding)
            if failed is not None:
                return failed
        return None
    if isinstance(f, Or):
        fails = [_check(state, p, binding) for p in f.parts]
        if any(x is None for x in fails) or not fails:
            return None
        return " and ".join(x[0] for x in fails if x), "or"  # type: ignore[index]
    if isinstance(f, ForAll):
        for obj in state.world:
            failed = _check(state, f.body, {**binding, **dict.fromkeys(f.variables, obj)})
            if failed is not None:
                return failed
        return None
    raise TypeError(f"not a condition: {f!r}")


def _bindings(state: State, variables: Sequence[str], binding: Binding) -> Iterator[Binding]:
    if not variables:
        yield binding
        return
    for obj in state.world:
        yield from _bindings(state, variables[1:], {**binding, variables[0]: obj})


def _effects(state: State, f: Formula, binding: Binding, adds: set[Fact], dels: set[Fact]) -> None:
    if isinstance(f, Atom):
        adds.add(_atom(state, f, binding))
    elif isinstance(f, Not) and isinstance(f.body, Atom):
        dels.add(_atom(state, f.body, binding))
    elif isinstance(f, And):
        for part in f.parts:
            _effects(state, part, binding, adds, dels)
    elif isinstance(f, When):
        if _check(state, f.condition, binding) is None:
            _effects(state, f.effect, binding, adds, dels)
    elif isinstance(f, ForAll):
        for b in _bindings(state, f.variables, binding):
            _effects(state, f.body, b, adds, dels)
    else:
        raise TypeError(f"not an effect: {f!r}")


def _bind(action: Action, args: Sequence[str]) -> dict[str, str]:
    if len(args) != action.arity:
        wanted = counted(action.arity, "argument", spelled=True)
        raise ValueError(f"{action.name} takes {wanted}, not {len(args)}: {list(args)}")
    return dict(zip(action.parameters, args, strict=True))


def step(state: State, action: Action, args: Sequence[str]) -> State | StepRefused:
    """The state after `action(args)`, or why it cannot run: the first failed precondition literal, or
    `MAX_GRASPED`."""
    binding = _bind(action, args)
    call = f"{action.name}({', '.join(args)})"
    if action.precondition is not None:
        failed = _check(state, action.precondition, binding)
        if failed is not None:
            return StepRefused(f"{call}: {failed[0]}", failed[1])
    adds: set[Fact] = set()
    dels: set[Fact] = set()
    _effects(state, action.effect, binding, adds, dels)
    after = State(state.world, frozenset((state.facts - dels) | adds))
    if len(after.grasped()) > MAX_GRASPED:
        return StepRefused(f"{call}: the robot already grasps {len(state.grasped())} objects "
                           f"({', '.join(state.grasped())}); it can hold at most {MAX_GRASPED}", "hands full")
    return after


def refusal(state: State, action: Action, args: Sequence[str]) -> StepRefused | None:
    """Why `action(args)` cannot run in `state`, or None when it can."""
    result = step(state, action, args)
    return result if isinstance(result, StepRefused) else None


def apply(state: State, action: Action, args: Sequence[str]) -> State:
    """The state after `action(args)`; raises `StepRefused` when its precondition or `MAX_GRASPED` fails."""
    result = step(state, action, args)
    if isinstance(result, StepRefused):
        raise result
    return result
