"""The outcome cache: a fold's outcomes read back are the outcomes run, and whatever decides them misses it."""

from __future__ import annotations

from dataclasses import replace
from functools import partial

import pytest

from taskseq.demonstrations.benchmark import Benchmark
from taskseq.evaluate.methods import ChanceMethod, MulticlassMethod, ScorerMethod, SymbolicMethod, configured
from taskseq.experiments import crossval, outcome_cache, robustness
from taskseq.experiments.robustness import FeedbackCondition, NoiseCondition, evaluate_conditions
from taskseq.features.dataset import build_steps
from taskseq.methods import Lineup
from taskseq.runtime import cache
from taskseq.settings import Folds, Methods

MRF = partial(ScorerMethod, "full", C=3.0, tol=1e-2, name="full")
METHODS = {"chance": ChanceMethod, "multiclass": MulticlassMethod, "symb_plan_manual": SymbolicMethod, "full": MRF}
CONDITIONS = [NoiseCondition(0.0, 0), NoiseCondition(0.2, 1), FeedbackCondition(2, 1)]


@pytest.fixture(scope="module")
def small(benchmark_tables):
    records = [i.record for i in benchmark_tables[1] if i.record["env_id"] in ("env01", "env02")]
    contexts, meta = build_steps(records)
    return contexts, meta, Benchmark.from_records(records)


@pytest.fixture
def cache_dir(tmp_path, monkeypatch):
    monkeypatch.setenv(cache.CACHE_ENV, str(tmp_path / "cache"))
    return tmp_path / "cache" / "outcomes"


@pytest.fixture
def runs(monkeypatch):
    """The fold jobs that ran their programs (not read back), as (method, kind)."""
    calls = []
    tested, replayed = crossval._tested, robustness._replayed

    def counted_tested(method, *args):
        calls.append((method.name, "crossval"))
        return tested(method, *args)

    def counted_replayed(method, *args):
        calls.append((method.name, "robustness"))
        return replayed(method, *args)

    monkeypatch.setattr(crossval, "_tested", counted_tested)
    monkeypatch.setattr(robustness, "_replayed", counted_replayed)
    return calls


def _cv(small, methods=METHODS, max_steps=20, **kw):
    contexts, meta, bench = small
    return crossval.cross_validate(methods, contexts, meta, bench, n_folds=2, max_steps=max_steps, **kw)


def test_outcomes_read_back_are_the_outcomes_run(small, cache_dir, runs, monkeypatch):
    monkeypatch.delenv(cache.CACHE_ENV)
    uncached = _cv(small)
    monkeypatch.setenv(cache.CACHE_ENV, str(cache_dir.parent))
    runs.clear()
    first = _cv(small)
    assert len(runs) == 2 * len(METHODS) and len(list(cache_dir.rglob("*.json"))) == 2 * len(METHODS)
    runs.clear()
    again = _cv(small)
    assert runs == []  # every fold job read back
    assert again == first == uncached  # predictions, sequences (and no programs) alike, field by field
    assert any(r.sequences is None for r in again) and any(r.sequences for r in again)  # multiclass runs none


def test_replayed_conditions_read_back_are_those_run(small, cache_dir, runs, monkeypatch):
    contexts, meta, bench = small
    monkeypatch.delenv(cache.CACHE_ENV)
    uncached = evaluate_conditions({"full": MRF}, contexts, meta, bench.scenarios, CONDITIONS, Folds(folds=2), 20)
    monkeypatch.setenv(cache.CACHE_ENV, str(cache_dir.parent))
    first = evaluate_conditions({"full": MRF}, contexts, meta, bench.scenarios, CONDITIONS, Folds(folds=2), 20)
    runs.clear()
    again = evaluate_conditions({"full": MRF}, contexts, meta, bench.scenarios, CONDITIONS, Folds(folds=2), 20)
    assert runs == [] and again == first == uncached
    assert {type(c) for c, _ in again["full"]} == {NoiseCondition, FeedbackCondition}
    evaluate_conditions({"full": MRF}, contexts, meta, bench.scenarios, CONDITIONS, Folds(folds=2), 20, seed=1)
    assert runs == [("full", "robustness")] * 2  # another noise seed: other draws, run again


def test_a_baseline_read_back_is_not_fitted_unless_a_kept_program_needs_it(small, cache_dir, monkeypatch):
    contexts, meta, bench = small
    kept = frozenset(sorted(bench.scenarios)[:2])
    svm = partial(SymbolicMethod, goals="svm", name="symb_plan_svm")
    baselines = {"chance": ChanceMethod, "multiclass": MulticlassMethod, "symb_plan_svm": svm}
    first = _cv(small, baselines, keep_programs={"symb_plan_svm": kept})
    fits = []
    for kind in (ChanceMethod, MulticlassMethod, SymbolicMethod):
        def counted(self, *args, _fit=kind.fit, **kw):
            fits.append(self.name)
            return _fit(self, *args, **kw)
        monkeypatch.setattr(kind, "fit", counted)
    assert _cv(small, baselines) == [replace(r, programs={}) for r in first]
    assert fits == []  # read back: the key never held their fitted state, so nothing was fitted
    assert _cv(small, baselines, keep_programs={"symb_plan_svm": kept}) == first  # the kept programs run again,
    holding = {r.fold for r in first if r.programs}
    assert holding and fits == ["symb_plan_svm"] * len(holding)  # fitted for them, in the folds that hold them


def test_whatever_decides_a_fold_misses_the_cache(small, cache_dir, runs):
    _cv(small, {"full": MRF})
    runs.clear()
    _cv(small, {"full": partial(MRF, C=1.0)})  # other weights
    _cv(small, {"full": partial(MRF, policy="feasible")})  # another setting
    _cv(small, {"full": MRF}, max_steps=5)  # another step cap
    contexts, meta, bench = small
    sid = sorted(bench.scenarios)[0]
    first = bench.scenarios[sid]
    changed = {**bench.scenarios, sid: replace(first, demonstrations=first.demonstrations[:1] + ((),))}
    _cv((contexts, meta, replace(bench, scenarios=changed)), {"full": MRF})  # a scenario judged otherwise
    assert runs == [("full", "crossval")] * 2 * 4



def test_programs_kept_for_recordings_are_run_again_from_an_entry(small, cache_dir, runs, monkeypatch):
    contexts, meta, bench = small
    kept = frozenset(sorted(bench.scenarios)[:3])
    monkeypatch.delenv(cache.CACHE_ENV)
    uncached = _cv(small, {"full": MRF}, keep_programs={"full": kept})
    monkeypatch.setenv(cache.CACHE_ENV, str(cache_dir.parent))
    _cv(small, {"full": MRF}, keep_programs={"full": kept})
    runs.clear()
    again = _cv(small, {"full": MRF}, keep_programs={"full": kept})
    assert runs == []  # the fold's outcomes read back; only the kept programs ran
    assert again == uncached  # the programs too, state by state
    assert sorted(sid for r in again for sid in r.programs) == sorted(kept)


def test_where_a_model_was_found_changes_nothing_but_its_weights_do(small, cache_dir, runs, tmp_path):
    from taskseq.learn.store import ModelStore

    contexts, meta, bench = small
    _cv(small, {"full": MRF})
    runs.clear()
    _cv(small, {"full": partial(configured, MRF, store=str(tmp_path / "empty"))})  # the same fits, via a store
    assert runs == []
    # a store whose models under these keys were trained otherwise (here: the same settings, on half the steps):
    # other weights, a miss
    store = ModelStore(tmp_path / "other")
    for test in crossval.scenario_folds(bench.scenarios, 2, 0, "scenario"):
        train = [contexts[i] for i in crossval.training_index(meta, test)]
        store.save(MRF().key(train), MRF().estimator().fit(train[: len(train) // 2]), {})
    _cv(small, {"full": partial(configured, MRF, store=str(tmp_path / "other"))})
    assert runs == [("full", "crossval")] * 2


def test_a_method_module_and_the_experiment_code_are_in_the_key(small, cache_dir, runs, monkeypatch):
    lineup = Lineup(Methods())
    make = lineup.factory("noise_trained")
    assert "taskseq.methods.noise_trained" in outcome_cache._factory_modules(make)
    assert outcome_cache._factory_modules(partial(configured, make, store="x")) >= {
        "taskseq.methods.noise_trained", "taskseq.evaluate.methods"}
    assert "taskseq.methods.noise_trained" not in outcome_cache._factory_modules(lineup.factory("full"))
    from taskseq.runtime.sources import code_fingerprint

    _cv(small, {"full": MRF})
    runs.clear()
    edited = {"taskseq.experiments.crossval"}
    monkeypatch.setattr(outcome_cache, "code_fingerprint",
                        lambda m: "edited" if m in edited else code_fingerprint(m))
    _cv(small, {"full": MRF})
    assert runs == [("full", "crossval")] * 2


def test_an_unreadable_entry_is_run_again_and_replaced(small, cache_dir, runs):
    first = _cv(small, {"chance": ChanceMethod})
    entries = sorted(cache_dir.rglob("*.json"))
    entries[0].write_text("{not json")
    runs.clear()
    with pytest.warns(UserWarning, match="unreadable entry of the cache is run again"):
        again = _cv(small, {"chance": ChanceMethod})
    assert again == first and len(runs) == 1
    runs.clear()
    assert _cv(small, {"chance": ChanceMethod}) == first and runs == []  # replaced


def test_a_cache_that_is_a_file_is_refused(tmp_path, monkeypatch):
    not_a_folder = tmp_path / "cache"
    not_a_folder.write_text("")
    monkeypatch.setenv(cache.CACHE_ENV, str(not_a_folder))
    with pytest.raises(ValueError, match="TASKSEQ_CACHE=.*not a folder"):
        outcome_cache.OutcomeCache.active()
    with pytest.raises(ValueError, match="--cache .*not a folder"), cache.folder(not_a_folder):
        pass


def test_a_taught_planners_outcomes_read_back_are_those_run(small, cache_dir, monkeypatch):
    from taskseq.experiments.teaching import judged

    contexts, meta, bench = small
    tested = [bench.scenarios[sid] for sid in sorted(bench.scenarios)[:4]]
    ran, run = [], ScorerMethod.run
    monkeypatch.setattr(ScorerMethod, "run", lambda self, *args: ran.append(1) or run(self, *args))
    first = judged(MRF, MRF().fit(contexts, meta), tested, 20)
    assert len(ran) == len(tested)
    again = judged(MRF, MRF().fit(contexts, meta), tested, 20)
    assert again == first and len(ran) == len(tested)  # read back, none run again
    judged(MRF, MRF().fit(contexts[: len(contexts) // 2], meta[: len(meta) // 2]), tested, 20)  # other weights
    assert len(ran) == 2 * len(tested)
