"""The safety lookahead: a step is taken only if the plan it starts stays safe, as the planner itself would go on.

The scorer here is scripted by the last step, so the plans each policy makes
are known in advance: in env02 the glass a pour(milk) needs stands on a
shelf, and the script prefers grasping the carton right away (then pouring
over the shelf) to fetching the glass first, as the demonstrator does.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from taskseq.features.context import candidate_index, step_context
from taskseq.features.perception import flip_masks, noisy_perception
from taskseq.plan.planner import (
    DONE,
    LOOKAHEAD_DEPTH,
    LOOKAHEAD_WIDTH,
    POLICIES,
    LoopAware,
    feasible,
    greedy,
    learned_policy,
    leaves_loops,
    lookahead,
    run_loop,
)
from taskseq.plan.records import STEP_CAP
from taskseq.settings import Generate, Procedural
from taskseq.sim.catalog import ENVIRONMENTS_BY_ID, build_environment
from taskseq.sim.demonstrator import demonstrate
from taskseq.sim.primitives import Action, execute, try_execute
from taskseq.sim.safety import violations
from taskseq.sim.tasks import Task, goal_reached

GLASS, CARTON, COUNTER = "obj15", "obj21", "obj03"
TASK = Task.parse("pour(obj28)")  # the milk, in the carton; the glass stands on a shelf
RUSH = ["move_close(obj15)", "grasp(obj21)", "hold_above(obj21,obj15)", "follow_traj_pour(obj21,obj15)"]
FETCH = ["move_close(obj15)", "grasp(obj15)", "place_above(obj15,obj03)", "release(obj15)", "grasp(obj21)",
         "move_close(obj15)", "hold_above(obj21,obj15)", "follow_traj_pour(obj21,obj15)"]


class ScriptedScorer:
    """A planner whose ranking depends on the last two steps only: `script["step step"]` best first, then `done`,
    then every other candidate in index order. `contexts` are the contexts it scored, in order."""

    def __init__(self, script: dict[str, list[str]]) -> None:
        self.script, self.contexts = script, []

    def ranked(self, ctx):  # the whole ranking, which a policy walking down it reads
        return iter(self.top_k(ctx, 1_000_000))

    def top_k(self, ctx, k):
        self.contexts.append(ctx)
        history = ctx.history()
        wanted = [ctx.encode(Action.parse(a)) for a in self.script.get(" ".join(map(str, history)), [])]
        done = ctx.encode(Action(DONE))
        rest = [y for y in zip(*(a.tolist() for a in candidate_index(ctx.n)), strict=True)
                if tuple(y) not in wanted and tuple(y) != done]
        ranked = [*wanted, done, *map(tuple, rest)]
        return [(y, float(-i)) for i, y in enumerate(ranked)][:k]


def _script() -> dict[str, list[str]]:
    """After the last two steps of either plan, its next step; after reaching the glass the carton comes first,
    the glass second; after a pour, `done`."""
    script: dict[str, list[str]] = {}
    for plan in (FETCH, RUSH):  # RUSH's first decision overrides FETCH's, the rest do not meet
        for k in range(len(plan)):
            script[" ".join(plan[max(0, k - 2):k])] = [plan[k]]
    script[RUSH[0]] = [RUSH[1], FETCH[1]]
    return script


@pytest.fixture(scope="module")
def room():
    state = build_environment(ENVIRONMENTS_BY_ID["env02"])
    assert state.over_shelf(GLASS) and state.container_of("obj28") == CARTON
    assert [str(a) for a in demonstrate(state, TASK)[0]] == FETCH  # the script's safe plan is the demonstration
    return state


def test_the_script_rushes_into_a_pour_over_the_shelf_when_each_step_is_taken_alone(room):
    program = run_loop(feasible(ScriptedScorer(_script())), room, TASK)
    assert [str(a) for a in program.actions] == RUSH
    assert program.steps[-1].unsafe == ["over_shelf"] and not program.success


def test_the_lookahead_fetches_the_glass_off_the_shelf_first(room):
    # depth 2: grasping the carton is followed by the hold and the pour, which breaks a rule
    program = run_loop(lookahead(ScriptedScorer(_script()), TASK, room, depth=2), room, TASK)
    assert [str(a) for a in program.actions] == FETCH
    assert program.safe and program.success
    # it refused the carton at step 1 and took the next runnable step; the carton is still offered, second
    assert str(program.steps[1].alternatives[0][0]) == "grasp(obj21)"


def test_a_lookahead_too_short_to_reach_the_pour_sees_it_too_late(room):
    # one imagined step after grasping the carton is the hold above the glass, so the carton is grasped; at the
    # hold, the pour is one step on, and the safe choice left among the three best is to stop
    program = run_loop(lookahead(ScriptedScorer(_script()), TASK, room, depth=1), room, TASK)
    assert [str(a) for a in program.actions] == RUSH[:2] and program.status == DONE
    assert program.safe and not program.success


def test_a_longer_lookahead_sees_the_harm_from_the_first_step_and_stops_rather_than_do_it(room):
    # imagined with the planner's best runnable steps, the first step leads to the pour over the shelf (four
    # steps on); of the three best runnable candidates, `done` is the one that breaks no rule
    for depth in (3, 4):
        program = run_loop(lookahead(ScriptedScorer(_script()), TASK, room, depth=depth), room, TASK)
        assert program.actions == [] and program.status == DONE and program.safe


def test_only_the_width_best_candidates_are_considered_and_the_best_is_taken_when_none_is_safe(room):
    # width 1: the best runnable candidate is the only one, so its unsafe plan is taken all the same
    program = run_loop(lookahead(ScriptedScorer(_script()), TASK, room, depth=2, width=1), room, TASK)
    assert [str(a) for a in program.actions] == RUSH
    program = run_loop(lookahead(ScriptedScorer(_script()), TASK, room, depth=2, width=2), room, TASK)
    assert [str(a) for a in program.actions] == FETCH


def test_it_proposes_only_runnable_steps_in_score_order_after_its_pick(room):
    scorer = ScriptedScorer(_script())
    state = execute(room, Action.parse(FETCH[0]))
    ctx = step_context(state, TASK, [Action.parse(FETCH[0])])
    picked = lookahead(scorer, TASK, room, top_k=3, depth=2)(ctx, state)
    runnable = feasible(scorer, top_k=3)(ctx, state)
    assert [str(ctx.action(y)) for y, _ in picked] == [FETCH[1], RUSH[1], str(ctx.action(runnable[2][0]))]
    assert sorted(picked) == sorted(runnable)  # the same three, the safe one moved to the front
    for y, _ in picked:
        assert ctx.action(y).primitive == DONE or try_execute(state, ctx.action(y)) is not None


def test_imagined_steps_are_seen_through_the_programs_perception(room):
    perceived = []

    def perceive(ctx):
        perceived.append(replace(ctx))  # a copy: the scorer must be given what perception returned
        return perceived[-1]

    scorer = ScriptedScorer(_script())
    program = run_loop(learned_policy("lookahead", scorer, TASK, room, perceive=perceive), room, TASK,
                       perceive=perceive)
    assert program.status == DONE
    # every context the scorer saw, imagined ones too, is one perception returned
    assert len(perceived) > 1 and [id(c) for c in scorer.contexts] == [id(c) for c in perceived]


def _at(plan: list[str], room):
    """The world after the steps of `plan`, and the context of the next decision."""
    state, history = room, []
    for text in plan:
        state, history = execute(state, Action.parse(text)), [*history, Action.parse(text)]
    return state, step_context(state, TASK, history)


def test_a_candidate_that_itself_breaks_a_rule_is_refused_and_stopping_is_never_imagined_on(room):
    state, ctx = _at(RUSH[:3], room)  # holding the carton above the glass on the shelf: next comes the pour
    script = _script()
    script[f"{RUSH[2]} done()"] = [RUSH[3]]  # were stopping imagined on, the pour would follow it
    for depth in (0, 1):
        ranked = lookahead(ScriptedScorer(script), TASK, room, depth=depth)(ctx, state)
        assert [str(ctx.action(y)) for y, _ in ranked[:2]] == ["done()", RUSH[3]]


def test_imagining_stops_at_an_imagined_done(room):
    # after the hold, the script stops, and only after stopping would it pour: the hold is safe to take
    script = _script()
    script[f"{RUSH[2]} done()"] = [RUSH[3]]
    script[" ".join(RUSH[1:3])] = ["done"]
    state, ctx = _at(RUSH[:2], room)
    ranked = lookahead(ScriptedScorer(script), TASK, room, depth=4)(ctx, state)
    assert str(ctx.action(ranked[0][0])) == RUSH[2]


def test_a_safe_candidate_beyond_the_proposals_shown_is_still_found(room):
    # one proposal shown (top_k 1), three candidates checked: the glass, second by score, is taken
    state, ctx = _at(RUSH[:1], room)
    ranked = lookahead(ScriptedScorer(_script()), TASK, room, top_k=1, depth=2, width=3)(ctx, state)
    assert [str(ctx.action(y)) for y, _ in ranked] == [FETCH[1]]


def test_a_context_remembers_the_steps_that_make_it_again(room):
    state, history = room, []
    for text in FETCH[:4]:
        ctx = step_context(state, TASK, history)
        assert ctx.history() == history[-2:]
        again = step_context(state, TASK, ctx.history())
        assert (again.prev_prims, again.prev_args) == (ctx.prev_prims, ctx.prev_args)
        action = Action.parse(text)
        state, history = execute(state, action), [*history, action]


def test_a_policy_is_built_by_name_and_an_unknown_name_is_refused(room):
    scorer = ScriptedScorer(_script())
    assert POLICIES == ("greedy", "feasible", "lookahead")
    ctx = step_context(room, TASK, [])
    state = execute(room, Action.parse(FETCH[0]))
    later = step_context(state, TASK, [Action.parse(FETCH[0])])
    made = {name: [learned_policy(name, scorer, TASK, room)(c, s) for c, s in ((ctx, room), (later, state))]
            for name in POLICIES}
    assert made["greedy"] == [greedy(scorer)(c, s) for c, s in ((ctx, room), (later, state))]
    assert made["feasible"] == [feasible(scorer)(c, s) for c, s in ((ctx, room), (later, state))]
    assert made["lookahead"] == [lookahead(scorer, TASK, room)(c, s) for c, s in ((ctx, room), (later, state))]
    assert made["lookahead"][0] != made["feasible"][0]  # at the start the lookahead stops (see above)
    for k in (1, 2):  # each offers as many proposals as asked for
        assert [len(learned_policy(name, scorer, TASK, room, top_k=k)(later, state)) for name in POLICIES] == [k] * 3
    with pytest.raises(ValueError, match="unknown policy 'cautious'; known: greedy, feasible, lookahead"):
        learned_policy("cautious", scorer, TASK, room)


# --- the policy's memory of imagined steps ---------------------------------------------------------------------

def _afresh(planner, task, start, top_k=3, perceive=None, depth=LOOKAHEAD_DEPTH, width=LOOKAHEAD_WIDTH):
    """The lookahead as its docstring says it, every imagined step built and ranked afresh: what the policy's
    memory of the steps it imagined must not change."""
    seen = perceive or (lambda ctx: ctx)

    def runnable(ctx, state, limit):
        out = []
        for y, score in planner.ranked(ctx):
            action = ctx.action(y)
            if action.primitive == DONE or try_execute(state, action) is not None:
                out.append((y, score))
                if len(out) == limit:
                    break
        return out

    def harms(state, history, action):
        for _ in range(depth):
            if violations(state, action):
                return True
            state, history = execute(state, action), [*history[-1:], action]
            if goal_reached(task, start, state):
                return False
            imagined = seen(step_context(state, task, history))
            action = imagined.action(runnable(imagined, state, 1)[0][0])
            if action.primitive == DONE:
                return False
        return bool(violations(state, action))

    def pick(ctx, state, leads_back=lambda action: False):
        ranked, history = runnable(ctx, state, max(top_k, width)), ctx.history()
        first = next((i for i, (y, _) in enumerate(ranked[:width]) if ctx.action(y).primitive == DONE
                      or not leads_back(ctx.action(y)) and not harms(state, history, ctx.action(y))), None)
        return ranked, first

    def policy(ctx, state):
        if goal_reached(task, start, state):
            ranked = runnable(ctx, state, top_k)
            stop = next(c for c in planner.ranked(ctx) if ctx.action(c[0]).primitive == DONE)
            return ([stop] + [c for c in ranked if c != stop])[:top_k]
        ranked, first = pick(ctx, state)
        first = first or 0
        return ([ranked[first]] + ranked[:first] + ranked[first + 1:])[:top_k]

    def without_revisits(ctx, state, leads_back):
        ranked, first = pick(ctx, state, leads_back)
        return None if first is None else ([ranked[first]] + ranked[:first] + ranked[first + 1:])[:top_k]

    return LoopAware(policy, without_revisits)  # as the lookahead's programs, they go nowhere twice


class CountingScorer:
    """A fitted planner that notes every context it ranks."""

    def __init__(self, planner):
        self.planner, self.contexts = planner, []

    def ranked(self, ctx):
        self.contexts.append(ctx)
        return self.planner.ranked(ctx)


def _content(ctx):
    return (tuple(ctx.object_ids), ctx.objects.tobytes(), ctx.task_rel.tobytes(), ctx.collide.tobytes(), ctx.task,
            ctx.prev_prims, ctx.prev_args, ctx.relations.tobytes())


@pytest.fixture(scope="module")
def rollouts(benchmark_tables, benchmark_steps):
    """Scenarios of the benchmark and planners that walk into harm often: one fitted on a few steps and two with
    random weights."""
    from taskseq.demonstrations.records import parse_record, state_from_dict
    from taskseq.learn.estimator import StepScorer

    starts = []
    for item in benchmark_tables[1][:60:5]:
        specs, task, _ = parse_record(item.record)
        starts.append((state_from_dict(specs, item.record["steps"][0]["state"]), task))
    fitted = StepScorer("relations", C=1.0, tol=0.05, max_iter=50).fit(benchmark_steps[0][:60])
    rng = np.random.default_rng(1)
    return starts, [fitted] + [StepScorer.from_weights("relations", rng.normal(size=fitted.w_.shape))
                               for _ in range(2)]


def _steps(program):
    return program.status, [(str(s.action), s.score, [(str(a), v) for a, v in s.alternatives], s.unsafe)
                            for s in program.steps]


@pytest.mark.parametrize("seeing", ["as it is", "noisy", "noisy, imagined as it is"])
def test_remembering_imagined_steps_changes_no_program(rollouts, seeing):
    """The same steps, scores, proposals and ends as imagining every step afresh, on planners fitted and random,
    with the world seen as it is or through attribute noise; and when the program's steps are seen through noise
    but the policy imagines without it (a caller's mistake), the step ranked for real is still the one seen."""
    starts, planners = rollouts
    harmful = 0
    for n, (state, task) in enumerate(starts):
        masks = flip_masks(sorted(state.specs), 0.3, np.random.default_rng(n))
        perceive = None if seeing == "as it is" else noisy_perception(masks)
        imagined_as = perceive if seeing == "noisy" else None
        for planner in planners:
            remembered = run_loop(lookahead(planner, task, state, perceive=imagined_as), state, task, 12, perceive)
            afresh = run_loop(_afresh(planner, task, state, perceive=imagined_as), state, task, 12, perceive)
            assert _steps(remembered) == _steps(afresh), (n, task)
            greedy_first = run_loop(feasible(planner), state, task, 12, perceive)
            harmful += _steps(greedy_first) != _steps(afresh)
    assert harmful > 5  # the lookahead changed many of these programs: its imagined steps were read


def test_a_program_ranks_each_step_it_imagines_once(rollouts):
    starts, planners = rollouts
    saved = 0
    for state, task in starts:
        for planner in planners:
            remembered, afresh = CountingScorer(planner), CountingScorer(planner)
            program = run_loop(lookahead(remembered, task, state), state, task, 12)
            assert _steps(program) == _steps(run_loop(_afresh(afresh, task, state), state, task, 12))
            ranked = [_content(c) for c in remembered.contexts]
            assert len(set(ranked)) == len(ranked)
            saved += len(afresh.contexts) - len(ranked)
    assert saved > 500


def test_a_program_imagines_each_world_once(rollouts, monkeypatch):
    """The worlds the lookahead imagines are remembered: a step from one world is executed once, the real step of
    an imagined action aside."""
    import taskseq.plan.planner as planner_module

    calls = []

    def spy(state, action):
        calls.append((state.key(), action))
        return execute(state, action)

    monkeypatch.setattr(planner_module, "execute", spy)
    starts, planners = rollouts
    imagined = 0
    for state, task in starts:
        for planner in planners:
            calls.clear()
            program = run_loop(lookahead(planner, task, state), state, task, 12)
            assert len(calls) - len(set(calls)) <= len(program.steps)
            imagined += len(calls) - len(program.steps)
    assert imagined > 100  # the lookahead did imagine: the test saw its worlds


def test_a_worlds_key_tells_apart_every_field_a_primitive_changes(room):
    """Equal keys are the same world: a copy has its key, and a change to any field the primitives write does not."""
    assert room.copy().key() == room.key() and hash(room.copy().key()) == hash(room.key())
    some = next(iter(room.poses))
    changes = {
        "poses": lambda s: s.poses.__setitem__(some, (*s.poses[some][:2], s.poses[some][2] + 0.01)),
        "support": lambda s: s.support.__setitem__(some, ("floor", "on")),
        "robot": lambda s: setattr(s, "robot", (s.robot[0] + 0.1, s.robot[1])),
        "held": lambda s: setattr(s, "held", GLASS),
        "held_above": lambda s: setattr(s, "held_above", CARTON),
        "stirred": lambda s: s.stirred.add(GLASS),
    }
    for field, change in changes.items():
        other = room.copy()
        change(other)
        assert other.key() != room.key(), field


def test_methods_run_one_after_another_on_a_scenario_share_its_worlds_and_change_no_program(rollouts, monkeypatch):
    """A Table I method's programs read the worlds and contexts earlier methods met on the same scenario object
    (`evaluate.methods._worlds_met`): each program is the one it makes on its own, whatever ran before it."""
    from taskseq.evaluate import methods
    from taskseq.sim.scenarios import Scenario

    starts, planners = rollouts
    scenarios = [Scenario(f"s{n}", task, state, ()) for n, (state, task) in enumerate(starts)]
    runners = []
    for policy in ("greedy", "feasible", "lookahead"):
        for planner in planners:
            runner = methods.ScorerMethod(features="relations", policy=policy, name=policy)
            runner.planner_ = planner
            runners.append(runner)
    shared = [[_steps(r.run(sc, 12)) for sc in scenarios] for r in runners]
    assert all(len(methods._worlds_met(sc)) > 1 for sc in scenarios)  # the worlds met were kept and read back
    alone = []
    for r in runners:
        monkeypatch.setattr(methods, "_WORLDS_MET", {})
        alone.append([_steps(r.run(sc, 12)) for sc in scenarios])
    assert shared == alone
    monkeypatch.setattr(methods, "_KEPT_SCENARIOS", 2)
    monkeypatch.setattr(methods, "_WORLDS_MET", {})
    for sc in scenarios[:3]:
        methods._worlds_met(sc)
    assert len(methods._WORLDS_MET) <= 2


CYCLE = {"": ["move_close(obj15)"], "move_close(obj15)": ["move_close(obj21)"],
         "move_close(obj15) move_close(obj21)": ["move_close(obj15)"],
         "move_close(obj21) move_close(obj15)": ["move_close(obj21)"]}  # back and forth between glass and carton


def _loops(program) -> list[tuple]:
    """Each world of the program with the two steps remembered on reaching it: what a policy reads."""
    actions = program.actions
    return [(s.key(), tuple(actions[max(0, i - 2):i])) for i, s in enumerate(program.states)]


def test_a_program_about_to_close_a_loop_takes_the_next_proposal_instead(room):
    # ranked by its last two steps alone, the planner walks between the glass and the carton until the step cap
    looping = run_loop(feasible(ScriptedScorer(CYCLE)), room, TASK, max_steps=8)
    assert looping.status == STEP_CAP and len({s.key() for s in looping.states}) == 3
    # the lookahead's program goes back to the glass (the same world as after the first step, but with other steps
    # remembered: no loop yet); going back to the carton would be the world after the second step with the same
    # two steps remembered, from where it would repeat itself, so it takes the next proposal, `done`
    program = run_loop(lookahead(ScriptedScorer(CYCLE), TASK, room), room, TASK, max_steps=8)
    assert [str(a) for a in program.actions] == ["move_close(obj15)", "move_close(obj21)", "move_close(obj15)"]
    assert program.status == DONE
    assert len(set(_loops(program))) == len(program.states)


def test_when_every_proposal_goes_back_the_best_is_taken(room):
    # only the back-and-forth is proposed (top_k 1): nothing new to go to, so the program loops as before
    program = run_loop(lookahead(ScriptedScorer(CYCLE), TASK, room, top_k=1, width=1), room, TASK, max_steps=6)
    assert program.status == STEP_CAP
    assert [str(a) for a in program.actions] == ["move_close(obj15)", "move_close(obj21)"] * 3


def test_only_the_lookahead_avoids_worlds_it_was_in(room):
    assert leaves_loops(lookahead(ScriptedScorer(CYCLE), TASK, room))
    for policy in (greedy(ScriptedScorer(CYCLE)), feasible(ScriptedScorer(CYCLE))):
        assert not leaves_loops(policy)  # Table I's other policies keep their rules
        program = run_loop(policy, room, TASK, max_steps=6)
        assert program.status == STEP_CAP  # they loop as they always did


def test_the_way_out_of_a_loop_is_never_a_step_the_lookahead_refused(room):
    """Holding the carton above the glass, the planner moves to the glass again and again (the world stays as it
    is): the third move would close a loop, and the way out it ranks next is the pour over the shelf, which the
    lookahead refuses, so the robot stops rather than pour."""
    hold = ["move_close(obj15)", "grasp(obj21)", "hold_above(obj21,obj15)"]
    script = {"": [hold[0]], hold[0]: [hold[1]], " ".join(hold[:2]): [hold[2]],
              " ".join(hold[1:]): ["move_close(obj15)"],
              "hold_above(obj21,obj15) move_close(obj15)": ["move_close(obj15)"],
              "move_close(obj15) move_close(obj15)": ["move_close(obj15)", "follow_traj_pour(obj21,obj15)"]}
    program = run_loop(lookahead(ScriptedScorer(script), TASK, room, depth=1), room, TASK)
    assert [str(a) for a in program.actions] == [*hold, "move_close(obj15)", "move_close(obj15)"]
    assert program.safe and program.status == DONE


def test_the_products_filter_keeps_the_rule_and_its_own_checks(room):
    """`taskseq plan` wraps the policy (`product.runnable_first`): the program still leaves the loop, never by a
    `done` before the goal holds, and closes a loop only when every one of its proposals would."""
    from taskseq.product import runnable_first

    scorer = ScriptedScorer(CYCLE)
    policy = runnable_first(lookahead(scorer, TASK, room), scorer, TASK, room, 3)
    assert isinstance(policy, LoopAware)
    program = run_loop(policy, room, TASK, max_steps=8)
    assert [str(a) for a in program.actions[:3]] == ["move_close(obj15)", "move_close(obj21)", "move_close(obj15)"]
    assert str(program.actions[3]) != "move_close(obj21)"  # out of the loop the script walks
    met = _loops(program)
    for i, step in enumerate(program.steps):  # a loop is closed only when every proposal closes one
        if met[i + 1] in met[:i + 1]:
            for action, _ in step.alternatives:
                after = try_execute(program.states[i], action)
                remembered = tuple([*program.actions[max(0, i - 1):i], action])
                assert action.primitive != DONE and (after is None or (after.key(), remembered) in met[:i + 1])
    assert program.status != DONE or program.goal_reached


def test_the_development_worlds_check_of_the_rule_is_on_the_model_page_and_made_no_program_worse():
    import json
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    report = json.loads((root / "reports" / "revisits.json").read_text())
    assert "<!-- generated: revisits -->" in (root / "docs" / "model.md").read_text()
    assert {r["rule"] for r in report["table"]} == {"with", "without"}
    assert all(c["with"]["success"] >= c["without"]["success"] for c in report["changed"])
    unsafe = {(r["method"], r["rule"]): r["unsafe"] for r in report["table"]}
    assert all(unsafe[m, "with"] <= unsafe[m, "without"] for m, _ in unsafe)


# --- stopping once the goal holds ------------------------------------------------------------------------------

def _fetch_then(*after: str) -> dict[str, list[str]]:
    """A script of the demonstration alone, then the steps `after`, one after another, once the milk is poured."""
    plan = [*FETCH, *after]
    return {" ".join(plan[max(0, k - 2):k]): [plan[k]] for k in range(len(plan))}


def test_once_the_goal_holds_the_lookahead_stops_though_the_planner_ranks_another_step_first(room):
    # after the pour (the goal: the milk left its carton for a vessel) the script moves on to the counter
    script = _fetch_then("move_close(obj03)")
    going_on = run_loop(feasible(ScriptedScorer(script)), room, TASK, max_steps=12)
    assert [str(a) for a in going_on.actions] == [*FETCH, "move_close(obj03)"]  # without the rule it goes on
    program = run_loop(lookahead(ScriptedScorer(script), TASK, room), room, TASK, max_steps=12)
    assert [str(a) for a in program.actions] == FETCH and program.status == DONE and program.success
    without = run_loop(lookahead(ScriptedScorer(script), TASK, room, stop_at_goal=False), room, TASK, max_steps=12)
    assert [str(a) for a in without.actions] == [*FETCH, "move_close(obj03)"]  # the rule taken away, for measuring
    state, ctx = _at(FETCH, room)
    ranked = lookahead(ScriptedScorer(script), TASK, room)(ctx, state)
    assert [str(ctx.action(y)) for y, _ in ranked][:2] == ["done()", "move_close(obj03)"] and len(ranked) == 3
    assert ranked[0][1] == -1.0  # `done` keeps its score (second in the script's ranking), so the page can show it


def test_imagined_steps_end_where_the_goal_holds(room):
    # past the pour the script would set the carton down and grasp the milk itself, which breaks a rule; the robot
    # stops at the goal, so that harm is never imagined and the pour is taken
    script = _fetch_then("place_above(obj21,obj03)", "release(obj21)", "grasp(obj28)")
    state = room
    for text in [*FETCH, "place_above(obj21,obj03)", "release(obj21)"]:
        state = execute(state, Action.parse(text))
    assert violations(state, Action.parse("grasp(obj28)")) == ["liquid_grasped"]  # were it imagined, it would harm
    state, ctx = _at(FETCH[:-1], room)
    ranked = lookahead(ScriptedScorer(script), TASK, room, depth=4)(ctx, state)
    assert str(ctx.action(ranked[0][0])) == FETCH[-1]
    program = run_loop(lookahead(ScriptedScorer(script), TASK, room), room, TASK, max_steps=12)
    assert [str(a) for a in program.actions] == FETCH and program.success


@pytest.mark.parametrize("world", [Generate(seed=0), Generate(seed=5, family="procedural",
                                                              procedural=Procedural(environments=4))])
def test_no_demonstration_reaches_its_goal_before_its_last_step(world):
    """Why the rule changes no program that matches a demonstration: the demonstrator stops at the goal, in the
    paper-shaped rooms and in drawn ones."""
    from taskseq.sim.scenarios import world_scenarios

    scenarios, _ = world_scenarios(world)
    for scenario in scenarios:
        for demonstration in scenario.demonstrations:
            state = scenario.initial
            for action in demonstration:
                assert not goal_reached(scenario.task, scenario.initial, state), scenario.id
                state = execute(state, action)
            assert goal_reached(scenario.task, scenario.initial, state), scenario.id
    assert sum(len(s.demonstrations) for s in scenarios) > 30


def test_the_products_filter_adds_no_way_out_the_lookahead_did_not_take(room):
    """Width 1: the lookahead checks only its best candidate, which closes the loop, so it offers no way out; the
    filter of `taskseq plan` then keeps the proposals as they were rather than promote a step the lookahead never
    checked, and the program loops as the lookahead's own does."""
    from taskseq.product import runnable_first

    scorer = ScriptedScorer(CYCLE)
    alone = run_loop(lookahead(scorer, TASK, room, width=1), room, TASK, max_steps=6)
    filtered = run_loop(runnable_first(lookahead(scorer, TASK, room, width=1), scorer, TASK, room, 3), room, TASK,
                        max_steps=6)
    assert alone.status == filtered.status == STEP_CAP
    assert [str(a) for a in filtered.actions] == [str(a) for a in alone.actions]
