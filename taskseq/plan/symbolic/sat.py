"""Planning as satisfiability (Kautz and Selman): the shortest plan by incremental SAT.

One variable per ground action and per fluent at each time step; actions
imply their preconditions and effects; explanatory frame axioms say a fluent
changes only through an action that adds or deletes it; at most one action per
step (a sequential counter), and no empty step before an action. The goal holds
at the horizon H; assuming "no action at step k" bounds the plan to k steps,
so trying k = 0, 1, ..., H on one incremental solver finds the shortest plan.
"""

from __future__ import annotations

import gc
from collections import OrderedDict, deque
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, replace
from functools import partial

import numpy as np
import pysolvers  # python-sat's compiled solvers (`_clause_adder`)
from pysat.card import CardEnc, EncType
from pysat.solvers import Glucose4, Solver

from .problem import Atom, GroundAction, Problem, ground_actions
from .stored_plans import PlanCache, plan_key


@dataclass
class PlanResult:
    plan: list[GroundAction] | None  # None: no plan within the horizon
    horizon: int
    n_actions: int  # ground actions considered

    @property
    def found(self) -> bool:
        return self.plan is not None

    def message(self) -> str:
        if self.plan is None:
            return f"no plan within horizon {self.horizon}"
        return f"plan of {len(self.plan)} steps"


def encode(problem: Problem, actions: list[GroundAction], fluents: list[Atom],
           horizon: int) -> tuple[list[list[int]], Callable[[int, int], int], Callable[[int], int]]:
    """The clauses of the planning problem, with the variables of "action i at step t" and "an action at t".

    Variables: fluent f at step t is 1 + t*F + f; action i at step t is
    1 + (H+1)*F + t*A + i; "some action at t" follows them; the sequential
    counters' auxiliary variables come last, one block per step. Every step's
    clauses are the first step's with each kind of variable shifted by the
    step, so the first step's are written out and the rest are shifted copies
    (NumPy over all steps at once), in the same order as writing each step out.
    """
    F, A, H = len(fluents), len(actions), horizon
    fid = {f: k for k, f in enumerate(fluents)}
    n_fluent, n_action = (H + 1) * F, H * A

    def fv(f: Atom, t: int) -> int:
        return 1 + t * F + fid[f]

    def av(i: int, t: int) -> int:
        return 1 + n_fluent + t * A + i

    def act(t: int) -> int:
        return 1 + n_fluent + n_action + t

    top = n_fluent + n_action + H
    clauses: list[list[int]] = [[fv(f, 0) if f in problem.init else -fv(f, 0)] for f in fluents]
    if H == 0:
        return clauses + [[fv(g, 0)] for g in sorted(problem.goal)], av, act
    adders: dict[Atom, list[int]] = {f: [] for f in fluents}
    deleters: dict[Atom, list[int]] = {f: [] for f in fluents}
    # every set is walked in sorted order: clause order steers the solver, and set order
    # changes with Python's per-process string hashing
    for i, a in enumerate(actions):
        for f in sorted(a.add):
            adders[f].append(i)
        for f in sorted(a.delete - a.add):
            deleters[f].append(i)
    # step 0, in three parts: actions and the counter; "an action at 1 needs one at 0"; frame axioms
    lits = [av(i, 0) for i in range(A)]
    head: list[list[int]] = []
    for i, a in enumerate(actions):
        x = av(i, 0)
        head += [[-x, fv(f, 0)] for f in sorted(a.pre)]
        head += [[-x, -fv(f, 0)] for f in sorted(a.pre_not)]
        head += [[-x, fv(f, 1)] for f in sorted(a.add)]
        head += [[-x, -fv(f, 1)] for f in sorted(a.delete - a.add)]
        head.append([-x, act(0)])
    head.append([-act(0), *lits])
    card = CardEnc.atmost(lits=lits, bound=1, top_id=top, encoding=EncType.seqcounter)
    n_aux = max(top, card.nv) - top
    head += card.clauses
    chain = [[-act(1), act(0)]]
    frame: list[list[int]] = []
    for f in fluents:
        frame.append([-fv(f, 0), fv(f, 1), *(av(i, 0) for i in deleters[f])])
        frame.append([fv(f, 0), -fv(f, 1), *(av(i, 0) for i in adders[f])])
    # how far each variable moves per step: fluents by F, actions by A, "an action" by 1, counters by their size
    bounds = np.array([n_fluent, n_fluent + n_action, top])
    for t, part in enumerate(_shifted([head, chain, frame], bounds, np.array([F, A, 1, n_aux]), H)):
        clauses += part[0]
        if t + 1 < H:
            clauses += part[1]
        clauses += part[2]
    return clauses + [[fv(g, H)] for g in sorted(problem.goal)], av, act


def _shifted(parts: list[list[list[int]]], bounds: np.ndarray, shifts: np.ndarray,
             horizon: int) -> list[list[list[list[int]]]]:
    """For each step t < horizon, `parts` with every variable v moved by t * shifts[kind of v]."""
    flat = np.array([lit for part in parts for clause in part for lit in clause], dtype=np.int64)
    move = np.sign(flat) * shifts[np.searchsorted(bounds, np.abs(flat))]
    steps = (flat[None, :] + np.arange(horizon)[:, None] * move[None, :]).tolist()
    ends = np.cumsum([len(c) for part in parts for c in part]).tolist()
    starts = [0, *ends[:-1]]
    cuts = np.cumsum([0, *(len(part) for part in parts)]).tolist()
    out = []
    for row in steps:
        clauses = list(map(row.__getitem__, map(slice, starts, ends)))  # no bytecode per clause
        out.append([clauses[a:b] for a, b in zip(cuts[:-1], cuts[1:], strict=True)])
    return out


# Solving is a pure function of the problem: a rollout and the teacher-forced steps of the same
# state ask for the same plan, so answers are kept (the problem's content is the key)
_SOLVED: OrderedDict[tuple, PlanResult] = OrderedDict()
_SOLVED_MAX = 4096


def solve(problem: Problem, horizon: int = 12, solver: str = "g4") -> PlanResult:
    """The shortest plan of `problem` within `horizon` steps: kept in this process, and with a cache in force
    read from or stored to it (`stored_plans`)."""
    key = (tuple(problem.objects), frozenset(problem.statics), frozenset(problem.init), frozenset(problem.goal),
           horizon, solver)
    if key in _SOLVED:
        _SOLVED.move_to_end(key)
        return _copy(_SOLVED[key])
    stored = PlanCache.active()
    digest = plan_key(problem, horizon, solver) if stored is not None else ""
    answer = stored.load(digest, problem) if stored is not None else None
    if answer is not None:
        result = PlanResult(answer[0], horizon, answer[1])
    else:
        result = _solve(problem, horizon, solver)
        if stored is not None:
            stored.save(digest, result.plan, result.n_actions)
    _SOLVED[key] = _copy(result)
    if len(_SOLVED) > _SOLVED_MAX:
        _SOLVED.popitem(last=False)
    return result


def _copy(result: PlanResult) -> PlanResult:
    """A result with a plan list of its own: what a caller does to it never reaches what is kept."""
    return replace(result, plan=None if result.plan is None else list(result.plan))


@contextmanager
def _no_cycle_collection() -> Iterator[None]:
    enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if enabled:
            gc.enable()


def _clause_adder(sat: Solver) -> Callable[[list[int]], object]:
    """Glucose 4.1's own add-clause on the solver's handle, for the default solver; any other through its wrapper.

    python-sat's `Solver.add_clause` calls its solver's `add_clause`, which
    calls the compiled function: two Python calls a clause, which were half of
    the symbolic baselines' time on a 130-room world (68 million clauses,
    about 1.2 us each). The compiled function takes the same clause in the
    same order; a clause that makes the formula unsatisfiable at once leaves
    the solver unsatisfiable, which `solve` then reports.
    """
    inner = sat.solver
    if isinstance(inner, Glucose4):
        return partial(pysolvers.glucose41_add_cl, inner.glucose)
    return sat.add_clause


def _solve(problem: Problem, horizon: int, solver: str) -> PlanResult:
    actions = ground_actions(problem)
    fluents = sorted({f for a in actions for f in a.pre | a.pre_not | a.add | a.delete} | problem.goal)
    if not problem.goal <= set(fluents) | problem.init:
        return PlanResult(None, horizon, len(actions))
    with _no_cycle_collection():  # thousands of small lists that form no cycles: collecting them is wasted time
        clauses, av, act = encode(problem, actions, fluents, horizon)
        sat = Solver(name=solver)
        deque(map(_clause_adder(sat), clauses), maxlen=0)  # in order, as `bootstrap_with` does, without its loop
        del clauses
    with sat:
        for k in range(horizon + 1):
            assumptions = [-act(k)] if k < horizon else []
            if sat.solve(assumptions=assumptions):
                model = {v for v in sat.get_model() if v > 0}
                chosen = [actions[i] for t in range(k) for i in range(len(actions)) if av(i, t) in model]
                plan = canonical(problem, chosen)
                return PlanResult(plan, horizon, len(actions))
    return PlanResult(None, horizon, len(actions))


def apply(state: frozenset[Atom], action: GroundAction) -> frozenset[Atom] | None:
    """The successor in the domain's semantics, or None when the action is not applicable."""
    if not action.pre <= state or action.pre_not & state:
        return None
    return frozenset((state - action.delete) | action.add)


def valid(problem: Problem, plan: list[GroundAction]) -> bool:
    state: frozenset[Atom] | None = frozenset(problem.init)
    for action in plan:
        state = apply(state, action)
        if state is None:
            return False
    return problem.goal <= state


def canonical(problem: Problem, plan: list[GroundAction]) -> list[GroundAction]:
    """Among plans of the same length, the one a person would write.

    SAT returns any shortest plan; this settles the ties the way the domain's
    conventions do: set a cleared object down on the furniture it stood on,
    set things down on surfaces (place, release) and drop them into
    receptacles (hold above, release), move close to the object the next step
    works on. Each change is kept only if the plan stays valid.
    """
    by_key = {(a.name, a.args): a for a in ground_actions(problem)}
    plan = list(plan)
    support = {f[1]: f[2] for f in problem.init if f[0] == "on"}
    furniture = {o for o in problem.objects
                 if ("large-surface", o) in problem.statics and ("movable", o) not in problem.statics}
    for k, a in enumerate(plan):
        if a.name != "place_above" or a.args[0] not in support:
            continue
        home = support[a.args[0]]
        while home not in furniture and home in support:
            home = support[home]
        alt = by_key.get(("place_above", (a.args[0], home)))
        if home in furniture and alt is not None and alt != a and valid(problem, plan[:k] + [alt] + plan[k + 1 :]):
            plan[k] = alt
    for k in range(len(plan) - 1):
        a, b = plan[k], plan[k + 1]
        if a.name == "hold_above" and b.name == "drop" and ("receives-inside", a.args[1]) not in problem.statics:
            swap = [by_key.get(("place_above", a.args)), by_key.get(("release", a.args[:1]))]
            if None not in swap and valid(problem, plan[:k] + swap + plan[k + 2 :]):
                plan[k : k + 2] = swap
        if a.name == "place_above" and b.name == "release" and ("receives-inside", a.args[1]) in problem.statics:
            swap = [by_key.get(("hold_above", a.args)), by_key.get(("drop", a.args))]
            if None not in swap and valid(problem, plan[:k] + swap + plan[k + 2 :]):
                plan[k : k + 2] = swap
    for k in range(len(plan) - 1):
        if plan[k].name != "move_close":
            continue
        nxt = plan[k + 1]
        target = nxt.args[1] if nxt.name in ("place_above", "hold_above") else nxt.args[0]
        targets = [target]
        while nxt.name == "grasp" and support.get(targets[0]) not in (None, *furniture):
            targets.insert(0, support[targets[0]])  # clearing a stack: go to the object under it
        for t in targets:
            alt = by_key.get(("move_close", (t,)))
            if alt is not None and (alt == plan[k] or valid(problem, plan[:k] + [alt] + plan[k + 1 :])):
                plan[k] = alt
                break
    return plan
