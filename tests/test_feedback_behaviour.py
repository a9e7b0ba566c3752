"""An observer's feedback, end to end: the planner executes what the observer picks, and the feedback rows count it.

The planner here is scripted (it prefers to stop at once and offers the demonstrated step second), so the
effect of every pick is known in advance and no model has to be trained.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from taskseq.experiments.crossval import judge
from taskseq.experiments.robustness import (
    FeedbackCondition,
    NoiseCondition,
    _replay,
    evaluate_conditions,
    feedback_rows,
    observer,
)
from taskseq.features.context import step_context
from taskseq.features.perception import BINARY_COLUMNS
from taskseq.plan.planner import DONE, plan
from taskseq.settings import Feedback, Folds
from taskseq.sim.primitives import Action
from taskseq.sim.scenarios import Scenario
from taskseq.sim.tasks import Task
from tests.conftest import world

TABLE, TRASH, CUP, MUG = "obj02", "obj10", "obj14", "obj13"
DEMO = tuple(Action.parse(t) for t in (f"move_close({CUP})", f"grasp({CUP})", f"move_close({TRASH})",
                                      f"hold_above({CUP},{TRASH})", f"release({CUP})"))


def demonstrated(ctx) -> int:
    """The demonstration's steps taken before this one, as the step's context remembers them: a planner is a
    function of the step (programs that share their first steps share them in the rollout loop)."""
    last = ctx.history()[-1:]
    return DEMO.index(last[0]) + 1 if last and last[0] in DEMO else 0


class ScriptedPlanner:
    """Ranks, at step t: `done` first, the demonstration's step t second, a detour to the mug third."""

    def ranked(self, ctx):  # the whole ranking, which a policy walking down it reads
        return iter(self.top_k(ctx, 1_000_000))

    def top_k(self, ctx, k: int):
        t = demonstrated(ctx)
        ranked = [Action("done")] + ([DEMO[t]] if t < len(DEMO) else []) + [Action.parse(f"move_close({MUG})")]
        return [(ctx.encode(a), float(-i)) for i, a in enumerate(ranked)][:k]


@pytest.fixture
def scenario() -> Scenario:
    state = world({2: 0.0, 10: -1.2, 8: 2.2}, [(14, 2, 0, 0.4), (13, 8, 1, 0.0)])
    return Scenario("envX", Task("throw_away", (CUP,)), state, (DEMO,))


def test_without_feedback_the_robot_takes_its_own_best(scenario):
    program = plan(ScriptedPlanner(), scenario.initial, scenario.task, top_k=3)
    assert program.actions == [] and program.status == DONE


@pytest.mark.parametrize("n", [1, 2, 4])
def test_the_planner_executes_the_observers_pick_at_the_first_n_steps(scenario, n):
    program = plan(ScriptedPlanner(), scenario.initial, scenario.task, top_k=3,
                   choose=observer(scenario.demonstrations, n))
    assert program.actions == list(DEMO[:n])  # the observer's picks, then the robot's own `done`
    assert judge(scenario, program).failure == "stopped_early"


def test_feedback_at_every_step_where_the_demonstration_is_offered_gives_the_demonstration(scenario):
    program = plan(ScriptedPlanner(), scenario.initial, scenario.task, top_k=2,
                   choose=observer(scenario.demonstrations, 20))
    assert program.actions == list(DEMO) and program.success
    outcome = judge(scenario, program)
    assert outcome.arg_correct and outcome.failure == "exact"


def test_feedback_changes_nothing_when_the_demonstration_is_not_among_the_top_k(scenario):
    program = plan(ScriptedPlanner(), scenario.initial, scenario.task, top_k=1,
                   choose=observer(scenario.demonstrations, 20))
    assert program.actions == []


def test_the_observer_picks_done_where_the_demonstration_ends(scenario):
    offered = [Action.parse(f"move_close({MUG})"), Action("done")]
    assert observer(scenario.demonstrations, 20)(list(DEMO), offered) == 1
    assert observer(scenario.demonstrations, 20)(list(DEMO[:2]), offered) == 0  # nothing right on offer


def test_the_observer_only_follows_a_demonstration_the_history_agrees_with():
    first = (Action.parse("move_close(obj1)"), Action.parse("grasp(obj1)"))
    second = (Action.parse("move_close(obj2)"), Action.parse("grasp(obj2)"))
    choose = observer((first, second), 5)
    offered = [Action.parse("grasp(obj1)"), Action.parse("grasp(obj2)")]
    assert choose([second[0]], offered) == 1 and choose([first[0]], offered) == 0


class ScriptedMethod:
    """What `_replay` trains per fold, with the scripted planner (fresh for every program)."""

    policy = "greedy"

    @property
    def planner_(self) -> ScriptedPlanner:
        return ScriptedPlanner()

    def fit(self, contexts, meta, scenarios=None) -> ScriptedMethod:
        return self


class GraspMugFirst:
    """Offers a grasp of the mug, out of reach (it cannot run), before the demonstration's step t."""

    def ranked(self, ctx):  # the whole ranking, which a policy walking down it reads
        return iter(self.top_k(ctx, 1_000_000))

    def top_k(self, ctx, k: int):
        t = demonstrated(ctx)
        ranked = [Action.parse(f"grasp({MUG})"), DEMO[t] if t < len(DEMO) else Action("done")]
        return [(ctx.encode(a), float(-i)) for i, a in enumerate(ranked)][:k]


@pytest.mark.parametrize(("policy", "status", "actions"), [("greedy", "infeasible", [f"grasp({MUG})"]),
                                                           ("feasible", DONE, [str(a) for a in DEMO])])
def test_noise_and_feedback_runs_pick_steps_with_the_methods_policy(scenario, policy, status, actions):
    method = type("Method", (ScriptedMethod,), {"policy": policy, "planner_": property(lambda self: GraspMugFirst())})
    for condition in (NoiseCondition(0.0, 0), FeedbackCondition(2, 0)):
        [(_, outcome)] = _replay(method, [], [], {scenario.id: scenario}, {scenario.id}, [condition], 20, 0)
        assert (outcome.status, list(outcome.actions)) == (status, actions)


def test_feedback_rows_count_the_programs_the_observer_corrected(scenario):
    conditions = [FeedbackCondition(k, n) for k in (1, 2) for n in (0, 2, 20)]
    results = _replay(ScriptedMethod, [], [], {scenario.id: scenario}, {scenario.id}, conditions, 20, 0)
    rows = feedback_rows(Feedback(k=(1, 2), n=("0", "2", "all")), 20, results)
    arg = {(r["k"], r["n"]): r["sequence_arg"] for r in rows}
    assert arg == {(1, "0"): 0.0, (1, "2"): 0.0, (1, "all"): 0.0, (2, "0"): 0.0, (2, "2"): 0.0, (2, "all"): 100.0}
    success = {(r["k"], r["n"]): r["success"] for r in rows}
    assert success[(2, "all")] == 100.0 and success[(2, "2")] == 0.0



class ListPolicy:
    """A policy that offers, at step t, the actions of `script[t]` in that order (scores 0, -1, ...)."""

    def __init__(self, script) -> None:
        self.script, self.seen, self.states = script, [], []

    def __call__(self, ctx, state):
        self.seen.append(ctx)
        self.states.append(state)
        step = self.script[min(len(self.seen) - 1, len(self.script) - 1)]
        return [(ctx.encode(Action.parse(a)), float(-i)) for i, a in enumerate(step)]


def test_a_program_records_each_step_its_alternatives_and_every_state(scenario):
    from taskseq.plan.planner import run_loop

    policy = ListPolicy([[str(DEMO[0]), f"move_close({MUG})"], [str(DEMO[1]), "done"], ["done"]])
    program = run_loop(policy, scenario.initial, scenario.task)
    assert program.status == DONE and program.actions == list(DEMO[:2]) and program.error is None
    assert [s.score for s in program.steps] == [0.0, 0.0]
    assert program.steps[0].alternatives == [(Action.parse(f"move_close({MUG})"), -1.0)]
    assert program.steps[1].alternatives == [(Action("done"), -1.0)]
    assert len(program.states) == 3 and program.initial is scenario.initial
    assert program.final.held == CUP and program.states[1].held is None
    assert not program.goal_reached and program.safe and not program.success
    assert policy.states == program.states  # the policy ranks each step from the world as it is then


def test_the_loop_stops_at_the_step_cap(scenario):
    from taskseq.plan.planner import STEP_CAP, run_loop

    back_and_forth = ListPolicy([[f"move_close({MUG})"], [f"move_close({CUP})"]] * 5)
    program = run_loop(back_and_forth, scenario.initial, scenario.task, max_steps=3)
    assert program.status == STEP_CAP and len(program.actions) == 3 and len(program.states) == 4
    assert len(back_and_forth.seen) == 4  # the fourth step was ranked, then refused by the cap
    assert not program.success


def test_an_infeasible_step_ends_the_program_with_the_reason(scenario):
    from taskseq.plan.planner import INFEASIBLE, run_loop

    program = run_loop(ListPolicy([[f"grasp({CUP})"]]), scenario.initial, scenario.task)
    assert program.status == INFEASIBLE and program.actions == [Action.parse(f"grasp({CUP})")]
    assert len(program.states) == 1 and program.final is scenario.initial  # the step changed nothing
    assert program.task == scenario.task and not program.goal_reached
    assert program.error == f"grasp({CUP}): precondition 'within reach' failed: {CUP} is 1.62 m from the robot"


def test_a_policy_that_abstains_ends_the_program_infeasible(scenario):
    from taskseq.plan.planner import INFEASIBLE, Abstain, run_loop

    def abstain(ctx, state):
        raise Abstain("no plan within 4 steps")

    program = run_loop(abstain, scenario.initial, scenario.task)
    assert (program.status, program.steps, program.error) == (INFEASIBLE, [], "no plan within 4 steps")
    assert program.task == scenario.task and program.states == [scenario.initial]


def test_an_abstention_read_back_from_the_memo_ends_the_program_with_its_reason(scenario):
    from taskseq.plan.planner import INFEASIBLE, Abstain, Memo, run_loop

    calls = []

    def abstain(ctx, state):
        calls.append(ctx)
        raise Abstain("no plan within 4 steps")

    memo = Memo()
    first, second = (run_loop(abstain, scenario.initial, scenario.task, memo=memo) for _ in range(2))
    assert len(calls) == 1  # the second program read the abstention back
    for program in (first, second):
        assert (program.status, program.steps, program.error) == (INFEASIBLE, [], "no plan within 4 steps")


def test_an_unsafe_step_is_recorded_and_fails_the_program():
    from taskseq.plan.planner import run_loop

    state = world({2: 0.0}, [(41, 2, 0, 0.4), (14, 41)])  # a cup standing on a tray
    task = Task("pick_and_place", ("obj41", "obj02"))
    steps = [["move_close(obj41)"], ["grasp(obj41)"], ["place_above(obj41,obj02)"], ["release(obj41)"], ["done"]]
    program = run_loop(ListPolicy(steps), state, task)
    assert [s.unsafe for s in program.steps] == [[], ["grasp_with_load"], [], []]
    assert program.goal_reached and not program.safe and not program.success


def test_perception_changes_what_the_policy_sees_not_the_world(scenario):
    from taskseq.plan.planner import run_loop

    def blind(ctx):
        return replace(ctx, objects=np.zeros_like(ctx.objects))

    policy = ListPolicy([[str(DEMO[0])], ["done"]])
    program = run_loop(policy, scenario.initial, scenario.task, perceive=blind)
    assert all((ctx.objects == 0).all() for ctx in policy.seen)
    assert program.actions == [DEMO[0]] and program.final.robot == (0.4, -0.35)


def test_a_task_on_an_object_missing_from_the_world_is_refused(scenario):
    with pytest.raises(ValueError, match="object obj99 is not in this environment"):
        plan(ScriptedPlanner(), scenario.initial, Task("throw_away", ("obj99",)))


SEEN: list[tuple[str, tuple]] = []  # (task, the binary attributes the planner saw first), in replay order


class SeeingPlanner(ScriptedPlanner):
    def top_k(self, ctx, k: int):
        if not ctx.history():  # the first step
            SEEN.append((str(ctx.object_ids), tuple(ctx.objects[:, BINARY_COLUMNS].ravel())))
        return super().top_k(ctx, k)


class SeeingMethod(ScriptedMethod):
    @property
    def planner_(self) -> SeeingPlanner:
        return SeeingPlanner()


@pytest.fixture
def two_scenarios(scenario) -> dict:
    other = world({2: 0.0, 10: -1.2, 8: 2.2}, [(14, 2, 0, 0.4), (13, 8, 1, 0.0), (34, 2, 0, 0.0)])
    second = Scenario("envY", Task("throw_away", (CUP,)), other, (DEMO,))
    return {scenario.id: scenario, second.id: second}


@pytest.mark.parametrize("fold_seed", [0, 1])
def test_every_condition_replays_every_scenario_once(two_scenarios, fold_seed):
    conditions = [NoiseCondition(0.0, 0), FeedbackCondition(2, 20)]
    out = evaluate_conditions({"full": SeeingMethod, "again": SeeingMethod}, [], [], two_scenarios, conditions,
                              Folds(folds=2, seed=fold_seed), max_steps=20, seed=0, n_jobs=1)
    assert list(out) == ["full", "again"]
    for results in out.values():
        assert sorted((type(c).__name__, o.scenario_id) for c, o in results) == sorted(
            (type(c).__name__, sid) for c in conditions for sid in two_scenarios)
        assert all(o.arg_correct == isinstance(c, FeedbackCondition) for c, o in results)


def test_noise_draws_depend_on_the_scenario_not_on_the_fold_layout(two_scenarios):
    noisy = [NoiseCondition(0.5, 0), NoiseCondition(0.5, 1)]
    seen = []
    for fold_seed in (0, 1, 2):
        SEEN.clear()
        evaluate_conditions({"full": SeeingMethod}, [], [], two_scenarios, noisy, Folds(folds=2, seed=fold_seed),
                            max_steps=20, seed=7, n_jobs=1)
        seen.append(sorted(SEEN))
    assert seen[0] == seen[1] == seen[2]
    SEEN.clear()
    evaluate_conditions({"full": SeeingMethod}, [], [], two_scenarios, noisy, Folds(folds=2), max_steps=20, seed=8,
                        n_jobs=1)
    assert sorted(SEEN) != seen[0]  # another noise seed, other errors
    draws = {}
    for ids, bits in seen[0]:
        draws.setdefault(ids, []).append(bits)
    assert all(len(set(b)) == 2 for b in draws.values())  # the two noise draws of a scenario differ


def test_each_program_gets_its_policy_for_its_task_seen_as_its_condition_says(two_scenarios, monkeypatch):
    """A lookahead needs the program's task, the world it began in (where the goal is judged from) and its
    perception (under noise it imagines with the same errors)."""
    from taskseq.experiments import robustness

    calls = []

    def spy(name, planner, task, start, top_k=3, perceive=None):
        assert any(start is sc.initial and task == sc.task for sc in two_scenarios.values())
        calls.append((task, top_k, perceive))
        return real(name, planner, task, start, top_k, perceive)

    real = robustness.learned_policy
    monkeypatch.setattr(robustness, "learned_policy", spy)
    conditions = [NoiseCondition(0.5, 0), FeedbackCondition(2, 20)]
    evaluate_conditions({"full": SeeingMethod}, [], [], two_scenarios, conditions, Folds(folds=2), max_steps=20,
                        seed=0, n_jobs=1)
    tasks = sorted(str(sc.task) for sc in two_scenarios.values())
    assert sorted(str(task) for task, _, _ in calls) == sorted(tasks * 2)
    noisy = [(k, p) for _, k, p in calls if p is not None]
    assert [k for k, _ in noisy] == [3, 3] and all(callable(p) for _, p in noisy)
    assert sorted(k for _, k, p in calls if p is None) == [2, 2]  # feedback: the observer's k, true perception


class Wanderer(ScriptedPlanner):
    """Never stops: offers a detour to the mug or back to the cup, in turn; the demonstration's step fourth.

    It counts its calls, so it ranks a history differently each time: never give its programs a memo.
    """

    def ranked(self, ctx):  # the whole ranking, which a policy walking down it reads
        return iter(self.top_k(ctx, 1_000_000))

    def __init__(self) -> None:
        self.calls = 0

    def top_k(self, ctx, k: int):
        t, self.calls = self.calls, self.calls + 1
        ranked = [f"move_close({MUG if t % 2 == 0 else CUP})", "done", f"move_close({TRASH})"]
        ranked += [str(DEMO[t])] if t < len(DEMO) else []
        return [(ctx.encode(Action.parse(a)), float(-i)) for i, a in enumerate(ranked)][:k]


def test_plan_caps_at_twenty_steps_by_default_or_as_told(scenario):
    from taskseq.plan.planner import STEP_CAP, run_loop

    assert len(plan(Wanderer(), scenario.initial, scenario.task).actions) == 20
    wanderer = Wanderer()
    assert len(run_loop(lambda ctx, state: wanderer.top_k(ctx, 3), scenario.initial, scenario.task).actions) == 20
    capped = plan(Wanderer(), scenario.initial, scenario.task, max_steps=2)
    assert capped.status == STEP_CAP and len(capped.actions) == 2


def test_by_default_the_observer_is_offered_the_top_three(scenario):
    # the demonstration's step comes fourth: out of reach by default, within reach with top_k=4
    choose = observer(scenario.demonstrations, 20)
    assert plan(Wanderer(), scenario.initial, scenario.task, max_steps=3, choose=choose).actions[0] != DEMO[0]
    assert plan(Wanderer(), scenario.initial, scenario.task, max_steps=3, choose=choose, top_k=4).actions[0] == DEMO[0]


def test_plan_passes_perception_on(scenario):
    seen = []

    class Looking(ScriptedPlanner):
        def top_k(self, ctx, k):
            seen.append(ctx.objects.copy())
            return super().top_k(ctx, k)

    plan(Looking(), scenario.initial, scenario.task, perceive=lambda ctx: replace(ctx, objects=ctx.objects + 1.0))
    clean = step_context(scenario.initial, scenario.task, [])
    np.testing.assert_array_equal(seen[0], clean.objects + 1.0)


FITS: list[tuple] = []
OFFERED: list[int] = []


class FittingMethod(SeeingMethod):
    def fit(self, contexts, meta, scenarios=None):
        FITS.append((list(contexts), list(meta), scenarios))
        return self

    @property
    def planner_(self) -> ScriptedPlanner:
        class Counting(ScriptedPlanner):
            def top_k(self, ctx, k):
                OFFERED.append(k)
                return super().top_k(ctx, k)

        return Counting()


def test_each_fold_trains_on_the_other_scenarios_steps_and_replays_under_the_cap(two_scenarios):
    from types import SimpleNamespace

    ids = sorted(two_scenarios)
    meta = [SimpleNamespace(scenario_id=ids[i % 2]) for i in range(5)]
    contexts = [f"step {i}" for i in range(5)]
    FITS.clear()
    OFFERED.clear()
    out = evaluate_conditions({"full": FittingMethod}, contexts, meta, two_scenarios,
                              [NoiseCondition(0.0, 0), FeedbackCondition(2, 20)], Folds(folds=2),
                              max_steps=2, seed=0, n_jobs=1)
    assert len(FITS) == 2
    for fit_contexts, fit_meta, scenarios in FITS:
        trained = {m.scenario_id for m in fit_meta}
        assert len(trained) == 1 and scenarios is two_scenarios
        assert fit_contexts == [c for c, m in zip(contexts, meta, strict=True) if m.scenario_id in trained]
    assert {FITS[0][1][0].scenario_id, FITS[1][1][0].scenario_id} == set(ids)  # each fold leaves its test out
    statuses = {(type(c).__name__, o.status) for c, o in out["full"]}
    # feedback follows the demonstration into the cap
    assert statuses == {("NoiseCondition", "done"), ("FeedbackCondition", "step_cap")}
    assert set(OFFERED) == {2, 3}  # the observer's k under feedback, the usual top 3 otherwise


def test_the_candidates_the_observer_passed_over_stay_in_order_as_alternatives(scenario):
    program = plan(ScriptedPlanner(), scenario.initial, scenario.task, top_k=3,
                   choose=observer(scenario.demonstrations, 1))
    assert program.steps[0].action == DEMO[0]
    assert program.steps[0].alternatives == [(Action("done"), 0.0), (Action.parse(f"move_close({MUG})"), -2.0)]


class CountingPlanner(ScriptedPlanner):
    """The scripted planner, counting the steps it ranks (over every program of a test)."""

    steps: list[tuple] = []

    def top_k(self, ctx, k: int):
        CountingPlanner.steps.append(tuple(ctx.history()))
        return super().top_k(ctx, k)


def test_programs_that_share_their_first_steps_rank_them_once(scenario):
    """An observer who corrects the first n steps leaves every program the same as the others up to there:
    with one memo they are ranked once, and each program is the one computed afresh, step for step."""
    from taskseq.plan.planner import Memo, greedy, run_loop

    def programs(memo):
        CountingPlanner.steps = []
        out = [run_loop(greedy(CountingPlanner(), 2), scenario.initial, scenario.task, 20, None,
                        observer(scenario.demonstrations, n), memo) for n in (0, 2, 20, 3, 2)]
        return out, CountingPlanner.steps

    alone, ranked_alone = programs(None)
    memo = Memo()
    shared, ranked_shared = programs(memo)
    assert [p.status for p in shared] == [DONE] * 5 and [len(p.actions) for p in shared] == [0, 2, 5, 3, 2]
    for a, b in zip(alone, shared, strict=True):
        assert (a.status, a.actions, a.error) == (b.status, b.actions, b.error)
        assert [(s.score, s.alternatives, s.unsafe) for s in a.steps] == [
            (s.score, s.alternatives, s.unsafe) for s in b.steps]
        assert [(x.specs, x.robot, x.held) for x in a.states] == [(y.specs, y.robot, y.held) for y in b.states]
    assert len(ranked_alone) == 1 + 3 + 6 + 4 + 3
    # the histories of the longest program, each ranked once
    assert len(ranked_shared) == len(memo.ranked) == len(memo.worlds) == 6
    # the same world objects, not executed again
    assert all(x is y for x, y in zip(shared[3].states[:4], shared[2].states[:4], strict=True))


def test_noise_draws_that_flip_nothing_are_one_program(scenario, monkeypatch):
    """At rate 0 every draw sees the world as it is: the replay ranks one program's steps for all of them.
    Draws that flip attributes rank their own steps, from the world's context made once."""
    from taskseq.plan import planner

    made = []
    real = planner.step_context
    monkeypatch.setattr(planner, "step_context", lambda *args: made.append(args) or real(*args))
    method = type("Method", (ScriptedMethod,), {"planner_": property(lambda self: CountingPlanner())})
    CountingPlanner.steps = []
    conditions = [NoiseCondition(0.0, 0), NoiseCondition(0.0, 1), NoiseCondition(0.0, 2),
                  FeedbackCondition(2, 20), FeedbackCondition(2, 20), FeedbackCondition(1, 20)]
    results = _replay(method, [], [], {scenario.id: scenario}, {scenario.id}, conditions, 20, 0)
    assert [c for c, _ in results] == conditions
    # offered one candidate (`done`), the observer cannot correct the robot: k is part of what a step offers
    assert [o.status for _, o in results] == [DONE] * 6
    assert [len(o.actions) for _, o in results] == [0, 0, 0, 5, 5, 0]
    assert len(CountingPlanner.steps) == 1 + 6 + 1  # done at once (noise), the demonstration and done, done
    assert len(made) == 6  # the world's context at each history met
    CountingPlanner.steps, made[:] = [], []
    _replay(method, [], [], {scenario.id: scenario}, {scenario.id}, [NoiseCondition(0.5, 0), NoiseCondition(0.5, 1)],
            20, 0)
    assert len(CountingPlanner.steps) == 2  # two draws that flip attributes: two ways of seeing, two programs
    assert len(made) == 1  # of one world
