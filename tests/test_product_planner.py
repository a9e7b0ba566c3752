"""The product's planner (`taskseq plan`, the assist page) never proposes first a step the simulator refuses.

A property over drawn rooms (`sim.procedural`), models of arbitrary weights and every policy a model file can
record: at every step of every program, the first proposal runs (its checks pass, it breaks no safety rule, and
`done` comes only once the goal holds), or the planner says plainly that no step can run. The same weights
without the product's filter propose refused steps first, so the property is not vacuous.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from taskseq.cli import main
from taskseq.demonstrations.records import spec_to_dict, state_to_dict
from taskseq.features.context import step_context
from taskseq.learn.estimator import StepScorer
from taskseq.learn.mrf import StepMRF
from taskseq.plan.planner import DONE, POLICIES, Abstain, learned_policy
from taskseq.product import parse_task, recorded_policy, runnable_first
from taskseq.sim.primitives import Action, execute, try_execute
from taskseq.sim.procedural import Procedural
from taskseq.sim.safety import violations
from taskseq.sim.scenarios import candidate_scenarios, drawn_scenarios
from taskseq.sim.tasks import Task, goal_reached
from tests.conftest import world

STEPS = 6  # steps followed per program


def runs(task, initial, state, action) -> bool:
    if action.primitive == DONE:
        return goal_reached(task, initial, state)
    return try_execute(state, action) is not None and not violations(state, action)


@pytest.fixture(scope="module")
def scenarios():
    """Three drawn rooms, two tasks of each kind where a room has them (in their drawn order)."""
    pool, _ = drawn_scenarios(11, 3, Procedural())
    picked: dict[tuple[str, str], list] = {}
    for s in pool:
        kind = picked.setdefault((s.env_id, s.task.name), [])
        if len(kind) < 2:
            kind.append(s)
    return [s for kind in picked.values() for s in kind]


@pytest.mark.parametrize("policy", POLICIES)
def test_the_first_proposal_always_runs_in_the_simulator(scenarios, policy, tmp_path):
    refused_raw = 0  # steps where the same policy without the filter proposes first a refused step
    for seed in (0, 1):
        path = tmp_path / f"{policy}{seed}.npz"
        weights = np.random.default_rng(seed).normal(size=StepMRF("full").size_joint_feature)
        StepScorer.from_weights("full", weights).save(path, policy=policy)
        planner = StepScorer.load(path)
        policy_for = recorded_policy(planner, path, 3)
        for scenario in scenarios:
            task, initial = scenario.task, scenario.initial
            checked, raw = policy_for(task, initial), learned_policy(policy, planner, task, initial, 3)
            state, history = initial, []
            for _ in range(STEPS):
                ctx = step_context(state, task, history)
                first_raw = ctx.action(raw(ctx, state)[0][0])
                refused_raw += not runs(task, initial, state, first_raw)
                try:
                    ranked = checked(ctx, state)
                except Abstain as why:
                    assert "no step that can run here" in str(why)
                    break
                actions = [ctx.action(y) for y, _ in ranked]
                assert runs(task, initial, state, actions[0]), (scenario.id, history, actions[0])
                assert all(runs(task, initial, state, a) for a in actions) and len(actions) == 3
                if actions[0].primitive == DONE:
                    break
                state, history = execute(state, actions[0]), [*history, actions[0]]
    assert refused_raw > 0


def test_taskseq_plan_never_stops_before_the_goal_in_a_hand_written_room(scenarios, tmp_path, capsys):
    """A model that scores `done` above everything: `taskseq plan` takes the best step that runs instead."""
    model = StepMRF("full")
    scenario = scenarios[0]
    ctx = step_context(scenario.initial, scenario.task, [])
    done = ctx.encode(Action("done"))
    weights = model.joint_feature(ctx, done)  # scores done highest of all at this step
    path = tmp_path / "eager.npz"
    StepScorer.from_weights("full", weights).save(path)
    planner = StepScorer.load(path)
    assert ctx.action(planner.top_k(ctx, 1)[0][0]).primitive == DONE  # unfiltered, it would stop at once
    room = tmp_path / "room.json"
    room.write_text(json.dumps({"objects": [spec_to_dict(s) for s in scenario.initial.specs.values()],
                                "state": state_to_dict(scenario.initial)}))
    main(["plan", "--model", str(path), "--env", str(room), "--task", str(scenario.task), "--max-steps", "3",
          "--json"])
    program = json.loads(capsys.readouterr().out)
    assert program["steps"] and program["steps"][0]["action"] != "done()"
    assert program["status"] != "done" or program["goal_reached"]
    assert all(not s["unsafe"] for s in program["steps"])


def test_when_no_candidate_runs_the_planner_says_so_plainly(scenarios):
    """A model whose every candidate is `done` before the goal holds (a stand-in: in the simulator the robot can
    nearly always move): no proposal, and the reason in words."""
    scenario = scenarios[0]
    ctx = step_context(scenario.initial, scenario.task, [])
    done = ctx.encode(Action("done"))

    class OnlyDone:
        def ranked(self, ctx):
            return iter([(done, 1.0)])

    policy = runnable_first(lambda ctx, state: [(done, 1.0)], OnlyDone(), scenario.task, scenario.initial, 3)
    with pytest.raises(Abstain, match="the planner has no step that can run here: the simulator refuses every"):
        policy(ctx, scenario.initial)


def test_every_task_the_benchmark_poses_passes_the_products_checks():
    """`parse_task` refuses only tasks of no kind the benchmark poses: every scenario of a paper-shaped world and of
    six drawn rooms, written in ids as the records write it, is taken as it is (the checks are not vacuous: the
    tests of `taskseq plan` and the task form see them refuse)."""
    pool = candidate_scenarios(0) + drawn_scenarios(2, 6, Procedural())[0]
    assert {s.task.name for s in pool} == {"stir", "pour", "pour_to", "pick_and_place", "throw_away"}
    for s in pool:
        assert parse_task(str(s.task), s.initial) == s.task, s.id


def test_a_liquid_task_no_program_can_do_is_refused_with_the_reason():
    """Water on the table itself, or in the only container of the room: nothing can pour it (a hand-written room
    where the planner went to its step cap); a cup beside the bottle makes the same task one to do."""
    loose = world({2: 0.0}, [(27, 2)])
    with pytest.raises(ValueError, match=r"water \(obj27\) is in no container, so nothing can pour it"):
        parse_task("pour(obj27)", loose)
    with pytest.raises(ValueError, match=r"in no container, so nothing can stir it"):
        parse_task("stir(water)", loose)
    alone = world({2: 0.0}, [(20, 2), (27, 20)])
    with pytest.raises(ValueError, match=r"water_bottle \(obj20\) is the only container here, so water has nowhere "
                                         r"to be poured"):
        parse_task("pour(water)", alone)
    with_a_cup = world({2: 0.0}, [(20, 2, 0, -0.2), (27, 20), (14, 2, 0, 0.2)])
    assert parse_task("pour(water)", with_a_cup) == Task("pour", ("obj27",))
