"""The symbolic baselines: PDDL files, SAT plans (shortest, executable), role rankers."""

from collections import deque
from dataclasses import replace

import pytest
from pddl import parse_domain, parse_problem

from taskseq.demonstrations.benchmark import Benchmark
from taskseq.evaluate.methods import SymbolicMethod
from taskseq.plan.planner import run_loop
from taskseq.plan.symbolic.executor import SymbolicPolicy
from taskseq.plan.symbolic.files import file_stem, write_pddl
from taskseq.plan.symbolic.problem import build_problem, ground_actions
from taskseq.plan.symbolic.roles import demonstrated_roles
from taskseq.plan.symbolic.sat import apply, solve
from taskseq.sim.primitives import execute
from taskseq.sim.tasks import Task, goal_reached
from tests.conftest import world


@pytest.fixture(scope="module")
def scenarios(benchmark_tables):
    return Benchmark.from_records([i.record for i in benchmark_tables[1]]).scenarios


def test_pddl_files_parse_with_a_standard_parser(scenarios, tmp_path):
    some = dict(sorted(scenarios.items())[::15])
    counts = write_pddl(some, tmp_path / "pddl")
    assert counts["problems"] == len(some) == counts["plans"]
    domain = parse_domain(tmp_path / "pddl" / "domain.pddl")
    assert {a.name for a in domain.actions} == {
        "move_close", "grasp", "place_above", "release", "hold_above", "drop", "follow_traj_circle",
        "follow_traj_pour",
    }
    for sid in some:
        problem = parse_problem(tmp_path / "pddl" / "problems" / f"{file_stem(sid)}.pddl")
        assert problem.domain_name == "kitchen" and problem.goal is not None
        plan = (tmp_path / "pddl" / "plans" / f"{file_stem(sid)}.plan").read_text().splitlines()
        assert plan[-1].startswith(";") and all(line.startswith("(") for line in plan[:-1])


def test_every_benchmark_plan_executes_in_the_simulator(scenarios):
    for sc in scenarios.values():
        problem = build_problem("p", sc.initial, sc.task, demonstrated_roles(sc.task, sc.demonstrations[0]))
        result = solve(problem)
        assert result.found, sc.id
        state = sc.initial
        for action in result.plan:
            state = execute(state, action.primitive())
        assert goal_reached(sc.task, sc.initial, state), sc.id


def bfs_length(problem, limit=8):
    actions = ground_actions(problem)
    start = frozenset(problem.init)
    seen, queue = {start}, deque([(start, 0)])
    while queue:
        state, depth = queue.popleft()
        if problem.goal <= state:
            return depth
        if depth == limit:
            continue
        for a in actions:
            nxt = apply(state, a)
            if nxt is not None and nxt not in seen:
                seen.add(nxt)
                queue.append((nxt, depth + 1))
    return None


SMALL = [
    ({2: 0.0}, [(14, 2, 0, 0.3), (20, 2, 0, -0.3), (27, 20)], Task("pour_to", ("obj27", "obj14")), {}),
    ({2: 0.0, 4: 1.9}, [(40, 2, 0, 0.0), (43, 40)], Task("pick_and_place", ("obj40", "obj04")), {}),
    ({2: 0.0, 10: -1.4}, [(43, 2, 0, 0.3)], Task("throw_away", ("obj43",)), {"bin": "obj10"}),
    ({2: 0.0}, [(13, 2, 0, 0.3), (31, 13), (34, 2, 0, -0.2)], Task("stir", ("obj31",)), {"stirrer": "obj34"}),
]


@pytest.mark.parametrize("case", range(len(SMALL)))
def test_sat_plans_are_as_short_as_breadth_first_search(case):
    furniture, items, task, roles = SMALL[case]
    state = world(furniture, items)
    problem = build_problem("small", state, task, roles)
    result = solve(problem, horizon=8)
    assert result.found
    assert len(result.plan) == bfs_length(problem)
    program = run_loop(SymbolicPolicy(task, roles), state, task)
    assert program.status == "done" and program.goal_reached


def test_an_unreachable_goal_says_so_within_the_horizon():
    state = world({2: 0.0}, [(20, 2, 0, -0.3), (27, 20), (34, 2, 0, 0.2)])
    task = Task("pour_to", ("obj27", "obj34"))  # a spoon holds no liquid
    result = solve(build_problem("p", state, task, {}), horizon=6)
    assert not result.found and result.message() == "no plan within horizon 6"
    program = run_loop(SymbolicPolicy(task, {}, horizon=6), state, task)
    assert program.status == "infeasible" and program.error == "no plan within horizon 6"
    assert program.steps == []


@pytest.fixture(scope="module")
def svm_method(benchmark_steps, scenarios):
    contexts, meta = benchmark_steps
    return SymbolicMethod(goals="svm", name="symb_plan_svm").fit(contexts, meta, scenarios)


def test_rankers_pick_the_bin_the_vessel_and_the_stirrer(svm_method):
    # a trash can, a bucket-like pot, a cup, a bottle of water, a mug of tea, a teaspoon, a book, tables
    state = world({2: 0.0, 10: -1.4, 4: 2.0},
                  [(18, 2, 0, -0.5), (14, 2, 0, 0.5), (20, 2, 0, -0.2), (27, 20), (39, 4, 0, 0.2),
                   (13, 4, 0, -0.2), (31, 13), (34, 2, 0, 0.2), (43, 4, 0, 0.0)])
    assert svm_method.roles(Task("throw_away", ("obj43",)), state, ())["bin"] == "obj10"
    assert svm_method.roles(Task("stir", ("obj31",)), state, ())["stirrer"] == "obj34"
    vessel = svm_method.roles(Task("pour", ("obj27",)), state, ())["vessel"]
    assert vessel in ("obj14", "obj18")  # an empty vessel, not the bottle, the mug of tea or a table


def test_the_symbolic_policy_replans_when_its_next_step_cannot_run(monkeypatch):
    """A plan whose next step no longer fits the world is dropped for a fresh one from where the robot is."""
    from taskseq.plan.symbolic import executor

    furniture, items, task, roles = SMALL[0]
    state = world(furniture, items)
    real = executor.plan_from
    calls = []

    def stale_first(now, task_, roles_, horizon):
        calls.append(now)
        result = real(now, task_, roles_, horizon)
        if len(calls) == 1:  # the first plan starts with a grasp the robot cannot make from afar
            grasp = next(a for a in result.plan if a.name == "grasp")
            return replace(result, plan=[grasp, *result.plan])
        return result

    monkeypatch.setattr(executor, "plan_from", stale_first)
    policy = SymbolicPolicy(task, roles)
    program = run_loop(policy, state, task)
    assert policy.replans == 1 and len(calls) == 2
    assert program.status == "done" and program.goal_reached
    assert program.actions == [a.primitive() for a in real(state, task, roles, 12).plan]


def test_the_symbolic_policy_gives_up_on_a_step_after_its_replans(monkeypatch):
    from taskseq.plan.symbolic import executor

    furniture, items, task, roles = SMALL[0]
    state = world(furniture, items)
    real = executor.plan_from

    def always_stale(now, task_, roles_, horizon):
        result = real(now, task_, roles_, horizon)
        grasp = next(a for a in result.plan if a.name == "grasp")
        return replace(result, plan=[grasp, *result.plan])

    monkeypatch.setattr(executor, "plan_from", always_stale)
    policy = SymbolicPolicy(task, roles)
    program = run_loop(policy, state, task)
    assert policy.replans == executor.MAX_REPLANS
    assert program.status == "infeasible" and len(program.steps) == 1 and program.steps[0].action.primitive == "grasp"
    assert len(program.states) == 1 and program.error


def _clauses_step_by_step(problem, actions, fluents, horizon):
    """The encoding written out one step at a time, as the module docstring states it."""
    from pysat.card import CardEnc, EncType

    F, A = len(fluents), len(actions)
    fv = {(f, t): 1 + t * F + k for t in range(horizon + 1) for k, f in enumerate(fluents)}
    av = {(i, t): 1 + (horizon + 1) * F + t * A + i for t in range(horizon) for i in range(A)}
    act = {t: 1 + (horizon + 1) * F + horizon * A + t for t in range(horizon)}
    top = (horizon + 1) * F + horizon * A + horizon
    out = [[fv[(f, 0)] if f in problem.init else -fv[(f, 0)]] for f in fluents]
    adders = {f: [i for i, a in enumerate(actions) if f in a.add] for f in fluents}
    deleters = {f: [i for i, a in enumerate(actions) if f in a.delete - a.add] for f in fluents}
    for t in range(horizon):
        lits = [av[(i, t)] for i in range(A)]
        for i, a in enumerate(actions):
            x = av[(i, t)]
            out += [[-x, fv[(f, t)]] for f in sorted(a.pre)] + [[-x, -fv[(f, t)]] for f in sorted(a.pre_not)]
            out += [[-x, fv[(f, t + 1)]] for f in sorted(a.add)]
            out += [[-x, -fv[(f, t + 1)]] for f in sorted(a.delete - a.add)] + [[-x, act[t]]]
        out.append([-act[t], *lits])
        card = CardEnc.atmost(lits=lits, bound=1, top_id=top, encoding=EncType.seqcounter)
        top = max(top, card.nv)
        out += card.clauses
        if t + 1 < horizon:
            out.append([-act[t + 1], act[t]])
        for f in fluents:
            out.append([-fv[(f, t)], fv[(f, t + 1)], *(av[(i, t)] for i in deleters[f])])
            out.append([fv[(f, t)], -fv[(f, t + 1)], *(av[(i, t)] for i in adders[f])])
    return out + [[fv[(g, horizon)]] for g in sorted(problem.goal)]


@pytest.mark.parametrize("horizon", [0, 1, 2, 5, 12])
def test_the_shifted_encoding_is_the_step_by_step_one_clause_for_clause(scenarios, horizon):
    from taskseq.plan.symbolic.sat import encode

    for sc in list(scenarios.values())[::20]:
        problem = build_problem("p", sc.initial, sc.task, demonstrated_roles(sc.task, sc.demonstrations[0]))
        actions = ground_actions(problem)
        fluents = sorted({f for a in actions for f in a.pre | a.pre_not | a.add | a.delete} | problem.goal)
        clauses, av, act = encode(problem, actions, fluents, horizon)
        assert clauses == _clauses_step_by_step(problem, actions, fluents, horizon), sc.id  # the order steers SAT
        if horizon:
            assert av(0, 0) == 1 + (horizon + 1) * len(fluents) and act(horizon - 1) == av(len(actions) - 1,
                                                                                            horizon - 1) + horizon


def test_a_kept_plan_is_the_one_a_fresh_solve_finds_and_a_copy(scenarios, monkeypatch):
    from taskseq.plan.symbolic import sat

    sc = next(iter(scenarios.values()))
    problem = build_problem("p", sc.initial, sc.task, demonstrated_roles(sc.task, sc.demonstrations[0]))
    monkeypatch.setattr(sat, "_SOLVED", type(sat._SOLVED)())
    first = solve(problem)
    solves = []
    monkeypatch.setattr(sat, "_solve", lambda *a: solves.append(a))
    again = solve(replace(problem, name="same content, another name"))
    assert not solves and again == first and again.plan is not first.plan
    again.plan.clear()  # a caller's changes never reach what is kept
    assert solve(problem).plan == first.plan != []


def _fresh(monkeypatch):
    """No plan kept in this process: every solve goes to the cache or the solver."""
    from taskseq.plan.symbolic import sat

    monkeypatch.setattr(sat, "_SOLVED", type(sat._SOLVED)())
    solves = []
    real = sat._solve
    monkeypatch.setattr(sat, "_solve", lambda *a: solves.append(a) or real(*a))
    return solves


def test_a_stored_plan_is_read_back_instead_of_solved_and_is_the_same(scenarios, monkeypatch, tmp_path):
    from taskseq.runtime.cache import folder, stored_only

    sc = next(iter(scenarios.values()))
    problem = build_problem("p", sc.initial, sc.task, demonstrated_roles(sc.task, sc.demonstrations[0]))
    none_within = replace(problem, goal={("in", problem.objects[0], problem.objects[0])})  # a goal no action adds
    entries = tmp_path / "cache" / "plans"
    with folder(tmp_path / "cache"):
        solves = _fresh(monkeypatch)
        first, nothing = solve(problem), solve(none_within, horizon=2)
        assert len(solves) == 2 and first.plan and nothing.plan is None
        assert len(list(entries.glob("??/*.json"))) == 2
        solves = _fresh(monkeypatch)
        again, still_nothing = solve(problem), solve(none_within, horizon=2)
        assert not solves and again == first and still_nothing == nothing  # read back, the same ground actions
        solves = _fresh(monkeypatch)
        with stored_only():  # a plan is never work to send elsewhere: a miss is solved here, not NotStored
            other = solve(replace(problem, init=problem.init | {("stirred", "x", "y")}))
            assert solve(problem) == first
        assert len(solves) == 1 and other.plan is not None and len(list(entries.glob("??/*.json"))) == 3
    solves = _fresh(monkeypatch)
    assert solve(problem) == first  # no cache in force: solved, nothing stored
    assert len(solves) == 1 and len(list(entries.glob("??/*.json"))) == 3


@pytest.mark.parametrize("damage", ["{not json", '{"format": "other", "plan": null, "n_actions": 0}',
                                    '{"format": "taskseq.plans/1", "plan": [["fly", ["obj1"]]], "n_actions": 1}'])
def test_an_unreadable_stored_plan_is_solved_again_and_replaced(scenarios, monkeypatch, tmp_path, damage):
    from taskseq.runtime.cache import folder

    sc = next(iter(scenarios.values()))
    problem = build_problem("p", sc.initial, sc.task, demonstrated_roles(sc.task, sc.demonstrations[0]))
    with folder(tmp_path / "cache"):
        _fresh(monkeypatch)
        first = solve(problem)
        entry, = (tmp_path / "cache" / "plans").glob("??/*.json")
        entry.write_text(damage)
        solves = _fresh(monkeypatch)
        with pytest.warns(UserWarning, match="solved again"):
            again = solve(problem)
        assert len(solves) == 1 and again == first
        assert '"taskseq.plans/1"' in entry.read_text() and "fly" not in entry.read_text()


@pytest.mark.parametrize("change", ["statics", "object order", "horizon", "solver", "planner's code"])
def test_whatever_decides_a_plan_is_in_its_key(scenarios, monkeypatch, change):
    from taskseq.plan.symbolic import stored_plans
    from taskseq.plan.symbolic.stored_plans import plan_key

    sc = next(iter(scenarios.values()))
    problem = build_problem("p", sc.initial, sc.task, demonstrated_roles(sc.task, sc.demonstrations[0]))
    key = plan_key(problem, 12, "g4")
    assert plan_key(replace(problem, name="another name"), 12, "g4") == key  # the name decides nothing
    other = {"statics": lambda: plan_key(replace(problem, statics=problem.statics - {min(problem.statics)}), 12, "g4"),
             "object order": lambda: plan_key(replace(problem, objects=problem.objects[::-1]), 12, "g4"),
             "horizon": lambda: plan_key(problem, 11, "g4"),
             "solver": lambda: plan_key(problem, 12, "m22")}
    if change == "planner's code":
        monkeypatch.setattr(stored_plans, "code_fingerprint", lambda module: "other code")
        assert plan_key(problem, 12, "g4") != key
    else:
        assert other[change]() != key


def test_a_stored_plan_is_never_served_to_a_shorter_horizon(scenarios, monkeypatch, tmp_path):
    from taskseq.runtime.cache import folder

    sc = next(iter(scenarios.values()))
    problem = build_problem("p", sc.initial, sc.task, demonstrated_roles(sc.task, sc.demonstrations[0]))
    with folder(tmp_path / "cache"):
        _fresh(monkeypatch)
        k = len(solve(problem).plan)
        _fresh(monkeypatch)
        assert solve(problem, horizon=k - 1).plan is None and len(solve(problem, horizon=k).plan) == k
