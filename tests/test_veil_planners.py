"""The symbolic planner and the MRF's goal lookahead on an invented release (the fixture of test_veil_evaluate).

"Tea Beaker" fills a beaker with tea at the tub (five steps), "Tidy Honey" puts the honey on the tub (four);
the planner must find those shortest plans in a kitchen it never saw, stop where the goal holds, and follow its
best partial plan when the search is cut short. The lookahead is checked against a scripted base ranking.
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pytest

from taskseq.veil import experiment
from taskseq.veil.evaluate import Executor, Run, derive_goals, env_number, lift, rollout, split
from taskseq.veil.experiment import Settings, run_experiment, tables
from taskseq.veil.grounding import Step
from taskseq.veil.lookahead import GoalLookahead
from taskseq.veil.metrics import goal_share
from taskseq.veil.persist import TrainedModel, load_mrf, save_mrf
from taskseq.veil.release import read_release
from taskseq.veil.replay import replay_release
from taskseq.veil.symbolic import SymbolicPlanner, groundings, relevant_categories, search
from tests.test_veil_evaluate import release_dir  # noqa: F401  (the invented release, a module fixture)


@pytest.fixture(scope="module")
def data(release_dir: Path):  # noqa: F811
    release = read_release(release_dir)
    reps = replay_release(release)
    train, test = split(reps, frozenset({4}))
    return release, train, test


def _first(test, objective):
    return next(r for r in test if r.point.objective == objective)


def test_relevant_categories_are_those_named_by_at_least_a_quarter_of_an_objectives_sequences(data) -> None:
    _, train, _ = data
    relevant = relevant_categories(train)
    # the wasted `moveto Teapot_1` is in half of the Tea Beaker sequences: at 0.25 it counts, at 0.6 it does not
    assert relevant["Tea Beaker"] == {"beaker", "tub", "tubknob", "teapot"}
    assert relevant_categories(train, share=0.6)["Tea Beaker"] == {"beaker", "tub", "tubknob"}
    assert relevant["Tidy Honey"] == {"honey", "tub"}


@pytest.mark.parametrize(("objective", "length"), [("Tea Beaker", 5), ("Tidy Honey", 4)])
def test_the_planner_finds_a_shortest_plan_to_the_whole_goal_in_a_kitchen_it_never_saw(data, objective, length
                                                                                       ) -> None:
    release, train, test = data
    executor = Executor(release)
    planner = SymbolicPlanner(executor).fit(train)
    start = _first(test, objective).initial
    plan = planner.plan(start, objective)
    assert plan.share == 1.0 and len(plan.steps) == length
    steps, final, refused, stopped = rollout(planner, executor, start, objective, "plain", 40)
    assert list(steps) == list(plan.steps) and refused == 0 and stopped
    assert goal_share(lift(final), derive_goals(train)[objective]) == 1.0
    assert next(planner.ranked(final, steps, objective)) == Step("done")  # the goal holds: it stops


def test_a_search_cut_short_follows_the_shortest_path_to_the_best_share_it_found(data) -> None:
    release, train, test = data
    executor = Executor(release)
    start = _first(test, "Tea Beaker").initial
    goal = derive_goals(train)["Tea Beaker"]  # beaker on the tub, tea in it, the tub running: three facts
    moves = groundings(executor, start.world, list(start.world.objects))
    whole = search(start, goal, moves, max_nodes=100000)
    assert whole.share == 1.0 and len(whole.steps) == 5
    cut = search(start, goal, moves, max_nodes=20)
    # within 20 states only one fact of three is reached, the tub running, and by its shortest way
    assert cut.share == pytest.approx(1 / 3)
    assert cut.steps == (Step("moveto", "Tub"), Step("turn", "TubKnob"))
    state = start
    for s in cut.steps:
        state = executor.after(state, s)
        assert state is not None
    assert goal_share(lift(state), goal) == cut.share
    assert search(start, goal, moves, max_nodes=0) == type(cut)((), 0.0, 0)


def test_an_objective_without_a_goal_stops_at_once_and_the_planner_predicts_no_next_step(data) -> None:
    release, train, test = data
    planner = SymbolicPlanner(Executor(release)).fit([r for r in train if r.point.objective == "Tea Beaker"])
    assert list(planner.ranked(_first(test, "Tidy Honey").initial, [], "Tidy Honey")) == [Step("done")]
    assert planner.predicts_next_step is False


@dataclass
class Scripted:
    """A base ranking written out: for each history length, the steps in order (then `done`)."""

    order: dict[int, list[Step]]
    C: float = 1.0
    name: str = "scripted"
    fits: list[int] = field(default_factory=list)

    def fit(self, train) -> Scripted:
        self.fits.append(len(train))
        return self

    def ranked(self, state, history, objective) -> Iterator[Step]:
        yield from self.order.get(len(history), [])
        yield Step("done")


def test_the_lookahead_takes_the_option_whose_imagined_run_reaches_more_of_the_goal(data) -> None:
    release, train, test = data
    executor = Executor(release)
    start = _first(test, "Tidy Honey").initial
    wander, go = Step("moveto", "Teapot_1"), Step("moveto", "Honey_1")
    # the base's first choice wanders and then stops; its second leads, by the base's own next choices, to the goal
    base = Scripted({0: [wander, go], 1: [Step("grasp", "Honey_1")], 2: [Step("moveto", "Tub")],
                     3: [Step("keep_on", "Honey_1", "Tub")]})
    method = GoalLookahead("look", base, executor).fit(train)
    assert base.fits == [len(train)]
    ranking = list(method.ranked(start, [], "Tidy Honey"))
    assert ranking[0] == go and ranking[1:3] == [wander, Step("done")]
    steps, final, _, stopped = rollout(method, executor, start, "Tidy Honey", "feasible", 10)
    assert steps == [go, Step("grasp", "Honey_1"), Step("moveto", "Tub"), Step("keep_on", "Honey_1", "Tub")]
    assert stopped and goal_share(lift(final), method.goals_["Tidy Honey"]) == 1.0


def test_the_lookahead_keeps_the_models_order_where_imagination_sees_no_difference_and_stops_at_the_goal(
        data) -> None:
    release, train, test = data
    executor = Executor(release)
    start = _first(test, "Tidy Honey").initial
    a, b = Step("moveto", "Teapot_1"), Step("moveto", "Beaker_1")
    method = GoalLookahead("look", Scripted({0: [a, b]}), executor, depth=4).with_goals(train)
    assert list(method.ranked(start, [], "Tidy Honey"))[:2] == [a, b]
    # an objective without a goal: the base's ranking as it is
    method.goals_ = {}
    assert list(method.ranked(start, [], "Tidy Honey")) == [a, b, Step("done")]
    # where the goal holds, `done` comes first whatever the base ranks first
    method.with_goals(train)
    state = start
    for s in [Step("moveto", "Honey_1"), Step("grasp", "Honey_1"), Step("moveto", "Tub"),
              Step("keep_on", "Honey_1", "Tub")]:
        state = executor.after(state, s)
    assert next(method.ranked(state, [], "Tidy Honey")) == Step("done")


def test_the_lookahead_row_shares_its_base_rows_fit_and_C_and_the_planner_row_prints_no_next_step(
        release_dir: Path, monkeypatch) -> None:  # noqa: F811
    fits: list[str] = []
    real = experiment.DomainScorer.fit

    def spy(self, train):
        fits.append(self.name)
        return real(self, train)

    monkeypatch.setattr(experiment.DomainScorer, "fit", spy)
    goals_from: list[set[int]] = []
    real_goals = GoalLookahead.with_goals

    def goals_spy(self, train):
        goals_from.append({env_number(r.point.env_id) for r in train})
        return real_goals(self, train)

    monkeypatch.setattr(GoalLookahead, "with_goals", goals_spy)
    settings = Settings(folds=2, C_grid=(1.0,), max_steps=8, resamples=50,
                        methods=("symbolic_planner", "mrf_categories", "mrf_categories_lookahead"))
    report = run_experiment(release_dir, settings)
    assert fits == ["mrf_categories", "mrf_categories"]  # one fit per fold, for both rows
    # the lookahead's goals come from its fold's training environments only
    assert goals_from == [{1, 2, 3, 4} - set(f["held_out"]) for f in report["folds"]]
    for fold in report["folds"]:
        assert fold["C"]["mrf_categories_lookahead"] == fold["C"]["mrf_categories"]
        assert fold["width"] == {"mrf_categories_lookahead": 3}
    planner = report["closed_loop"]["symbolic_planner/feasible"]["goal_share"]
    assert planner["mean"] == 1.0
    assert report["next_step"]["symbolic_planner"]["both"]["mean"] is None
    text = tables(report)
    assert "| symbolic planner toward the derived goal | - | - | - |" in text
    # both folds derive both goals: Tea Beaker's three facts, Tidy Honey's one (sizes only, never the names)
    assert report["folds"][0]["goal_facts"] == report["folds"][1]["goal_facts"] == [3, 1]
    assert "| 1 | 2 of 2 | 3, 1 |" in text and "Tidy Honey" not in text and "Tub" not in text
    assert "| ours - full + categories + goal lookahead | 1; 3 | 1; 3 |" in text


def test_the_lookahead_width_is_the_one_whose_inner_runs_reach_most_of_the_goal(data, monkeypatch) -> None:
    release, train, _ = data
    objectives = sorted({r.point.objective for r in train})
    settings = Settings(folds=2, C_grid=(1.0,), max_steps=8, lookahead_widths=(8, 2, 5))
    seen: list[int] = []

    fit_on, inner_check = experiment.inner_split(train, settings, "x")

    def runs(method, executor, check_on, goals, policy, max_steps):
        seen.append(method.width)
        # runs on the inner held-out environments, toward the goals of the inner training ones
        assert check_on == inner_check and goals == method.goals_ == derive_goals(fit_on)
        return [Run("s", "e", "o", (), 0, True, {2: 0.2, 5: 0.5, 8: 0.5}[method.width], None, False)]

    monkeypatch.setattr(experiment, "closed_loop", runs)
    assert experiment.choose_width("mrf_categories", 1.0, release, objectives, train, settings) == 5
    assert seen == [2, 5, 8]  # in order; the tie of 5 and 8 goes to the smaller


def test_a_model_for_use_is_the_one_the_choices_and_fit_give_in_one_process(release_dir: Path) -> None:  # noqa: F811
    """`train_model` runs the final fit and each width's inner runs as separate jobs: the same width and the same
    weights, to the bit, as `choose_width` and the fit one after the other in this process."""
    settings = Settings(folds=2, C_grid=(1.0, 10.0), max_steps=8, lookahead_widths=(3, 1))
    trained = experiment.train_model(release_dir, settings, n_jobs=2)
    release = read_release(release_dir)
    replays = replay_release(release)
    name, C, fits = experiment.choose_model(release, replays, settings)
    objectives = sorted({r.point.objective for r in replays})
    assert trained.method.name == name and trained.method.C == C
    assert trained.lookahead_width == experiment.choose_width(name, C, release, objectives, replays, settings, fits)
    alone = experiment.make_method(name, release, objectives, settings, C).fit(replays)
    assert np.array_equal(trained.method.w_, alone.w_)


def test_the_lookahead_keeps_the_models_choice_per_state_and_last_two_steps(data) -> None:
    """The kept choices are keyed by the last two steps: a history differing two steps back is another key."""
    release, train, test = data
    start = _first(test, "Tidy Honey").initial
    a, b = Step("moveto", "Teapot_1"), Step("moveto", "Beaker_1")

    class TwoBack(Scripted):
        def ranked(self, state, history, objective):
            yield a if len(history) >= 2 and history[-2] == a else b

    method = GoalLookahead("look", TwoBack({}), Executor(release)).with_goals(train)
    assert method.first(start, [a, b], "Tidy Honey")[0] == a
    assert method.first(start, [b, b], "Tidy Honey")[0] == b
    assert method.first(start, [b, a, b], "Tidy Honey")[0] == a  # only the last two count


def test_a_model_file_keeps_the_lookaheads_width_and_refuses_another_format(data, tmp_path: Path) -> None:
    release, train, _ = data
    objectives = sorted({r.point.objective for r in train})
    method = experiment.make_method("mrf_categories", release, objectives, Settings(C_grid=(1.0,)), 1.0).fit(train)
    path = tmp_path / "m.npz"
    save_mrf(path, TrainedModel(method, derive_goals(train), ["kitchen1"], 5))
    model, meta = load_mrf(path)
    assert model.lookahead_width == 5 and model.goals == derive_goals(train) and model.trained_on == ["kitchen1"]
    assert (model.method.w_ == method.w_).all()
    meta["format"] = "taskseq.veil-mrf/1"
    np.savez(path, w=method.w_, meta=np.array(json.dumps(meta)))
    with pytest.raises(ValueError, match="veil-mrf/1"):
        load_mrf(path)
    # a model of `taskseq train` is named as one, and a file that is no archive is not blamed on pickles
    np.savez(path, w=method.w_, meta=np.array(json.dumps({"format": "taskseq.mrf/3"})))
    with pytest.raises(ValueError, match="a model of `taskseq train`.*not a VEIL-500 model"):
        load_mrf(path)
    path.write_text("# not a model\n")
    with pytest.raises(ValueError, match="not the .npz archive `taskseq veil train` writes") as err:
        load_mrf(path)
    assert "pickle" not in str(err.value)


def test_rows_that_make_the_same_fits_share_them(release_dir: Path, monkeypatch) -> None:  # noqa: F811
    """Rows of one feature set and row content differ only in how they choose C or run the model: each fold fits
    each C once on its inner split and each chosen C once on its training environments, for all three rows."""
    fits: list[tuple[float, int]] = []
    real = experiment.DomainScorer.fit

    def spy(self, train):
        fits.append((self.C, len(train)))
        return real(self, train)

    monkeypatch.setattr(experiment.DomainScorer, "fit", spy)
    rows = ("mrf_categories", "mrf_categories_goal", "mrf_categories_lookahead")
    assert experiment.fit_groups(("chance", *rows)) == [("chance",), rows]
    report = run_experiment(release_dir, Settings(folds=2, C_grid=(1.0, 10.0), max_steps=8, resamples=50,
                                                  methods=rows, lookahead_widths=(1, 3)))
    expected = sum(2 + len({fold["C"]["mrf_categories"], fold["C"]["mrf_categories_goal"]})
                   for fold in report["folds"])
    assert len(fits) == expected


def test_the_executor_keeps_a_steps_outcome_per_state_never_across_states(data) -> None:
    """A step the domain refuses at the start and runs later gets each outcome from one executor, as from a fresh
    one, asked in either order and again; the kept outcomes are dropped whole when there are too many."""
    release, _, test = data
    replay = next(r for r in test if len(r.kept) > 1)
    states = replay.states
    k, later = next((k, s) for k, s in enumerate(replay.kept) if Executor(release).after(replay.initial, s) is None)
    executor = Executor(release)
    for state in (replay.initial, states[k], replay.initial, states[k]):
        assert executor.after(state, later) == Executor(release).after(state, later)
    assert executor.after(replay.initial, later) is None and executor.after(states[k], later) is not None
    executor.KEPT_OUTCOMES = 1
    assert executor.after(replay.initial, replay.kept[0]) is not None and len(executor._outcomes) == 1
