"""The planner's hand-grounded actions are the actions of domain.pddl, on every benchmark problem.

`problem.ground_actions` instantiates the domain by hand (fast, and in the
order the SAT encoding numbers its variables). Here an independent grounder
reads domain.pddl with the `pddl` parser and instantiates every action schema
over a problem's objects by the standard semantics: static predicates (those
no action changes) are evaluated against the problem's facts, universal
conditions and effects are expanded, conditional effects whose condition is
static are resolved, and an atom both deleted and added ends up added. Every
hand-grounded action must equal the PDDL action of the same name and
arguments, and every PDDL action the hand grounder leaves out must be one
that can never run.
"""

from __future__ import annotations

import itertools

import pytest
from pddl import parse_domain
from pddl.logic.base import And, ForallCondition, Not
from pddl.logic.effects import Forall, When
from pddl.logic.predicates import Predicate

from taskseq.demonstrations.benchmark import Benchmark
from taskseq.plan.symbolic.problem import DOMAIN_PATH, GroundAction, Problem, build_problem, ground_actions
from taskseq.plan.symbolic.roles import demonstrated_roles
from taskseq.sim.primitives import PreconditionError, execute

DOMAIN = parse_domain(DOMAIN_PATH)


def _effect_predicates(effect) -> set[str]:
    if isinstance(effect, Predicate):
        return {effect.name}
    if isinstance(effect, Not):
        return _effect_predicates(effect.argument)
    if isinstance(effect, And):
        return set().union(*(_effect_predicates(e) for e in effect.operands))
    if isinstance(effect, Forall | When):
        return _effect_predicates(effect.effect)
    raise TypeError(f"effect {effect!r} is outside the subset the domain uses")


FLUENTS = set().union(*(_effect_predicates(a.effect) for a in DOMAIN.actions))


class Grounding:
    """One action schema under one binding of its variables, over one problem."""

    def __init__(self, problem: Problem) -> None:
        self.problem = problem
        self.pre: set[tuple] = set()
        self.pre_not: set[tuple] = set()
        self.add: set[tuple] = set()
        self.delete: set[tuple] = set()

    def atom(self, p: Predicate, env: dict[str, str]) -> tuple[str, ...]:
        return (p.name, *(env[str(t.name)] for t in p.terms))

    def holds(self, formula, env: dict[str, str]) -> bool:
        """Collect the fluent preconditions; False as soon as a static one fails."""
        if isinstance(formula, Predicate):
            atom = self.atom(formula, env)
            if formula.name in FLUENTS:
                self.pre.add(atom)
                return True
            return atom in self.problem.statics
        if isinstance(formula, Not):
            inner = formula.argument
            if not isinstance(inner, Predicate):
                raise TypeError(f"negation of {inner!r} is outside the subset the domain uses")
            atom = self.atom(inner, env)
            if inner.name in FLUENTS:
                self.pre_not.add(atom)
                return True
            return atom not in self.problem.statics
        if isinstance(formula, And):
            return all(self.holds(f, env) for f in formula.operands)
        if isinstance(formula, ForallCondition):
            return all(self.holds(formula.condition, {**env, **b}) for b in self.bindings(formula.variables))
        raise TypeError(f"condition {formula!r} is outside the subset the domain uses")

    def static(self, formula, env: dict[str, str]) -> bool:
        """The truth of a condition over static predicates only (those of the domain's `when`s)."""
        probe = Grounding(self.problem)
        value = probe.holds(formula, env)
        if probe.pre or probe.pre_not:
            raise TypeError(f"condition {formula!r} reads a fluent: the grounder resolves static ones only")
        return value

    def apply(self, effect, env: dict[str, str]) -> None:
        if isinstance(effect, Predicate):
            self.add.add(self.atom(effect, env))
        elif isinstance(effect, Not):
            self.delete.add(self.atom(effect.argument, env))
        elif isinstance(effect, And):
            for e in effect.operands:
                self.apply(e, env)
        elif isinstance(effect, Forall):
            for b in self.bindings(effect.variables):
                self.apply(effect.effect, {**env, **b})
        elif isinstance(effect, When):
            if self.static(effect.condition, env):
                self.apply(effect.effect, env)
        else:
            raise TypeError(f"effect {effect!r} is outside the subset the domain uses")

    def bindings(self, variables) -> list[dict[str, str]]:
        names = sorted(str(v.name) for v in variables)
        return [dict(zip(names, objs, strict=True))
                for objs in itertools.product(self.problem.objects, repeat=len(names))]


def pddl_actions(problem: Problem) -> dict[tuple[str, tuple[str, ...]], GroundAction]:
    """Every action of domain.pddl over the problem's objects whose static preconditions hold."""
    out = {}
    for schema in DOMAIN.actions:
        names = [str(v.name) for v in schema.parameters]
        for objs in itertools.product(problem.objects, repeat=len(names)):
            env = dict(zip(names, objs, strict=True))
            g = Grounding(problem)
            if not g.holds(schema.precondition, env):
                continue
            g.apply(schema.effect, env)
            out[(schema.name, objs)] = GroundAction(schema.name, objs, frozenset(g.pre), frozenset(g.pre_not),
                                                    frozenset(g.add), frozenset(g.delete - g.add))
    return out


def normalised(a: GroundAction) -> GroundAction:
    """An atom both deleted and added ends up added (PDDL applies deletes first)."""
    return GroundAction(a.name, a.args, a.pre, a.pre_not, a.add, a.delete - a.add)


def never_runs(a: GroundAction, problem: Problem) -> str | None:
    """Why a PDDL action the hand grounder leaves out can never run in the problem, or None."""
    if len(set(a.args)) < len(a.args):
        return "the same object twice"  # the simulator has no step with one object in two roles
    held = [atom[1] for atom in a.pre if atom[0] == "holding"]
    if any(("movable", o) not in problem.statics and ("holding", o) not in problem.init for o in held):
        return "holds an object that cannot be grasped"  # only grasp makes `holding`, and it needs `movable`
    inside = [atom for atom in a.pre if atom[0] == "in"]
    if any(("container", atom[2]) not in problem.statics and ("receives-inside", atom[2]) not in problem.statics
           for atom in inside):
        return "needs something inside an object that holds nothing"
    return None


@pytest.fixture(scope="module")
def problems(benchmark_tables) -> list[Problem]:
    """The problem of every scenario's first state, and of every state along its first demonstration."""
    bench = Benchmark.from_records([i.record for i in benchmark_tables[1]])
    out = []
    for sid, sc in sorted(bench.scenarios.items()):
        roles = demonstrated_roles(sc.task, sc.demonstrations[0])
        state = sc.initial
        for k, action in enumerate((*sc.demonstrations[0], None)):
            out.append(build_problem(f"{sid}-{k}", state, sc.task, roles))
            if action is None:
                break
            try:
                state = execute(state, action)
            except PreconditionError:
                break
    return out


def test_the_grounder_reads_every_action_of_the_domain():
    assert {a.name for a in DOMAIN.actions} == {"move_close", "grasp", "place_above", "release", "hold_above",
                                                 "drop", "follow_traj_circle", "follow_traj_pour"}
    assert {"near", "hand-empty", "holding", "anchored", "on", "in", "above", "stirred"} == FLUENTS


def test_every_hand_grounded_action_is_the_pddl_action_it_stands_for(problems):
    assert len(problems) > 500
    compared = 0
    for problem in problems:
        reference = pddl_actions(problem)
        hand = ground_actions(problem)
        assert len({(a.name, a.args) for a in hand}) == len(hand), problem.name  # no action twice
        for a in hand:
            key = (a.name, a.args)
            assert key in reference, f"{problem.name}: {a.pddl()} is not an action of domain.pddl"
            assert normalised(a) == reference[key], f"{problem.name}: {a.pddl()} differs from domain.pddl"
            compared += 1
        left_out = [b for key, b in reference.items() if key not in {(a.name, a.args) for a in hand}]
        unexplained = [b.pddl() for b in left_out if never_runs(b, problem) is None]
        assert not unexplained, f"{problem.name}: the planner lacks {unexplained[:5]}"
    assert compared > 10_000


def test_the_check_catches_an_action_that_differs_from_the_domain(problems):
    problem = problems[0]
    reference = pddl_actions(problem)
    grasp = next(a for a in ground_actions(problem) if a.name == "grasp")
    wrong = GroundAction(grasp.name, grasp.args, grasp.pre - {("hand-empty",)}, grasp.pre_not, grasp.add,
                         grasp.delete)
    assert normalised(grasp) == reference[(grasp.name, grasp.args)]
    assert normalised(wrong) != reference[(grasp.name, grasp.args)]
