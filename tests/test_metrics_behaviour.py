"""Failure kinds at their boundaries, the rates of a summary and the choice of C, on hand-made inputs with known
answers."""

from __future__ import annotations

import pytest

from taskseq.evaluate.failures import FAILURES, KINDS, classify, failure_counts
from taskseq.evaluate.metrics import confusion, headline_metrics, step_accuracy, summarize
from taskseq.experiments.crossval import FoldResult, SequenceOutcome
from taskseq.experiments.selection import CRITERION, best_candidate
from taskseq.features.context import StepContext
from taskseq.plan.planner import DONE, INFEASIBLE, STEP_CAP
from taskseq.sim.primitives import ALL_PRIMITIVES, Action


def acts(*texts: str) -> tuple[Action, ...]:
    return tuple(Action.parse(t) for t in texts)


DEMO = acts("move_close(obj20)", "grasp(obj20)", "move_close(obj14)", "hold_above(obj20,obj14)",
            "follow_traj_pour(obj20,obj14)")

# one program built to be exactly each failure kind: (actions, status, unsafe steps)
PROGRAMS = {
    "wrong_object": (DEMO[:2] + acts("move_close(obj16)"), DONE, []),
    "wrong_primitive": (DEMO[:2] + acts("hold_above(obj20,obj14)"), DONE, []),
    "infeasible_step": (DEMO[:1] + acts("grasp(obj14)"), INFEASIBLE, []),
    "unsafe_step": (DEMO[:3] + acts("hold_above(obj20,obj16)"), DONE, [3]),
    "stopped_early": (DEMO[:3], DONE, []),
    "stopped_late": (DEMO + acts("release(obj20)"), DONE, []),
    "step_cap": (DEMO[:2] + acts("move_close(obj16)", "move_close(obj14)") * 3, STEP_CAP, []),
}


def test_every_failure_kind_has_a_program_built_to_be_it():
    assert set(PROGRAMS) == set(FAILURES)


@pytest.mark.parametrize("kind", FAILURES)
@pytest.mark.parametrize("goal", [False, True])
def test_each_failure_kind_whether_or_not_the_goal_was_reached_safely(kind, goal):
    # a goal reached with no unsafe step changes no kind: only a goal reached *unsafely* is relabelled
    actions, status, unsafe = PROGRAMS[kind]
    assert classify(actions, status, unsafe, False, [DEMO], goal_reached=goal) == kind


@pytest.mark.parametrize("kind", [k for k in FAILURES if k not in ("unsafe_step", "step_cap")])
def test_a_goal_reached_unsafely_is_unsafe_wherever_the_program_diverged(kind):
    actions, status, _ = PROGRAMS[kind]
    assert classify(actions, status, [0], False, [DEMO], goal_reached=True) == "unsafe_step"
    assert classify(actions, status, [0], False, [DEMO], goal_reached=False) != "unsafe_step"


def test_the_step_cap_wins_over_everything_but_success():
    actions, _, _ = PROGRAMS["step_cap"]
    assert classify(actions, STEP_CAP, [2], False, [DEMO], goal_reached=True) == "step_cap"
    assert classify(DEMO, STEP_CAP, [], False, [DEMO]) == "exact"  # equal to a demonstration: exact, however ended


def test_success_is_other_success_unless_exact():
    other = DEMO[:2] + acts("move_close(obj15)") + DEMO[3:]
    assert classify(other, DONE, [], True, [DEMO], goal_reached=True) == "other_success"
    assert classify(DEMO, DONE, [], True, [DEMO], goal_reached=True) == "exact"
    assert classify(other, DONE, [], False, [DEMO, other]) == "exact"  # any demonstration counts


def test_an_infeasible_step_is_named_only_at_the_divergence():
    at = DEMO[:2] + acts("grasp(obj14)")  # diverges at its last step, which could not run
    assert classify(at, INFEASIBLE, [], False, [DEMO]) == "infeasible_step"
    assert classify(at, DONE, [], False, [DEMO]) == "wrong_primitive"  # the same step, executed
    after = DEMO[:2] + acts("move_close(obj16)", "grasp(obj14)")  # diverged one step before
    assert classify(after, INFEASIBLE, [], False, [DEMO]) == "wrong_object"


def test_an_unsafe_step_is_named_only_at_the_divergence():
    program = DEMO[:3] + acts("hold_above(obj20,obj16)", "follow_traj_pour(obj20,obj16)")
    assert classify(program, DONE, [3], False, [DEMO]) == "unsafe_step"
    assert classify(program, DONE, [4], False, [DEMO]) == "wrong_object"  # unsafe after it diverged
    assert classify(program, DONE, [2], False, [DEMO]) == "wrong_object"  # unsafe before, goal not reached


def test_stopping_early_and_late_are_told_apart_by_the_demonstration_length():
    assert classify(DEMO[:4], DONE, [], False, [DEMO]) == "stopped_early"
    assert classify((), DONE, [], False, [DEMO]) == "stopped_early"
    assert classify(DEMO + acts("release(obj20)"), DONE, [], False, [DEMO]) == "stopped_late"
    assert classify(DEMO[:4] + acts("release(obj20)"), DONE, [], False, [DEMO]) == "wrong_primitive"


def test_the_longest_agreeing_demonstration_is_the_reference_the_first_listed_on_a_tie():
    short, program = DEMO[:2], DEMO[:2] + acts("release(obj20)")
    assert classify(program, DONE, [], False, [short]) == "stopped_late"
    assert classify(program, DONE, [], False, [DEMO, short]) == "wrong_primitive"  # both agree for two steps
    assert classify(program, DONE, [], False, [short, DEMO]) == "stopped_late"
    longer = DEMO[:3] + acts("release(obj20)")
    assert classify(longer, DONE, [], False, [short, DEMO]) == "wrong_primitive"  # DEMO agrees longer


def test_failure_counts_are_exact_and_in_kind_order():
    counts = failure_counts(["stopped_late", "exact", "stopped_late", "wrong_object"])
    assert list(counts) == list(KINDS)
    assert counts == {k: {"stopped_late": 2, "exact": 1, "wrong_object": 1}.get(k, 0) for k in KINDS}
    assert failure_counts([]) == dict.fromkeys(KINDS, 0)


def _ctx(gold: tuple[int, int, int]) -> StepContext:
    import numpy as np

    return StepContext(["a", "b", "c"], np.zeros((3, 1)), np.zeros((3, 4)), np.zeros((3, 3), dtype=bool), 0,
                       (0, 0), (-1, -1, -1, -1), gold)


def _seq(sid, task, prim, arg, goal, safe, success, failure):
    return SequenceOutcome(sid, task, (), DONE, prim, arg, goal, safe, success, failure)


# five programs whose rates all differ: prim 80, arg 40, goal 60, success 20 (percent)
SEQUENCES = [
    _seq("e/pour(a)", "pour", True, True, True, True, True, "exact"),
    _seq("e/pour(b)", "pour", True, True, True, False, False, "exact"),
    _seq("e/stir(a)", "stir", True, False, True, False, False, "unsafe_step"),
    _seq("e/stir(b)", "stir", True, False, False, True, False, "wrong_object"),
    _seq("e/stir(c)", "stir", False, False, False, True, False, "step_cap"),
]


def test_summary_rates_each_come_from_their_own_field():
    g = ALL_PRIMITIVES.index("grasp")
    contexts = [_ctx((g, 0, -1)), _ctx((g, 1, -1))]
    results = [FoldResult("m", 0, [0], [(g, 0, -1)], SEQUENCES[:2]),
               FoldResult("m", 1, [1], [(g, 2, -1)], SEQUENCES[2:])]
    both = summarize(results + [FoldResult("mc", 0, [0, 1], [(g, 0, -1), (g, 0, -1)], None)], contexts,
                     {"m": True, "mc": False})
    assert both["mc"]["steps"]["grasp/prim"] == 100.0 and both["mc"]["steps"]["grasp/arg"] is None
    assert both["mc"]["steps"]["average/prim"] == 100.0 and "sequence/arg" not in both["mc"]
    s = both["m"]
    assert (s["sequence/prim"], s["sequence/arg"], s["goal_reached"], s["success"]) == (80.0, 40.0, 60.0, 20.0)
    assert s["n_scenarios"] == 5 and s["n_steps"] == 2
    assert s["steps"]["grasp/prim"] == 100.0 and s["steps"]["grasp/arg"] == 50.0
    assert s["programs"] == {k: {"exact": 2, "unsafe_step": 1, "wrong_object": 1, "step_cap": 1}.get(k, 0)
                             for k in KINDS}
    assert s["per_task"]["pour"] == {"sequence/arg": 100.0, "success": 50.0, "n": 2,
                                     "programs": {k: 2 if k == "exact" else 0 for k in KINDS}}
    assert s["per_task"]["stir"]["sequence/arg"] == 0.0 and s["per_task"]["stir"]["n"] == 3
    head = headline_metrics({"m": s})["m"]
    assert head == {"average_prim": 100.0, "average_arg": 50.0, "sequence_prim": 80.0, "sequence_arg": 40.0,
                    "success": 20.0, "goal_reached": 60.0}


def test_step_accuracy_keeps_done_out_of_the_average_and_confusion_counts_pairs():
    g, r, d = (ALL_PRIMITIVES.index(p) for p in ("grasp", "release", "done"))
    contexts = [_ctx((g, 0, -1)), _ctx((r, 0, -1)), _ctx((d, -1, -1))]
    preds = [(g, 0, -1), (g, 0, -1), (d, -1, -1)]
    acc = step_accuracy(contexts, preds)
    assert acc["average/prim"] == 50.0 and acc["done/prim"] == 100.0 and acc["release/arg"] == 0.0
    m = confusion(contexts, preds)
    assert m[g, g] == 1 and m[r, g] == 1 and m[d, d] == 1 and m.sum() == 3 and m.dtype.kind == "i"
    assert confusion(contexts * 2, preds * 2)[r, g] == 2
    for f in (step_accuracy, confusion):  # predictions that do not line up with the steps are refused
        with pytest.raises(ValueError, match="zip"):
            f(contexts, preds[:2])


def _cand(C, arg, success):
    return {"C": C, "sequence_arg": arg, "success": success, "average_arg": 0.0}


def test_c_is_the_candidate_with_the_best_sequence_accuracy():
    cands = [_cand(0.5, 60.0, 90.0), _cand(2.0, 75.0, 70.0), _cand(8.0, 70.0, 95.0)]
    assert best_candidate(cands)["C"] == 2.0
    assert best_candidate(list(reversed(cands)))["C"] == 2.0


def test_a_tie_in_sequence_accuracy_goes_to_the_higher_success_rate():
    assert best_candidate([_cand(0.5, 70.0, 80.0), _cand(8.0, 70.0, 85.0), _cand(2.0, 60.0, 99.0)])["C"] == 8.0


def test_a_tie_in_both_goes_to_the_smaller_c():
    assert best_candidate([_cand(8.0, 70.0, 80.0), _cand(0.5, 70.0, 80.0), _cand(2.0, 70.0, 80.0)])["C"] == 0.5


def test_figures_equal_to_nine_decimals_tie():
    near = 70.0 + 1e-12  # the same figure summed in another order
    assert best_candidate([_cand(0.5, 70.0, 80.0), _cand(2.0, near, 80.0)])["C"] == 0.5
    assert best_candidate([_cand(0.5, 70.0, 80.0), _cand(2.0, 70.0 + 1e-6, 80.0)])["C"] == 2.0
    assert best_candidate([_cand(0.5, 70.0, 80.0), _cand(2.0, 70.0 + 2e-10, 80.0)])["C"] == 0.5
    assert best_candidate([_cand(0.5, 70.0, 80.0), _cand(2.0, 70.0, 80.0 + 2e-10)])["C"] == 0.5
    assert best_candidate([_cand(0.5, 70.0, 80.2), _cand(2.0, 70.0, 80.4)])["C"] == 2.0  # not rounded to whole


def test_the_criterion_is_written_as_applied_and_no_candidates_is_an_error():
    assert CRITERION == "sequence_arg, then success, then the smaller C"
    with pytest.raises(ValueError, match="^select: no candidates to choose from$"):
        best_candidate([])
