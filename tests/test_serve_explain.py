"""The assist table says why each proposal stands where it stands: its score, and what the lookahead found.

A scorer scripted by the last steps (as in tests/test_lookahead.py) makes the
lookahead's choice known in advance: in env02 the glass a pour(milk) needs
stands on a shelf, and the script scores grasping the milk carton right away
(then pouring over the shelf) above fetching the glass first. The shipped
policy proposes the glass first; the table must say why.
"""

from __future__ import annotations

import re

from taskseq.features.context import candidate_index, step_context
from taskseq.plan.planner import DONE, lookahead
from taskseq.product import runnable_first
from taskseq.serve.explain import explain
from taskseq.sim.catalog import ENVIRONMENTS_BY_ID, build_environment
from taskseq.sim.primitives import Action, execute
from taskseq.sim.safety import RULES
from taskseq.sim.tasks import Task

GLASS, CARTON = "obj15", "obj21"
TASK = Task.parse("pour(obj28)")  # the milk, in the carton
RUSH = ["move_close(obj15)", "grasp(obj21)", "hold_above(obj21,obj15)", "follow_traj_pour(obj21,obj15)"]
FETCH = ["move_close(obj15)", "grasp(obj15)", "place_above(obj15,obj03)", "release(obj15)", "grasp(obj21)",
         "move_close(obj15)", "hold_above(obj21,obj15)", "follow_traj_pour(obj21,obj15)"]


class ScriptedScorer:
    """Ranks `script["last steps"]` first, then `done`, then every other candidate in index order."""

    def __init__(self, script: dict[str, list[str]]) -> None:
        self.script = script

    def ranked(self, ctx):
        history = " ".join(map(str, ctx.history()))
        wanted = [ctx.encode(Action.parse(a)) for a in self.script.get(history, [])]
        done = ctx.encode(Action(DONE))
        rest = [tuple(y) for y in zip(*(a.tolist() for a in candidate_index(ctx.n)), strict=True)
                if tuple(y) not in wanted and tuple(y) != done]
        return iter([(y, float(-i)) for i, y in enumerate([*wanted, done, *rest])])

    def top_k(self, ctx, k):
        return list(self.ranked(ctx))[:k]


def script() -> dict[str, list[str]]:
    out: dict[str, list[str]] = {}
    for plan in (FETCH, RUSH):
        for k in range(len(plan)):
            out[" ".join(plan[max(0, k - 2):k])] = [plan[k]]
    out[RUSH[0]] = [RUSH[1], FETCH[1]]  # at the glass: the carton scores first, the glass second
    return out


def proposals_at_the_glass():
    room = build_environment(ENVIRONMENTS_BY_ID["env02"])
    scorer = ScriptedScorer(script())
    first = Action.parse(RUSH[0])
    state = execute(room, first)
    ctx = step_context(state, TASK, [first])
    ranked = runnable_first(lookahead(scorer, TASK, room, 3), scorer, TASK, room, 3)(ctx, state)
    return room, state, ctx, ranked, explain(scorer, "lookahead", TASK, room, ctx, state, ranked)


def test_a_step_above_a_better_scored_one_says_the_lookahead_found_that_plan_unsafe():
    room, state, ctx, ranked, why = proposals_at_the_glass()
    names = {o: s.name for o, s in room.specs.items()}
    glass, carton, shelf = names[GLASS], names[CARTON], names[room.support[GLASS][0]]
    actions = [str(ctx.action(y)) for y, _ in ranked]
    assert actions[:2] == [f"grasp({GLASS})", f"grasp({CARTON})"] and ranked[0][1] < ranked[1][1]
    assert why[0].startswith(f"moved up above grasp({carton}) (0.00): the lookahead found its plan breaks")
    assert f"looking ahead (grasp({glass}), " in why[0] and "it breaks no safety rule" in why[0]
    # its clauses, as the assist table folds them: the first shown, the imagined plan under it
    assert why[0].parts[0] == (f"moved up above grasp({carton}) (0.00): the lookahead found its plan breaks a safety "
                               "rule")
    assert why[0].parts[1].startswith("looking ahead (") and "; ".join(why[0].parts) == why[0]
    assert why[1] == (f"demoted: its plan would take grasp({carton}), hold_above({carton}, {glass}), then "
                      f"follow_traj_pour({carton}, {glass}), where it breaks the safety rule \u201c"
                      f"{RULES['over_shelf']}\u201d: {glass} is on {shelf}; bring it to a table first")


def test_reasons_use_names_never_ids_or_none_and_count_what_cannot_run():
    room, state, ctx, ranked, why = proposals_at_the_glass()
    assert len(why) == len(ranked) == 3
    # done scores above the third, and is not due yet; the two better-scored steps are listed above it
    assert why[2] == "moved up: a step scored above it cannot run here (done: the goal of pour(milk) does not hold yet)"
    for text in why:
        assert text and not re.search(r"\bobj\d+\b", text) and "None" not in text


def test_done_above_better_scored_steps_says_the_goal_holds():
    # the milk is poured; the script would move on to the counter, scored above `done`
    room = build_environment(ENVIRONMENTS_BY_ID["env02"])
    plan = [*FETCH, "move_close(obj03)"]
    scorer = ScriptedScorer({" ".join(plan[max(0, k - 2):k]): [plan[k]] for k in range(len(plan))})
    state, history = room, []
    for text in FETCH:
        state, history = execute(state, Action.parse(text)), [*history, Action.parse(text)]
    ctx = step_context(state, TASK, history)
    ranked = runnable_first(lookahead(scorer, TASK, room, 3), scorer, TASK, room, 3)(ctx, state)
    why = explain(scorer, "lookahead", TASK, room, ctx, state, ranked)
    assert [str(ctx.action(y)) for y, _ in ranked][:2] == ["done()", "move_close(obj03)"]
    counter = room.specs["obj03"].name
    assert why[0].startswith(f"moved up above move_close({counter}) (0.00): the goal holds, and the lookahead stops")
    assert why[1] == "below done: the goal holds, and the robot stops once it does"


CYCLE = {"": ["move_close(obj15)"], "move_close(obj15)": ["move_close(obj21)"],
         "move_close(obj15) move_close(obj21)": ["move_close(obj15)"],
         "move_close(obj21) move_close(obj15)": ["move_close(obj21)"]}  # back and forth between glass and carton


def assisted(script: dict[str, list[str]], tmp_path):
    """The web app's planner (`Served`) ranking with a scripted lookahead, as `taskseq serve` runs a model file's, and
    an assist activity of pour(milk) in env02 at its start."""
    from taskseq.serve.app import Served
    from taskseq.serve.environments import Environment
    from taskseq.serve.sessions import Activity

    room = build_environment(ENVIRONMENTS_BY_ID["env02"])
    scorer = ScriptedScorer(script)
    served = Served(tmp_path, tmp_path / "model.npz", 3)
    served._policy_for = lambda task, initial: runnable_first(lookahead(scorer, task, initial, 3), scorer, task,
                                                              initial, 3)
    served._planner, served._policy_name = scorer, "lookahead"
    return served, Activity(Environment("env02", "env02", room), TASK, "assist", None)


def test_the_assist_table_passes_over_a_step_that_would_close_a_loop_and_says_why(tmp_path):
    """The web app ranks as `taskseq plan` runs (`plan.planner.out_of_loops`): the script walks between the glass
    and the carton, and where going back to the carton would close a loop the page proposes another step first,
    naming the loop as the reason."""
    served, activity = assisted(CYCLE, tmp_path)
    for text in ["move_close(obj15)", "move_close(obj21)"]:
        shown, _ = served.candidates(activity)
        assert str(shown[0].action) == text  # no loop yet: the script's step comes first
        activity.step(Action.parse(text))
    shown, _ = served.candidates(activity)
    assert str(shown[0].action) == "move_close(obj15)"  # the glass again: a world met, but with other steps before
    activity.step(Action.parse("move_close(obj15)"))
    shown, _ = served.candidates(activity)
    carton = activity.env.state.specs[CARTON].name
    assert str(shown[0].action) != "move_close(obj21)"  # back to the carton would close the loop
    assert shown[0].why.startswith(f"moved up above move_close({carton}) (0.00): it would lead back to where this "
                                   "task already was, with the same last two steps")
    looped = next(c for c in shown if str(c.action) == "move_close(obj21)")
    assert looped.why.startswith("demoted: it leads back to where this task already was")


def test_a_step_demoted_for_its_unsafe_plan_is_not_said_to_close_a_loop(tmp_path):
    """Going back to the carton would close a loop, but the lookahead demotes it already for the pour over the
    shelf its plan leads to, so the rule against loops never acts: the page gives the safety reason only."""
    walk = ["move_close(obj15)", "move_close(obj21)", "move_close(obj15)"]
    script = {**CYCLE, "move_close(obj21) move_close(obj15)": ["move_close(obj21)", "grasp(obj15)"],
              "move_close(obj15) move_close(obj21)": ["grasp(obj21)"],
              "move_close(obj21) grasp(obj21)": ["hold_above(obj21,obj15)"],
              "grasp(obj21) hold_above(obj21,obj15)": ["follow_traj_pour(obj21,obj15)"]}
    served, activity = assisted(script, tmp_path)
    for text in walk:
        activity.step(Action.parse(text))
    shown, _ = served.candidates(activity)
    assert [str(c.action) for c in shown[:2]] == ["grasp(obj15)", "move_close(obj21)"]
    assert "the lookahead found its plan breaks a safety rule" in shown[0].why and "loop" not in shown[0].why
    assert shown[1].why.startswith("demoted: its plan would") and "loop" not in shown[1].why


class ScoredScorer:
    """Ranks the given steps first with the given scores, then every other candidate below them."""

    def __init__(self, scores: list[tuple[str, float]]) -> None:
        self.scores = scores

    def ranked(self, ctx):
        wanted = [(ctx.encode(Action.parse(a)), score) for a, score in self.scores]
        low = min(score for _, score in self.scores) - 1
        rest = [tuple(y) for y in zip(*(a.tolist() for a in candidate_index(ctx.n)), strict=True)
                if tuple(y) not in {y for y, _ in wanted}]
        return iter([*wanted, *((y, low - i) for i, y in enumerate(rest))])


def test_a_proposal_scored_the_same_as_the_one_above_says_so():
    """Two proposals of 1.40 and 1.40 (as the table shows them, to two decimals) are a tie, not "the next score
    down"; a lower score still is."""
    room = build_environment(ENVIRONMENTS_BY_ID["env02"])
    ctx = step_context(room, TASK, [])
    for scores, said in [
        ([2.0, 1.4, 1.4], ["the best score of all the steps", "the next score down",
                           "the same score as the step above"]),
        ([1.4012, 1.3995, 0.7], ["the best score of all the steps", "the same score as the step above",
                                 "the next score down"]),
        ([2.0, 1.4, 1.39], ["the best score of all the steps", "the next score down", "the next score down"])]:
        steps = list(zip(["move_close(obj15)", "move_close(obj21)", "move_close(obj03)"], scores, strict=True))
        scorer = ScoredScorer(steps)
        offered = [(ctx.encode(Action.parse(a)), score) for a, score in steps]
        why = explain(scorer, "feasible", TASK, room, ctx, room, offered)
        assert why == said and [w.parts for w in why] == [(w,) for w in said]
