"""Planning as satisfiability (Kautz and Selman): the shortest plan by incremental SAT.

One variable per ground action and per fluent at each time step; actions
imply their preconditions and effects; explanatory frame axioms say a fluent
changes only through an action that adds or deletes it; at most one action per
step (a sequential counter), and no empty step before an action. The goal holds
at the horizon H; assuming "no action at step k" bounds the plan to k steps,
so trying k = 0, 1, ..., H on one incremental solver finds the shortest plan.
"""

from __future__ import annotations

from dataclasses import dataclass
from itertools import count

from pysat.card import CardEnc, EncType
from pysat.solvers import Solver

from .problem import Atom, GroundAction, Problem, ground_actions


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


def solve(problem: Problem, horizon: int = 12, solver: str = "g4") -> PlanResult:
    actions = ground_actions(problem)
    fluents = sorted({f for a in actions for f in a.pre | a.pre_not | a.add | a.delete} | problem.goal)
    if not problem.goal <= set(fluents) | problem.init:
        return PlanResult(None, horizon, len(actions))
    ids = count(1)
    fv = {(f, t): next(ids) for t in range(horizon + 1) for f in fluents}
    av = {(i, t): next(ids) for t in range(horizon) for i in range(len(actions))}
    act = {t: next(ids) for t in range(horizon)}  # some action happens at step t
    top = next(ids) - 1
    clauses: list[list[int]] = []
    for f in fluents:
        clauses.append([fv[(f, 0)] if f in problem.init else -fv[(f, 0)]])
    adders: dict[Atom, list[int]] = {f: [] for f in fluents}
    deleters: dict[Atom, list[int]] = {f: [] for f in fluents}
    # every set is walked in sorted order: clause order steers the solver, and set order
    # changes with Python's per-process string hashing
    for i, a in enumerate(actions):
        for f in sorted(a.add):
            adders[f].append(i)
        for f in sorted(a.delete - a.add):
            deleters[f].append(i)
    for t in range(horizon):
        lits = [av[(i, t)] for i in range(len(actions))]
        for i, a in enumerate(actions):
            x = av[(i, t)]
            clauses += [[-x, fv[(f, t)]] for f in sorted(a.pre)]
            clauses += [[-x, -fv[(f, t)]] for f in sorted(a.pre_not)]
            clauses += [[-x, fv[(f, t + 1)]] for f in sorted(a.add)]
            clauses += [[-x, -fv[(f, t + 1)]] for f in sorted(a.delete - a.add)]
            clauses.append([-x, act[t]])
        clauses.append([-act[t], *lits])
        card = CardEnc.atmost(lits=lits, bound=1, top_id=top, encoding=EncType.seqcounter)
        top = max(top, card.nv)
        clauses += card.clauses
        if t + 1 < horizon:
            clauses.append([-act[t + 1], act[t]])
        for f in fluents:
            clauses.append([-fv[(f, t)], fv[(f, t + 1)], *(av[(i, t)] for i in deleters[f])])
            clauses.append([fv[(f, t)], -fv[(f, t + 1)], *(av[(i, t)] for i in adders[f])])
    clauses += [[fv[(g, horizon)]] for g in sorted(problem.goal)]
    with Solver(name=solver, bootstrap_with=clauses) as sat:
        for k in range(horizon + 1):
            assumptions = [-act[k]] if k < horizon else []
            if sat.solve(assumptions=assumptions):
                model = {v for v in sat.get_model() if v > 0}
                chosen = [actions[i] for t in range(k) for i in range(len(actions)) if av[(i, t)] in model]
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
