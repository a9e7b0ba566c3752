"""Why a program fails: one hand-made program per kind."""

import pytest

from taskseq.evaluate.failures import KINDS, classify, failure_counts
from taskseq.plan.planner import DONE, INFEASIBLE, STEP_CAP
from taskseq.sim.primitives import Action


def acts(*texts: str) -> tuple[Action, ...]:
    return tuple(Action.parse(t) for t in texts)


DEMO = acts("move_close(obj20)", "grasp(obj20)", "move_close(obj14)", "hold_above(obj20,obj14)",
            "follow_traj_pour(obj20,obj14)")
OTHER = acts("move_close(obj20)", "grasp(obj20)", "move_close(obj15)", "hold_above(obj20,obj15)",
             "follow_traj_pour(obj20,obj15)")


@pytest.mark.parametrize("kind, actions, status, unsafe, success", [
    ("exact", DEMO, DONE, [], True),
    ("other_success", DEMO[:2] + acts("move_close(obj15)") + DEMO[3:], DONE, [], True),
    ("wrong_object", DEMO[:2] + acts("move_close(obj16)", "hold_above(obj20,obj16)"), DONE, [], False),
    ("wrong_primitive", DEMO[:2] + acts("hold_above(obj20,obj14)"), DONE, [], False),
    ("infeasible_step", DEMO[:1] + acts("grasp(obj14)"), INFEASIBLE, [], False),
    ("unsafe_step", DEMO[:3] + acts("follow_traj_pour(obj20,obj14)"), DONE, [3], False),
    ("stopped_early", DEMO[:3], DONE, [], False),
    ("stopped_late", DEMO + acts("release(obj20)"), DONE, [], False),
    ("step_cap", DEMO[:1] + acts("move_close(obj14)", "move_close(obj20)") * 3, STEP_CAP, [], False),
])
def test_each_kind_of_program_is_named(kind, actions, status, unsafe, success):
    assert classify(actions, status, unsafe, success, [DEMO]) == kind


def test_the_demonstration_followed_longest_decides():
    # follows the second demonstration to step 3, then picks another cup: a wrong object against it
    program = OTHER[:3] + acts("hold_above(obj20,obj14)")
    assert classify(program, DONE, [], False, [DEMO, OTHER]) == "wrong_object"
    assert classify(OTHER, DONE, [], True, [DEMO, OTHER]) == "exact"


def test_a_goal_reached_unsafely_is_an_unsafe_program_wherever_it_diverged():
    program = acts("move_close(obj27)", "grasp(obj27)") + DEMO[2:]  # grasps the liquid itself, pours anyway
    assert classify(program, DONE, [4], False, [DEMO], goal_reached=True) == "unsafe_step"
    assert classify(program, DONE, [4], False, [DEMO], goal_reached=False) == "wrong_object"


def test_an_infeasible_step_after_the_divergence_counts_as_the_divergence():
    program = DEMO[:2] + acts("move_close(obj16)", "grasp(obj14)")
    assert classify(program, INFEASIBLE, [], False, [DEMO]) == "wrong_object"


def test_counts_list_every_kind_and_refuse_unknown_ones():
    counts = failure_counts(["exact", "exact", "step_cap"])
    assert list(counts) == list(KINDS) and counts["exact"] == 2 and counts["wrong_object"] == 0
    with pytest.raises(ValueError, match="unknown program kinds"):
        failure_counts(["lost"])
