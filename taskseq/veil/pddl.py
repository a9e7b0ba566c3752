"""A tolerant reader of the release's `domainKnowledge.pddl`: its actions are parsed, never re-typed.

Why a reader of our own: the `pddl` package (a dev dependency of the project, used for the benchmark's own domain)
refuses this file. The file uses the constant `Robot` (and object names such as `HotPlate1`)
without declaring them, declares no `:requirements` although it uses `:conditional-effects`, `forall` and
equality, overloads `pour` with one and with two parameters, and has actions without parameters or without a
precondition. This reader accepts all of that and keeps every formula as written (also where one looks like a slip
of the release, docs/veil.md); what the formulas mean is `taskseq.veil.state`.

Grammar read: s-expressions with `;` comments; `(define (domain N) (:predicates ...) (:action ...)*)`; an action
has `:parameters (?a ...)`, an optional `:precondition` and an `:effect`; formulas are `and`, `or`, `not`, `when`,
`forall`, `=` and predicate atoms. A parse error names the file, the line and what was expected.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from .xmltree import VeilFormatError


@dataclass(frozen=True)
class Atom:
    """A predicate applied to terms: variables (`?x`) or constants (`Robot`, `HotPlate1`, a state name)."""

    predicate: str
    args: tuple[str, ...]

    def __str__(self) -> str:
        return f"({' '.join((self.predicate, *self.args))})"


@dataclass(frozen=True)
class Eq:
    left: str
    right: str


@dataclass(frozen=True)
class Not:
    body: Formula


@dataclass(frozen=True)
class And:
    parts: tuple[Formula, ...]


@dataclass(frozen=True)
class Or:
    parts: tuple[Formula, ...]


@dataclass(frozen=True)
class When:
    condition: Formula
    effect: Formula


@dataclass(frozen=True)
class ForAll:
    variables: tuple[str, ...]
    body: Formula


Formula = Atom | Eq | Not | And | Or | When | ForAll


@dataclass(frozen=True)
class Action:
    """One `(:action ...)`: its name, parameters, precondition (None when it has none), effect and line."""

    name: str
    parameters: tuple[str, ...]
    precondition: Formula | None
    effect: Formula
    line: int

    @property
    def arity(self) -> int:
        return len(self.parameters)


@dataclass(frozen=True)
class Domain:
    """The parsed domain: its name, declared predicates (name -> arity) and actions in file order."""

    name: str
    predicates: dict[str, int]
    actions: tuple[Action, ...]
    path: str

    def action(self, name: str, arity: int) -> Action | None:
        """The action of this name and number of parameters (`pour` exists with one and with two)."""
        for a in self.actions:
            if a.name.lower() == name.lower() and a.arity == arity:
                return a
        return None

    def named(self, name: str) -> tuple[Action, ...]:
        return tuple(a for a in self.actions if a.name.lower() == name.lower())


@dataclass(frozen=True)
class _Tok:
    text: str
    line: int


# an s-expression: a token or a list of them, with the line it starts on
@dataclass(frozen=True)
class _List:
    items: tuple[_Tok | _List, ...]
    line: int


def _tokens(text: str) -> list[_Tok]:
    out: list[_Tok] = []
    for lineno, line in enumerate(text.splitlines(), start=1):
        line = line.split(";", 1)[0]
        for piece in line.replace("(", " ( ").replace(")", " ) ").split():
            out.append(_Tok(piece, lineno))
    return out


class _Reader:
    def __init__(self, path: Path | str, text: str) -> None:
        self.path = str(path)
        self.toks = _tokens(text)
        self.last_line = max(1, len(text.splitlines()))

    def fail(self, line: int, element: str, expected: str) -> VeilFormatError:
        return VeilFormatError(self.path, line, element, f"expected {expected}")

    def sexprs(self) -> list[_Tok | _List]:
        stack: list[tuple[list[_Tok | _List], int]] = [([], 1)]
        for tok in self.toks:
            if tok.text == "(":
                stack.append(([], tok.line))
            elif tok.text == ")":
                if len(stack) == 1:
                    raise self.fail(tok.line, "')'", "no ')' without its '(' before it")
                items, line = stack.pop()
                stack[-1][0].append(_List(tuple(items), line))
            else:
                stack[-1][0].append(tok)
        if len(stack) > 1:
            raise self.fail(self.last_line, "(end of file)", f"a ')' closing the '(' of line {stack[-1][1]}")
        return stack[0][0]

    # formulas ---------------------------------------------------------------------------------------------
    def symbol(self, item: _Tok | _List, what: str, ctx: str) -> str:
        if not isinstance(item, _Tok):
            raise self.fail(item.line, ctx, what)
        return item.text

    def formula(self, item: _Tok | _List, ctx: str) -> Formula:
        if not isinstance(item, _List) or not item.items:
            raise self.fail(item.line, ctx, "a formula in parentheses, e.g. (Near Robot ?o)")
        head = self.symbol(item.items[0], "a predicate name or and/or/not/when/forall/=", ctx)
        rest = item.items[1:]
        key = head.lower()
        if key in ("and", "or"):
            parts = tuple(self.formula(r, ctx) for r in rest)
            return And(parts) if key == "and" else Or(parts)
        if key == "not":
            if len(rest) != 1:
                raise self.fail(item.line, ctx, "(not F) with exactly one formula F")
            return Not(self.formula(rest[0], ctx))
        if key == "when":
            if len(rest) != 2:
                raise self.fail(item.line, ctx, "(when CONDITION EFFECT)")
            return When(self.formula(rest[0], ctx), self.formula(rest[1], ctx))
        if key == "forall":
            if len(rest) != 2 or not isinstance(rest[0], _List):
                raise self.fail(item.line, ctx, "(forall (?v ...) BODY)")
            names = tuple(self.variable(v, ctx) for v in rest[0].items)
            return ForAll(names, self.formula(rest[1], ctx))
        args = tuple(self.symbol(r, "a variable or constant (not a nested formula)", ctx) for r in rest)
        if head == "=":
            if len(args) != 2:
                raise self.fail(item.line, ctx, "(= A B) with two terms")
            return Eq(*args)
        return Atom(head, args)

    def variable(self, item: _Tok | _List, ctx: str) -> str:
        name = self.symbol(item, "a variable such as ?x", ctx)
        if not name.startswith("?") or len(name) < 2:
            raise self.fail(item.line, ctx, f"a variable such as ?x, not {name!r}")
        return name

    # domain ------------------------------------------------------------------------------------------------
    def action(self, item: _List) -> Action:
        if len(item.items) < 2 or not isinstance(item.items[1], _Tok):
            raise self.fail(item.line, "(:action)", "an action name after :action")
        name = item.items[1].text
        ctx = f"(:action {name})"
        fields: dict[str, _Tok | _List] = {}
        rest = list(item.items[2:])
        while rest:
            key = rest.pop(0)
            if not isinstance(key, _Tok) or not key.text.startswith(":"):
                raise self.fail(key.line, ctx, ":parameters, :precondition or :effect")
            k = key.text.lower()
            if k not in (":parameters", ":precondition", ":effect"):
                raise self.fail(key.line, ctx, f":parameters, :precondition or :effect, not {key.text}")
            if not rest:
                raise self.fail(key.line, ctx, f"a value after {key.text}")
            fields[k] = rest.pop(0)
        params: tuple[str, ...] = ()
        if ":parameters" in fields:
            p = fields[":parameters"]
            if not isinstance(p, _List):
                raise self.fail(p.line, ctx, "a parameter list such as (?o) or ()")
            params = tuple(self.variable(v, ctx) for v in p.items)
        if ":effect" not in fields:
            raise self.fail(item.line, ctx, "an :effect")
        pre = self.formula(fields[":precondition"], ctx) if ":precondition" in fields else None
        return Action(name, params, pre, self.formula(fields[":effect"], ctx), item.line)

    def domain(self) -> Domain:
        top = self.sexprs()
        if len(top) != 1 or not isinstance(top[0], _List):
            line = top[1].line if len(top) > 1 else self.last_line
            raise self.fail(line, "(file)", "one (define (domain NAME) ...) and nothing after it")
        define = top[0]
        if not define.items or not isinstance(define.items[0], _Tok) or define.items[0].text.lower() != "define":
            raise self.fail(define.line, "(define)", "(define (domain NAME) ...)")
        name = ""
        predicates: dict[str, int] = {}
        actions: list[Action] = []
        for item in define.items[1:]:
            if not isinstance(item, _List) or not item.items or not isinstance(item.items[0], _Tok):
                raise self.fail(item.line, "(define)", "(domain N), (:predicates ...) or (:action ...)")
            head = item.items[0].text.lower()
            if head == "domain" and len(item.items) == 2:
                name = self.symbol(item.items[1], "a domain name", "(domain)")
            elif head == ":predicates":
                for p in item.items[1:]:
                    if not isinstance(p, _List) or not p.items:
                        raise self.fail(p.line, "(:predicates)", "a predicate such as (Near ?x ?y)")
                    pname = self.symbol(p.items[0], "a predicate name", "(:predicates)")
                    predicates[pname] = len(p.items) - 1
            elif head == ":action":
                actions.append(self.action(item))
            elif head in (":requirements", ":types", ":constants"):
                continue  # tolerated: the release has none, other files in its style may
            else:
                raise self.fail(item.line, "(define)", f"(domain N), (:predicates ...) or (:action ...), not {head}")
        if not actions:
            raise self.fail(define.line, "(define)", "at least one (:action ...)")
        seen: dict[tuple[str, int], int] = {}
        for a in actions:
            key = (a.name.lower(), a.arity)
            if key in seen:
                raise self.fail(a.line, f"(:action {a.name})",
                                f"one action {a.name} with {a.arity} parameters (another at line {seen[key]})")
            seen[key] = a.line
        return Domain(name, predicates, tuple(actions), self.path)


def parse_domain(text: str, path: Path | str = "<domain>") -> Domain:
    """Parse domain text; `path` only names the file in errors."""
    return _Reader(path, text).domain()


def read_domain(path: Path | str) -> Domain:
    """Read and parse a `domainKnowledge.pddl`; a missing or malformed file raises `VeilFormatError`."""
    try:
        text = Path(path).read_text(encoding="utf-8", errors="replace")
    except OSError as err:
        raise VeilFormatError(path, 0, "(file)", f"cannot be read: {err.strerror or err}") from None
    return parse_domain(text, path)
