"""The simulator's rules as a person reads them: its preconditions and safety rules, and why a step is refused.

The page states the rules the simulator applies, so they are read from its
code rather than written again here: the preconditions of each primitive
are the checks its effect function makes (`sim.primitives`, read once from
its source), the safety rules are `sim.safety.RULES`. A rule changed there
changes the page with it.

A refusal names objects by their names, as the page shows them, never by
ids a person never sees, and never prints Python's `None`.
"""

from __future__ import annotations

import ast
import functools
import inspect
import re
from dataclasses import dataclass

from ..sim import primitives
from ..sim.primitives import ALL_PRIMITIVES, Action, PreconditionError
from ..sim.safety import RULES, violations
from ..sim.state import WorldState


class UnsafeStep(ValueError):
    """A step the page refuses because it breaks a safety rule; `reason` says which and why, in names."""

    def __init__(self, action: Action, reason: str) -> None:
        super().__init__(f"{action}: {reason}")
        self.action, self.reason = action, reason


@functools.cache
def preconditions() -> dict[str, tuple[str, ...]]:
    """Per primitive, the names of the checks the simulator makes before running it, in the order it makes them.

    Read from the source of `sim.primitives`: every `_require(cond, action, check, reason)` in the primitive's
    effect function, and in the module's helpers it calls (`_check_target`), in order."""
    tree = ast.parse(inspect.getsource(primitives))
    functions = {node.name: node for node in tree.body if isinstance(node, ast.FunctionDef)}

    def checks(name: str) -> list[str]:
        out: list[str] = []
        calls = [n for n in ast.walk(functions[name]) if isinstance(n, ast.Call) and isinstance(n.func, ast.Name)]
        for node in sorted(calls, key=lambda n: (n.lineno, n.col_offset)):  # ast.walk is breadth first
            if node.func.id == "_require":
                out.append(node.args[2].value)
            elif node.func.id in functions and node.func.id != name:
                out += checks(node.func.id)
        return out

    effects = primitives._EFFECTS
    return {p: tuple(dict.fromkeys(checks(effects[p].__name__))) for p in ALL_PRIMITIVES}


def named(state: WorldState, text: str) -> str:
    """`text` with every object id replaced by the object's name, and Python's `None` by "nothing"; where the
    simulator wrote an id and its name (`obj02 (kitchen_table) cannot be moved`), the name once."""
    text = re.sub(r"\bNone\b", "nothing", text)
    ids = sorted(state.specs, key=len, reverse=True)  # obj1 must not eat the start of obj14
    if not ids:
        return text
    pattern = re.compile(r"\b(" + "|".join(re.escape(o) for o in ids) + r")\b")
    return re.sub(r"(\b[\w.-]+) \(\1\)", r"\1", pattern.sub(lambda m: state.specs[m.group(1)].name, text))


def refusal(state: WorldState, err: PreconditionError) -> str:
    """Why the simulator refuses a step, in names. The simulator lets the gripper hold a thing above a liquid itself
    (nothing breaks), after which a stir or a pour there finds no liquid or no container, which its own words
    (`water holds no liquid to stir`) make sound absurd: then the reason says what is below and where to hold."""
    below = state.held_above
    if err.check in ("liquid below", "container") and below is not None and state.specs[below].has("liquid"):
        container = state.container_of(below)
        where = f"; hold it above {state.specs[container].name}, which holds {state.specs[below].name}" if (
            container and err.check == "liquid below") else ""
        return (f"{state.specs[state.held].name} is held above {state.specs[below].name}, a liquid itself, not a "
                f"container{where}")
    return named(state, err.reason)


def _why(state: WorldState, action: Action, rule: str) -> str:
    """What in this world makes `action` break `rule`, in names."""
    name = state.specs
    if rule == "liquid_grasped":
        target = action.args[0]
        container = state.container_of(target)
        where = f"; grasp {name[container].name}, which holds it" if container else ""
        return f"{name[target].name} is a liquid{where}"
    if rule == "grasp_with_load":
        target = action.args[0]
        loads = [name[o].name for o in state.loads(target)]
        verb, them = ("rests", "it") if len(loads) == 1 else ("rest", "them")
        return f"{' and '.join(loads)} {verb} on {name[target].name}; take {them} off first"
    if rule == "over_shelf":
        below = state.held_above
        shelf = next(a for a in state.ancestors(below) if state.specs[a].has("multi_surface"))
        return f"{name[below].name} is on {name[shelf].name}; bring it to a table first"
    return RULES[rule]  # a rule added to sim.safety without its own explanation here: its words say it


def unsafe_reason(state: WorldState, action: Action) -> str | None:
    """Why `action` breaks a safety rule in `state` (each rule in words, and what in the world breaks it), or None
    when it breaks none."""
    broken = violations(state, action)
    if not broken:
        return None
    return "; and ".join(f"it breaks the safety rule \u201c{RULES[r]}\u201d: {_why(state, action, r)}" for r in broken)


@dataclass(frozen=True)
class Choices:
    """What the step form offers for one primitive: the held object where the primitive works on it (or why it
    cannot be chosen now), and the objects offered for each other argument, with what they are in words (which the
    page says when an object clicked in the picture is not among them)."""

    held: str | None  # a1, fixed: the primitive works on what the gripper holds
    lists: tuple[tuple[str, ...], ...]  # the objects offered per remaining argument, by id
    unavailable: str | None = None  # why the primitive cannot be chosen now, in words
    offers: tuple[str, ...] = ()  # per list, what it offers: "movable things, never a liquid"


def argument_choices(state: WorldState) -> dict[str, Choices]:
    """Per primitive, the objects worth offering, from the simulator's checks (`sim.primitives`) and safety rules.

    A checks that holds whatever the person does next narrows a list: `held` (release, place_above, hold_above and
    the trajectories work on the held object, so a1 is it), `movable` (grasp), `not held` (move_close),
    `separate objects` (a target never rests on or in the held object), `container` (pour into one), and the
    rule that a liquid is handled only through its container (never grasped, placed on or held over). The floor
    is no place to drive to. Checks that depend on where the robot stands (within reach, room below) are left
    to the simulator, whose refusal says why. Names sort the lists, as the person reads them."""
    specs = state.specs

    def ordered(ids) -> tuple[str, ...]:
        return tuple(sorted(ids, key=lambda o: (specs[o].name, o)))

    liquid = {o for o in specs if specs[o].has("liquid")}
    floor = {o for o in specs if specs[o].category == "floor"}
    held = state.held
    out = {
        "move_close": Choices(None, (ordered(o for o in specs if o != held and o not in floor),), None,
                              ("any object but the floor" + ("" if held is None else " and the held one"),)),
        "grasp": Choices(None, (ordered(o for o in specs if specs[o].has("movable") and o not in liquid),),
                         None if held is None else f"the gripper holds {specs[held].name}; release it first",
                         ("movable things, never a liquid",)),
        "done": Choices(None, ()),
    }
    if held is None:
        for p in ("release", "place_above", "hold_above", "follow_traj_circle", "follow_traj_pour"):
            out[p] = Choices(None, (), "nothing is in the gripper")
        return out
    carried = {held, *state.descendants(held)}
    targets = ordered(o for o in specs if o not in carried and o not in liquid)
    name = specs[held].name
    targets_are = f"anything but a liquid, {name} and what rests on or in it"
    out.update({
        "release": Choices(held, ()),
        "place_above": Choices(held, (targets,), None, (targets_are,)),
        "hold_above": Choices(held, (targets,), None, (targets_are,)),
        "follow_traj_circle": Choices(held, ()),
        "follow_traj_pour": Choices(held, (ordered(o for o in specs if o not in carried
                                                   and specs[o].has("container")),), None,
                                    (f"a container other than {name} and what it carries",)),
    })
    return out
