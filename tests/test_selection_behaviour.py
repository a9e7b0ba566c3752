"""Choosing each method's C: every value tried is cross-validated with that C, a grid whose best is at an edge is
extended until the best is inside or the cap stops it (recorded), the documented rule picks and ranks; the
selection file is read back with errors that name what is wrong."""

from __future__ import annotations

import argparse
import json
import math

import pytest

from taskseq.demonstrations.benchmark import Benchmark
from taskseq.evaluate.methods import ScorerMethod
from taskseq.experiments import selection
from taskseq.experiments.crossval import FoldResult, SequenceOutcome
from taskseq.experiments.selection import (
    DevData,
    choose_C,
    cross_validate_settings,
    rank_methods,
)
from taskseq.features.context import StepContext
from taskseq.methods import Lineup
from taskseq.selection import UNTUNED_C, Selection, read_selection
from taskseq.settings import Folds, Learner, Params, Replay
from taskseq.sim.primitives import ALL_PRIMITIVES
from taskseq.stages import fold_models as fold_models_stage
from taskseq.stages import train as train_stage
from taskseq.stages.command import load_params
from taskseq.stages.options import TrainOptions

GRASP = ALL_PRIMITIVES.index("grasp")
# per C: sequences right (of 4), successes (of 4), steps with the right arguments (of 2)
FIGURES = {0.5: (2, 4, 1), 2.0: (3, 1, 2), 8.0: (3, 2, 0)}


def _ctx(gold):
    import numpy as np

    return StepContext(["a", "b"], np.zeros((2, 1)), np.zeros((2, 4)), np.zeros((2, 2), dtype=bool), 0, (0, 0),
                       (-1, -1, -1, -1), gold)


def _fake_fold_runs(calls):
    """Stand-ins for fitting the fold models and cross-validating from them: each records what it is given and
    returns figures that depend on the method's own C only."""
    def train_fold_models(methods, contexts, meta, scenarios, jobs, output, n_jobs, verbose):
        calls.append(("fit", sorted((name, make().C, make().store) for name, make in methods.items()), output))
        calls.append({"fit data": (contexts, meta, scenarios), "jobs": jobs, "workers": (n_jobs, verbose)})
        return [{"from_cache": name.startswith("full")} for name in methods]  # one record per model

    def cross_validate(methods, contexts, meta, bench, n_folds, seed, group_by, max_steps, n_jobs, verbose):
        calls.append({"data": (contexts, meta, bench), "n_folds": n_folds, "seed": seed, "group_by": group_by,
                      "max_steps": max_steps, "workers": (n_jobs, verbose)})
        out = []
        for name, make in methods.items():
            method = make()
            assert method.name == name
            right, successes, args = FIGURES[method.C]
            calls.append((name, method.C, method.tol, method.max_iter, method.policy, method.store))
            seqs = [SequenceOutcome(f"s{i}", "pour", (), "done", True, i < right, i < successes, True, i < successes,
                                    "exact") for i in range(4)]
            preds = [(GRASP, 0, -1) if i < args else (GRASP, 1, -1) for i in range(2)]
            out.append(FoldResult(name, 0, [0, 1], preds, seqs))
        return out

    return train_fold_models, cross_validate


def test_each_method_is_cross_validated_at_each_of_its_own_values_of_c(monkeypatch, tmp_path, capsys):
    calls = []
    fit, cv = _fake_fold_runs(calls)
    monkeypatch.setattr(selection, "train_fold_models", fit)
    monkeypatch.setattr(selection, "cross_validate", cv)
    planned = []

    def training_jobs(methods, meta, scenarios, n_folds, seed, group_by, chained):
        planned.append((sorted(methods), meta, scenarios, n_folds, seed, group_by, chained))
        return "the jobs"

    monkeypatch.setattr(selection, "training_jobs", training_jobs)
    contexts, meta = [_ctx((GRASP, 0, -1)), _ctx((GRASP, 0, -1))], ["m0", "m1"]
    bench = Benchmark([], {"s": "a scenario"}, {}, {})
    data = DevData(contexts, meta, bench, Folds(folds=3, seed=4, group_by="environment"), 9)
    store = tmp_path / "models"
    # each value of C is tried as it is, not an earlier choice of the method's own C
    lineup = Lineup(Params.load().methods, Selection({"full": 77.0, "feasible": 66.0}, source="x"),
                    Learner(tol=0.02, max_iter=7))
    out = cross_validate_settings({"full": (0.5, 2.0), "feasible": (8.0,)}, lambda m, c: lineup.at_C(c).factory(m),
                                  data, store, n_jobs=3, verbose=2)
    # every model the three settings need, planned on the development world's folds (no chained starts there)
    assert planned == [(["feasible C=8", "full C=0.5", "full C=2"], meta, bench.scenarios, 3, 4, "environment", ())]
    assert calls[0] == ("fit", [("feasible C=8", 8.0, None), ("full C=0.5", 0.5, None), ("full C=2", 2.0, None)],
                        store)  # fitted without a store, into it
    assert calls[1] == {"fit data": (contexts, meta, bench.scenarios), "jobs": "the jobs", "workers": (3, 2)}
    assert "3 models, 2 of them read back from the fit cache" in capsys.readouterr().out
    assert calls[2] == {"data": (contexts, meta, bench), "n_folds": 3, "seed": 4, "group_by": "environment",
                        "max_steps": 9, "workers": (3, 2)}
    assert calls[3:] == [("full C=0.5", 0.5, 0.02, 7, "greedy", str(store)), ("full C=2", 2.0, 0.02, 7, "greedy",
                                                                             str(store)),
                         ("feasible C=8", 8.0, 0.02, 7, "feasible", str(store))]  # then run from it
    assert out == {"full": {0.5: {"sequence_arg": 50.0, "success": 100.0, "average_arg": 50.0},
                            2.0: {"sequence_arg": 75.0, "success": 25.0, "average_arg": 100.0}},
                   "feasible": {8.0: {"sequence_arg": 75.0, "success": 50.0, "average_arg": 0.0}}}


def _peaked(peaks, rounds):
    """A hand-made score: each method's sequence arg falls with the distance of log C from its peak; every call
    is recorded, so the test sees which values each round tried."""
    def evaluate(pending):
        rounds.append(pending)
        return {m: {c: {"sequence_arg": 100.0 - abs(math.log(c / peaks[m])), "success": 50.0, "average_arg": 0.0}
                    for c in values} for m, values in pending.items()}

    return evaluate


GRID = (0.3, 1.0, 3.0, 10.0)  # spacing 10/3 at the top, 1/0.3 at the bottom


def test_a_best_inside_the_grid_stops_at_once():
    rounds = []
    chosen = choose_C(["full"], GRID, _peaked({"full": 1.2}, rounds), max_extensions=2)
    assert rounds == [{"full": GRID}]
    assert chosen["full"]["C"] == 1.0 and chosen["full"]["extensions"] == 0 and not chosen["full"]["capped"]
    assert [r["C"] for r in chosen["full"]["candidates"]] == list(GRID)


def test_a_best_at_an_edge_is_extended_by_the_grid_spacing_until_it_is_inside():
    rounds = []
    chosen = choose_C(["full", "dagger", "relations"], GRID, _peaked({"full": 30.0, "dagger": 0.1, "relations": 2.0},
                                                                     rounds), max_extensions=3)
    # only the methods at an edge go on, each one value beyond its own edge per round
    assert rounds[1:] == [{"full": (33.3333,), "dagger": (0.09,)}, {"full": (111.111,), "dagger": (0.027,)}]
    assert chosen["full"] == {"C": 33.3333, "extensions": 2, "capped": False, "candidates": [
        {"C": c, "sequence_arg": 100.0 - abs(math.log(c / 30.0)), "success": 50.0, "average_arg": 0.0}
        for c in (*GRID, 33.3333, 111.111)]}
    assert (chosen["dagger"]["C"], chosen["dagger"]["extensions"], chosen["dagger"]["capped"]) == (0.09, 2, False)
    assert (chosen["relations"]["C"], chosen["relations"]["extensions"]) == (3.0, 0)


def test_the_cap_stops_the_extension_and_is_recorded():
    rounds = []
    chosen = choose_C(["full"], GRID, _peaked({"full": 1000.0}, rounds), max_extensions=2)
    assert [r["full"] for r in rounds] == [GRID, (33.3333,), (111.111,)]
    assert chosen["full"]["C"] == 111.111 and chosen["full"]["extensions"] == 2 and chosen["full"]["capped"]
    rounds.clear()
    chosen = choose_C(["full"], GRID, _peaked({"full": 1000.0}, rounds), max_extensions=0)
    assert rounds == [{"full": GRID}] and chosen["full"]["C"] == 10.0 and chosen["full"]["capped"]


def test_ties_go_to_the_smaller_c_and_a_one_value_grid_is_refused():
    flat = lambda pending: {m: {c: {"sequence_arg": 60.0, "success": 80.0, "average_arg": 0.0} for c in v}  # noqa: E731
                            for m, v in pending.items()}
    chosen = choose_C(["full"], (1.0, 3.0), flat, max_extensions=1)
    assert chosen["full"]["C"] == 0.333333 and chosen["full"]["capped"]  # the smaller edge, so extended downwards once
    with pytest.raises(ValueError, match=r"^select: the grid of C needs at least two values \(its spacing is how it "
                                         r"is extended\)$"):
        choose_C(["full"], (3.0,), flat, max_extensions=1)


def test_methods_are_ranked_each_at_its_own_c_by_sequence_arg_then_success_then_the_order_listed():
    figures = {"full": (60.0, 80.0), "relations": (60.0, 85.0), "dagger": (70.0, 70.0), "chained": (60.0, 80.0)}
    settings = {m: {"C": 3.0 if m == "dagger" else 1.0, "candidates": [
        {"C": 1.0, "sequence_arg": a, "success": s, "average_arg": 90.0},
        {"C": 3.0, "sequence_arg": a, "success": s, "average_arg": 90.0}]} for m, (a, s) in figures.items()}
    settings = {m: settings[m] for m in ("full", "chained", "relations", "dagger")}
    ranked = rank_methods(settings)
    assert [(r["method"], r["C"]) for r in ranked] == [("dagger", 3.0), ("relations", 1.0), ("full", 1.0),
                                                       ("chained", 1.0)]
    with pytest.raises(ValueError, match=r"^select: no MRF methods to rank \(no method of params.yaml's methods "
                                         r"section names select\)$"):
        rank_methods({})


def _ranked(figures: dict[str, tuple[float, float]]) -> list[str]:
    """The ranking of methods chosen at C = 1 with these (sequence arg, success); at C = 3, worse figures."""
    return [r["method"] for r in rank_methods({m: {"C": 1.0, "candidates": [
        {"C": 3.0, "sequence_arg": 0.0, "success": 0.0, "average_arg": 0.0},
        {"C": 1.0, "sequence_arg": a, "success": s, "average_arg": 90.0}]} for m, (a, s) in figures.items()})]


def test_a_ranking_reads_each_methods_figures_at_its_chosen_c_and_ties_within_rounding():
    assert _ranked({"a": (60.0, 50.0), "b": (70.0, 40.0)}) == ["b", "a"]
    # figures that differ past the ninth decimal are equal (sums of the same programs in another order)
    assert _ranked({"a": (60.0 + 4e-10, 50.0), "b": (60.0, 90.0)}) == ["b", "a"]
    assert _ranked({"b": (60.0, 80.0), "a": (60.0, 80.0 + 4e-10)}) == ["b", "a"]  # a tie: the order listed
    # but not whole points apart
    assert _ranked({"a": (60.4, 50.0), "b": (60.0, 90.0)}) == ["a", "b"]
    assert _ranked({"a": (60.0, 80.4), "b": (60.0, 80.0)}) == ["a", "b"]
    assert _ranked({"b": (60.0, 80.0), "a": (60.0, 80.4)}) == ["a", "b"]


def test_the_method_ranked_first_is_read_back_or_the_file_says_what_is_missing(tmp_path):
    path = tmp_path / "selection.json"
    path.write_text(json.dumps({"C": 3, "method": "choice_lookahead", "settings": {}}))
    assert read_selection(path).method == "choice_lookahead"
    paths = TrainOptions(selection=path, model=tmp_path / "m.npz")
    assert train_stage.shipped_method(Params().train, paths)[0] == "choice_lookahead"
    for data in ({"C": 3}, {"C": 3, "method": ""}, {"C": 3, "method": 7}):
        path.write_text(json.dumps({**data, "settings": {}}))
        assert read_selection(path).method is None
        with pytest.raises(ValueError, match=f"^{path}: no field 'method' \\(the method ranked first\\); the file "
                                             "predates the ranking of methods: run `taskseq select` again, or name "
                                             "the method with --set train.method=NAME$"):
            train_stage.shipped_method(Params().train, paths)


def test_read_selection_returns_each_methods_c_and_nothing_else(tmp_path):
    path = tmp_path / "selection.json"
    path.write_text(json.dumps({"C": 3, "settings": {"full": {"C": 3}, "dagger": {"C": 33.3333, "capped": True}}}))
    selection = read_selection(path)
    assert selection == Selection({"full": 3.0, "dagger": 33.3333}, None, str(path))
    assert selection.of("dagger") == 33.3333 and isinstance(selection.of("full"), float)
    # the top-level C is the full model's for the summary, not everyone's fallback: a method without its own is an
    # error that says how to give it one
    with pytest.raises(ValueError, match=f"^{path}: no C for method relations: add select to "
                                         "methods.relations.experiments in params.yaml"):
        selection.of("relations")
    path.write_text(json.dumps({"C": 2, "settings": {"full": {"C": 0.25}}}))
    assert read_selection(path).of("full") == 0.25  # below 1 is a valid slack weight
    # no file at all: every method at the documented untuned C
    assert read_selection(None).of("anything") == UNTUNED_C == 3.0


@pytest.mark.parametrize("text, message", [
    ("{not json", "not valid JSON"),
    (json.dumps({"C": 2}), "field 'settings' must map each method to its choice, got None; run `taskseq select`"),
    (json.dumps([2.0]), "field 'settings' must map each method to its choice, got None"),
    (json.dumps({"C": 1, "settings": {"full": {"C": 0}}}), "field 'settings.full.C' must be a positive number, got 0"),
    (json.dumps({"C": 1, "settings": {"full": {"C": True}}}), "got True"),
    (json.dumps({"C": 1, "settings": {"full": {"C": "2"}}}), "got '2'"),
    (json.dumps({"C": 1, "settings": [1]}), "field 'settings' must map each method to its choice"),
    (json.dumps({"C": 1, "settings": {"dagger": {"C": -3}}}), "field 'settings.dagger.C' must be a positive number"),
    (json.dumps({"C": 1, "settings": {"dagger": 3}}), "field 'settings.dagger.C' .* got None"),
])
def test_read_selection_names_the_file_and_what_is_wrong(tmp_path, text, message):
    path = tmp_path / "selection.json"
    path.write_text(text)
    with pytest.raises(ValueError, match=f"{path}: .*{message}"):
        read_selection(path)


def test_a_missing_selection_file_says_how_to_make_it(tmp_path):
    with pytest.raises(FileNotFoundError, match="no selection file; run `dvc repro select`"):
        read_selection(tmp_path / "none.json")


def test_every_stage_builds_each_mrf_method_with_its_own_c(tmp_path):
    """From the selection file to the methods the evaluation stages and `train` build: each ranked method at its
    own C, the rest (the paper's ablations) at the full model's."""
    path = tmp_path / "selection.json"
    path.write_text(json.dumps({"C": 2, "settings": {"full": {"C": 2}, "dagger": {"C": 0.5}, "feasible": {"C": 8}}}))
    params = load_params(argparse.Namespace(params=None, overrides=[]))
    selection = read_selection(path)
    for learner in (params.train.learner, Replay.of(params).learner, train_stage.settings(params).train.learner,
                    fold_models_stage.settings(params).learner):
        lineup = Lineup(params.methods, selection, learner)
        made = {name: lineup.factory(name)() for name in ("only_edge", "only_clique", "full", "dagger", "feasible")}
        assert {name: m.C for name, m in made.items()} == {"only_edge": 2.0, "only_clique": 2.0, "full": 2.0,
                                                           "dagger": 0.5, "feasible": 8.0}
        with pytest.raises(ValueError, match="no C for method relations"):  # not the full model's: an error
            lineup.factory("relations")
    assert made["feasible"].policy == "feasible" and made["dagger"].policy == "greedy"
    assert made["feasible"].key([_ctx((GRASP, 0, -1))]) != made["dagger"].key([_ctx((GRASP, 0, -1))])  # C differs
    with pytest.raises(ValueError, match="unknown setting train.tuned"):
        load_params(argparse.Namespace(params=None, overrides=["train.tuned=full"]))


def test_an_unknown_policy_is_refused():
    with pytest.raises(ValueError, match="method full: unknown policy 'cautious'; known: greedy, feasible"):
        ScorerMethod(policy="cautious")


def test_the_development_worlds_size_is_checked_where_params_are_read():
    with pytest.raises(ValueError, match="select.environments must be at least 1, got 0"):
        Params.load(None, ["select.environments=0"])
    assert Params.load(None, ["select.environments=1"]).select.environments == 1


@pytest.fixture(scope="module")
def dev_data(benchmark_tables):
    """Three environments of the benchmark as a development world, cross-validated over two folds."""
    from taskseq.features.dataset import build_steps

    records = [i.record for i in benchmark_tables[1] if i.record["env_id"] in ("env01", "env02", "env03")]
    contexts, meta = build_steps(records)
    return DevData(contexts, meta, Benchmark.from_records(records), Folds(folds=2, seed=0, group_by="scenario"), 30)


def _weights(store):
    from taskseq.learn.store import ModelStore

    index = json.loads((store / "index.json").read_text())["models"]
    return {m["key"]: ModelStore(store).load(m["key"]).w_.tobytes() for m in index}


def test_a_method_chosen_alone_fits_the_same_models_as_beside_the_plain_method_of_its_features(dev_data, tmp_path):
    """Chained starts start from the plain model of their features (`fold_models.plan_tasks`); chosen alone, the
    grid's round fits those plain models too, so its models, and so its figures, are the bytes it gets beside the
    method of its features that is plain."""
    lineup = Lineup(Params.load().methods, learner=Learner(tol=0.01, max_iter=200))

    def make(name, C):
        return lineup.at_C(C).factory(name)

    grid = (0.5, 2.0)
    beside = cross_validate_settings({"relations": grid, "chained": grid}, make, dev_data, tmp_path / "beside")
    alone = cross_validate_settings({"chained": grid}, make, dev_data, tmp_path / "alone", plain_at=grid)
    cold = cross_validate_settings({"chained": grid}, make, dev_data, tmp_path / "cold")
    assert alone["chained"] == beside["chained"]
    chained = _weights(tmp_path / "alone")
    assert chained.items() <= _weights(tmp_path / "beside").items()  # the plain models and chained starts' own
    assert set(_weights(tmp_path / "cold")) < set(chained)  # without plain_at: no plain models ...
    assert not _weights(tmp_path / "cold").items() <= chained.items()  # ... and chained starts fitted from scratch
    assert cold.keys() == {"chained"}


def test_a_methods_grid_round_fits_the_plain_models_of_its_features_and_an_extension_round_does_not(
        monkeypatch, tmp_path):
    rounds = []

    def cross_validate_settings(pending, make, data, store, n_jobs, verbose, plain_at):
        rounds.append((pending, store, plain_at))
        return {m: {c: {"sequence_arg": c, "success": 0.0, "average_arg": 0.0} for c in values}
                for m, values in pending.items()}  # best at the largest C: the grid is extended upwards

    monkeypatch.setattr(selection, "cross_validate_settings", cross_validate_settings)
    choice, seconds = selection.choose_method_C("chained", "make", "data", (3.0, 1.0), 1, tmp_path)
    assert rounds == [({"chained": (1.0, 3.0)}, tmp_path / "0", (1.0, 3.0)),
                      ({"chained": (9.0,)}, tmp_path / "1", ())]
    assert choice["C"] == 9.0 and choice["extensions"] == 1 and choice["capped"] and len(seconds) == 2


@pytest.mark.parametrize("richer, plain", [("chained", "relations"), ("dagger", "relations"),
                                           ("noise_trained", "relations"), ("drawn_rooms", "choice"),
                                           ("relations", "relations")])
def test_a_methods_plain_model_is_the_plain_method_of_its_features(richer, plain):
    """`ScorerMethod.plain` drops every kind of added training data and keeps the rest: its model is the one the
    plain method of the same features fits (the same key), the start of the richer method's fits."""
    lineup = Lineup(Params.load().methods).at_C(2.0)
    made, expected = lineup.factory(richer)().plain(), lineup.factory(plain)()
    assert made.features == expected.features and made.learner_params() == expected.learner_params()
    assert made.key([]) == expected.key([])


def test_a_methods_choice_of_c_reads_its_own_entry_of_params_alone(monkeypatch, tmp_path):
    # dvc.yaml's choose_C runs list methods.NAME, not the whole section: an edit of another method's entry must not
    # be able to change this choice
    from taskseq.stages import choose_C as stage
    from taskseq.stages.options import ChooseCOptions

    seen = []

    class Stop(Exception):
        pass

    def chosen(*args, **kwargs):
        raise Stop

    monkeypatch.setattr(stage, "read_manifest", lambda world: {"seed": 99})
    monkeypatch.setattr(stage, "read_features", lambda folder: ([], []))
    monkeypatch.setattr(stage, "load_benchmark", lambda folder: Benchmark([], {}, {}, {}))
    monkeypatch.setattr(stage, "Lineup", lambda methods, **kw: seen.append(methods) or Lineup(methods, **kw))
    monkeypatch.setattr(stage, "choose_method_C", chosen)
    settings = stage.settings(Params.load())
    with pytest.raises(Stop):
        stage.run(settings, ChooseCOptions(world=tmp_path, method="noise_trained", output=tmp_path / "c.json"))
    assert seen[0].entries == ((("noise_trained", settings.methods.entry("noise_trained")),))
    assert len(settings.methods.entries) > 1 and not (tmp_path / "c.json").exists()
