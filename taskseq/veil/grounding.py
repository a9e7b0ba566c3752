"""One action line of `data.xml` (`keep Teapot_1 On HotPlate_1`) to the domain action that executes it, and to the
step the learner sees.

Which domain action: the object-specific action `<verb>_<Object>` when the domain defines one (`turn_HotPlateKnob_1`,
`press_Radio_1PowerButton`; `add_<Object> ?x`: the line's remaining objects are its parameters), else the generic
action of the verb with as many parameters as the line has arguments (`grasp ?o`, `pour ?x` or `pour ?x ?y`). For
`keep X <Rel> Y` it is `keep_<Rel>_<Y> ?x` when defined, else the generic `keep ?x ?rel ?z`.

Names (checked on the release): the domain writes an object-specific name as the object is written in the
sequences, but for case and, for some objects, an underscore (the fixture's
`keep_On_HotPlate1` for the object `HotPlate_1`). So an action is looked up by its object's
name without case and underscores (`release.loose_key`); two actions of one verb whose names meet under that
key are an error of the domain. The relation words of the sequences are `On` and `Inside`; the domain writes
`Inside` as `In` (`keep_In_<Object>`, `(= ?rel In)`), so `RELATIONS` maps one to the other.

`wait` is an instruction of `ControllerInstructions.xml` but no action of the domain: it grounds to `WAIT`, an
action with no precondition and no effect, unless the domain defines one.

For learning, a step is `Step(verb, a1, a2)` with the relation folded into the verb (`keep_on`, `keep_inside`:
each relation gets its own weights as a primitive, and every step keeps at most two object arguments, the MRF's
(p, a1, a2) shape); `pour` has an optional second argument, `wait` none. The verbs are `VERBS`.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

from ..words import counted
from .pddl import Action, And, Domain
from .release import NameIndex, loose_key
from .xmltree import VeilFormatError

VERBS = ("moveto", "grasp", "release", "keep_on", "keep_inside", "turn", "open", "close", "press", "pour",
         "add", "insert", "scoop", "squeeze", "place", "wait")
RELATIONS = {"On": "On", "Inside": "In"}  # a sequence's relation word -> the domain's
# the number of words after the verb each instruction takes (ControllerInstructions.xml; `read_instructions`
# gives the same from a release's file)
ARITIES: dict[str, tuple[int, ...]] = {
    "moveto": (1,), "grasp": (1,), "release": (1,), "keep": (3,), "turn": (1,), "open": (1,), "close": (1,),
    "press": (1,), "pour": (1, 2), "add": (2,), "insert": (2,), "scoop": (2,), "squeeze": (2,), "place": (2,),
    "wait": (0, 1),
}
WAIT = Action("wait", (), None, And(()), 0)


@dataclass(frozen=True)
class Step:
    """A step as the learner sees it: a verb of `VERBS` and at most two objects (environment spellings)."""

    verb: str
    a1: str | None = None
    a2: str | None = None

    def __str__(self) -> str:
        return f"{self.verb}({', '.join(a for a in (self.a1, self.a2) if a is not None)})"


@dataclass(frozen=True)
class Grounded:
    """A line grounded in an environment: its step, and the domain action with its arguments."""

    step: Step
    action: Action
    args: tuple[str, ...]


class ActionError(ValueError):
    """A line no action of the domain executes, or not of the instructions' shape: an error of the release."""


class UnknownObject(LookupError):
    """A line naming an object its environment does not hold: people's noise (`taskseq.veil.replay`)."""

    def __init__(self, name: str) -> None:
        super().__init__(f"no object {name} in this environment")
        self.name = name


@dataclass(frozen=True)
class _Parsed:
    verb: str
    objects: tuple[str, ...]  # object words as written
    relation: str | None  # `keep`'s relation word as the domain writes it
    action: Action
    specific: bool  # an object-specific action: its parameters are the objects after the first


class ActionIndex:
    """The domain's actions by verb and by the loose key of their object (module docstring)."""

    def __init__(self, domain: Domain) -> None:
        self.domain = domain
        self.specific: dict[tuple[str, ...], Action] = {}
        for a in domain.actions:
            parts = a.name.split("_", 1)
            if len(parts) < 2 or not parts[1]:
                continue
            verb, rest = parts[0].lower(), parts[1]
            if verb == "keep":
                rel, _, target = rest.partition("_")
                key: tuple[str, ...] = (verb, rel.lower(), loose_key(target))
            else:
                key = (verb, loose_key(rest))
            if key in self.specific:
                other = self.specific[key]
                raise VeilFormatError(domain.path, a.line, f"(:action {a.name})",
                                      f"its name meets {other.name} (line {other.line}) without case and underscores")
            self.specific[key] = a

    def parse(self, text: str, arities: Mapping[str, tuple[int, ...]] = ARITIES) -> _Parsed:
        """The domain action of a line, independently of any environment; `ActionError` when there is none."""
        words = text.split()
        if not words:
            raise ActionError("an empty action")
        verb = words[0].lower()
        if verb not in arities:
            raise ActionError(f"unknown action {words[0]!r} (instructions: {', '.join(sorted(arities))})")
        rest = words[1:]
        if len(rest) not in arities[verb]:
            *fewer, most = arities[verb]
            wanted = (" or ".join([*map(str, fewer), counted(most, "argument")]) if fewer  # 0 or 1 argument
                      else counted(most, "argument", spelled=True))
            raise ActionError(f"{verb} takes {wanted}, not {len(rest)}: {text!r}")
        if verb == "wait":
            if rest and not rest[0].isdigit():
                raise ActionError(f"wait takes a whole number of seconds, not {rest[0]!r}")
            return _Parsed(verb, (), None, self.domain.action("wait", 0) or WAIT, False)
        if verb == "keep":
            obj, word, target = rest
            rel = next((RELATIONS[r] for r in RELATIONS if r.lower() == word.lower()), None)
            if rel is None:
                raise ActionError(f"unknown relation {word!r} in {text!r} (known: {', '.join(RELATIONS)})")
            a = self.specific.get(("keep", rel.lower(), loose_key(target)))
            if a is not None and a.arity == 1:
                return _Parsed(verb, (obj, target), rel, a, True)
            a = self.domain.action("keep", 3)
            if a is None:
                raise ActionError(f"no action of the domain executes {text!r} (no keep_{rel}_{target}, no keep)")
            return _Parsed(verb, (obj, target), rel, a, False)
        a = self.specific.get((verb, loose_key(rest[0])))
        if a is not None and a.arity == len(rest) - 1:
            return _Parsed(verb, tuple(rest), None, a, True)
        a = self.domain.action(verb, len(rest))
        if a is None:
            raise ActionError(f"no action of the domain executes {text!r} "
                              f"(no {verb}_{rest[0]}, no {verb} with {len(rest)} parameters)")
        return _Parsed(verb, tuple(rest), None, a, False)

    def ground(self, text: str, names: NameIndex, arities: Mapping[str, tuple[int, ...]] = ARITIES) -> Grounded:
        """Ground a line in an environment; `ActionError` for a line of no action, `UnknownObject` for a name
        the environment does not hold (compared without case, `NameIndex.strict`)."""
        parsed = self.parse(text, arities)
        objs = []
        for word in parsed.objects:
            name = names.strict(word)
            if name is None:
                raise UnknownObject(word)
            objs.append(name)
        if parsed.verb == "keep":
            verb = "keep_" + next(k for k, v in RELATIONS.items() if v == parsed.relation).lower()
            step = Step(verb, objs[0], objs[1])
            args = (objs[0],) if parsed.specific else (objs[0], parsed.relation, objs[1])
            return Grounded(step, parsed.action, args)  # type: ignore[arg-type]
        step = Step(parsed.verb, objs[0] if objs else None, objs[1] if len(objs) > 1 else None)
        args = tuple(objs[1:]) if parsed.specific else tuple(objs)
        return Grounded(step, parsed.action, args)
