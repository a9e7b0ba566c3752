"""Cross-validation pieces: folds that never leak, metrics on hand-made predictions, the tables."""

import re

import numpy as np
import pytest

from taskseq.demonstrations.benchmark import Benchmark
from taskseq.evaluate.folds import grouped_folds
from taskseq.evaluate.methods import ChanceMethod, MulticlassMethod
from taskseq.evaluate.metrics import step_accuracy, summarize
from taskseq.experiments.crossval import FoldResult, SequenceOutcome, run_fold, scenario_folds
from taskseq.features.context import StepContext
from taskseq.report.tables import table_rows, to_csv, to_latex, to_markdown
from taskseq.sim.primitives import ALL_PRIMITIVES


def test_grouped_folds_cover_everything_once_and_never_split_a_group():
    groups = [f"s{i % 17}" for i in range(100)]
    folds = grouped_folds(groups, 6, seed=0)
    seen = np.concatenate(folds)
    assert sorted(seen) == list(range(100))
    for k, idx in enumerate(folds):
        inside = {groups[i] for i in idx}
        others = {groups[i] for j, f in enumerate(folds) if j != k for i in f}
        assert not inside & others
    assert [f.tolist() for f in folds] == [f.tolist() for f in grouped_folds(groups, 6, seed=0)]
    with pytest.raises(ValueError, match="cannot fill"):
        grouped_folds(["a", "b"], 3, seed=0)


@pytest.fixture(scope="module")
def scenarios(benchmark_tables):
    return Benchmark.from_records([i.record for i in benchmark_tables[1]]).scenarios


@pytest.mark.parametrize("group_by", ["scenario", "environment"])
def test_benchmark_folds_never_leak(scenarios, group_by):
    folds = scenario_folds(scenarios, 6, seed=0, group_by=group_by)
    assert sorted(s for f in folds for s in f) == sorted(scenarios)
    if group_by == "environment":
        envs = [{scenarios[s].env_id for s in f} for f in folds]
        assert all(not a & b for i, a in enumerate(envs) for b in envs[i + 1 :])


class Recorder:
    """A method that remembers what it was trained on."""

    name, predicts_args = "recorder", True

    def fit(self, contexts, meta, scenarios=None):
        self.trained = contexts
        Recorder.last = self
        return self

    def predict_steps(self, contexts, meta, demos):
        return [x.gold for x in contexts]

    def run(self, scenario, max_steps):
        return None


def test_a_fold_trains_on_no_step_of_its_test_scenarios(benchmark_steps, scenarios):
    contexts, meta = benchmark_steps
    test = scenario_folds(scenarios, 6, seed=0, group_by="scenario")[2]
    result = run_fold(Recorder, 2, contexts, meta, scenarios, test, max_steps=20)
    trained = {id(x) for x in Recorder.last.trained}
    assert all(meta[i].scenario_id in test for i in result.step_index)
    assert not any(id(contexts[i]) in trained for i in result.step_index)
    assert len(trained) + len(result.step_index) == len(contexts)


def _step(prim: str, a1: int = -1, a2: int = -1) -> StepContext:
    return StepContext(["o0", "o1", "o2"], np.zeros((3, 20)), np.zeros((3, 4)), np.zeros((3, 3), bool), 0,
                       (8, 8), (-1, -1, -1, -1), (ALL_PRIMITIVES.index(prim), a1, a2))


def test_step_accuracy_on_hand_made_predictions():
    steps = [_step("grasp", 0), _step("grasp", 1), _step("place_above", 0, 2), _step("done")]
    g = ALL_PRIMITIVES.index("grasp")
    preds = [(g, 0, -1), (g, 2, -1), (g, 0, -1), (ALL_PRIMITIVES.index("done"), -1, -1)]
    acc = step_accuracy(steps, preds)
    assert acc["grasp/prim"] == 100.0 and acc["grasp/arg"] == 50.0
    assert acc["place_above/prim"] == 0.0 and acc["place_above/arg"] == 0.0
    assert acc["average/prim"] == pytest.approx(200 / 3) and acc["average/arg"] == pytest.approx(100 / 3)
    assert acc["done/arg"] == 100.0  # done is kept out of the average


def _outcome(sid, task, prim, arg, success):
    return SequenceOutcome(sid, task, (), "done", prim, arg, success, True, success,
                           "exact" if arg else ("other_success" if success else "wrong_object"))


def test_summary_pools_folds_and_hides_arguments_a_method_does_not_predict():
    steps = [_step("grasp", 0), _step("release", 1)]
    g, r = ALL_PRIMITIVES.index("grasp"), ALL_PRIMITIVES.index("release")
    results = [
        FoldResult("m", 0, [0], [(g, 0, -1)], [_outcome("a", "pour", True, True, True)]),
        FoldResult("m", 1, [1], [(r, 0, -1)], [_outcome("b", "stir", True, False, False)]),
        FoldResult("mc", 0, [0, 1], [(g, -1, -1), (g, -1, -1)], None),
    ]
    s = summarize(results, steps, {"m": True, "mc": False})
    assert s["m"]["steps"]["average/arg"] == 50.0 and s["m"]["sequence/prim"] == 100.0
    assert s["m"]["sequence/arg"] == 50.0 and s["m"]["per_task"]["pour"]["success"] == 100.0
    assert s["mc"]["steps"]["average/arg"] is None and "sequence/arg" not in s["mc"]


def test_tables_have_one_row_per_method_and_balanced_latex():
    summary = {
        "a": {"steps": {"grasp/prim": 50.0, "grasp/arg": 25.0, "average/prim": 50.0, "average/arg": 25.0},
              "sequence/prim": 10.0, "sequence/arg": 5.0},
        "b": {"steps": {"grasp/prim": 90.0, "grasp/arg": None, "average/prim": 90.0, "average/arg": None}},
    }
    rows = table_rows(summary, {"a": "ours - full"})
    assert {r["method"] for r in rows} == {"ours - full", "b"}
    csv = to_csv(rows)
    assert csv.splitlines()[0] == "method,column,prim,arg" and "b,sequence,," in csv
    tex = to_latex(rows, "caption")
    assert tex.count("{") == tex.count("}")
    assert tex.count("\\begin{") == tex.count("\\end{")
    body = [line for line in tex.splitlines() if line.startswith("\\textit{")]
    assert len(body) == 2 and all(line.count("&") == 18 for line in body)
    assert "\\textbf{90.0}" in tex and "\\textbf{25.0}" in tex
    assert re.search(r"\| b \| - \| - \|", to_markdown(rows))


def test_chance_is_deterministic_and_multiclass_predicts_no_arguments(benchmark_steps):
    contexts, _ = benchmark_steps
    a = ChanceMethod(seed=3).predict_steps(contexts[:50])
    assert a == ChanceMethod(seed=3).predict_steps(contexts[:50]) != ChanceMethod(seed=4).predict_steps(contexts[:50])
    mc = MulticlassMethod().fit(contexts[:300], None)
    preds = mc.predict_steps(contexts[300:400])
    assert all(a1 == -1 and a2 == -1 for _, a1, a2 in preds)
    assert np.mean([p == x.gold[0] for (p, _, _), x in zip(preds, contexts[300:400], strict=True)]) > 0.5


def test_the_symbolic_planners_of_a_fold_share_a_job_and_results_keep_the_methods_order(benchmark_steps, scenarios,
                                                                                          monkeypatch):
    """Their SAT problems coincide where their roles agree, which one process then solves once: the two symbolic
    baselines of a fold run in one job, every other method alone, and the results come back method by method."""
    from functools import partial

    from taskseq.evaluate.methods import SymbolicMethod
    from taskseq.experiments import crossval

    calls = []

    keep = {"symb_plan_manual": frozenset({"s1"}), "multiclass": frozenset({"s2"})}

    def fake(makes, fold, *args):
        names = tuple(make().name for make in makes)
        calls.append((names, fold))
        assert args[-1] == tuple(keep.get(name, frozenset()) for name in names)  # each method its recordings
        return [FoldResult(name, fold, [], [], None) for name in names]

    monkeypatch.setattr(crossval, "run_folds", fake)
    methods = {"chance": ChanceMethod, "symb_plan_svm": partial(SymbolicMethod, goals="svm", name="symb_plan_svm"),
               "multiclass": MulticlassMethod, "symb_plan_manual": SymbolicMethod}
    contexts, meta = benchmark_steps
    bench = Benchmark(scenarios=scenarios, records=[], states={}, actions={})
    results = crossval.cross_validate(methods, contexts, meta, bench, n_folds=3, n_jobs=1, keep_programs=keep)
    assert [(r.method, r.fold) for r in results] == [(name, k) for name in methods for k in range(3)]
    assert sorted(calls) == sorted([(("symb_plan_svm", "symb_plan_manual"), k) for k in range(3)]
                                   + [((name,), k) for name in ("chance", "multiclass") for k in range(3)])
