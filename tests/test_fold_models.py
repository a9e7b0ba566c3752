"""Fold models are trained once by the `fold_models` stage and served to every evaluation stage."""

from dataclasses import replace
from functools import partial
from pathlib import Path

import pytest

from taskseq.demonstrations.benchmark import Benchmark
from taskseq.demonstrations.generate import generate
from taskseq.demonstrations.ingest import load_logs
from taskseq.evaluate.methods import ScorerMethod
from taskseq.experiments.crossval import cross_validate
from taskseq.experiments.fold_models import plan_tasks, train_fold_models, training_jobs
from taskseq.experiments.recipes import evaluate_recipes
from taskseq.experiments.robustness import NoiseCondition, evaluate_conditions
from taskseq.features.dataset import build_steps
from taskseq.learn.estimator import StepScorer
from taskseq.methods import Lineup, specs
from taskseq.selection import Selection
from taskseq.settings import Folds, Generate, Learner, Methods, Procedural
from taskseq.sim.procedural import NEW_KINDS

SETTINGS = {"C": 3.0, "tol": 1e-2, "max_iter": 2000, "n_slacks": 0}
# two of the paper's models and both that consult the demonstrator (chained starts, DAgger)
METHODS = Lineup(Methods(), Selection(dict.fromkeys(specs(), SETTINGS["C"]), source="s"),
                 Learner(SETTINGS["tol"], SETTINGS["max_iter"], SETTINGS["n_slacks"])).mrf(
    ["only_edge", "full", "chained", "dagger"])


def _steps(records: list[dict]) -> tuple:
    contexts, meta = build_steps(records)
    return records, contexts, meta, Benchmark.from_records(records).scenarios


def _train(steps: tuple, out: Path, n_jobs: int) -> tuple:
    """The fold models of METHODS on `steps`, stored in `out`: (out, jobs, index rows)."""
    records, contexts, meta, scenarios = steps
    jobs = training_jobs(METHODS, meta, scenarios, n_folds=2, seed=0, group_by="scenario",
                         recipe_methods=("full", "chained", "choice_chained_lookahead"))
    return out, jobs, train_fold_models(METHODS, contexts, meta, scenarios, jobs, out, n_jobs=n_jobs)


@pytest.fixture(scope="module")
def small(benchmark_tables):
    return _steps([i.record for i in benchmark_tables[1] if i.record["env_id"] in ("env01", "env02", "env03")])


@pytest.fixture(scope="module")
def store(small, tmp_path_factory):
    return _train(small, tmp_path_factory.mktemp("store") / "folds", n_jobs=1)


@pytest.fixture(scope="module")
def drawn(tmp_path_factory):
    """Two rooms of a procedural world, with objects of kinds the catalog never had."""
    folder = tmp_path_factory.mktemp("drawn") / "raw"
    generate(Generate(seed=1, family="procedural", procedural=Procedural(environments=2)), folder)
    records = [r.record for r in load_logs(folder)[1]]
    new = {k.name for kinds in NEW_KINDS.values() for k in kinds}
    assert any(o["name"] in new for r in records for o in r["objects"])
    return _steps(records)


@pytest.fixture(scope="module")
def drawn_store(drawn, tmp_path_factory):
    return _train(drawn, tmp_path_factory.mktemp("drawn_store") / "folds", n_jobs=2)  # loky's processes


@pytest.fixture
def count_fits(monkeypatch):
    calls = []

    real = StepScorer.fit

    def counting(self, *args, **kwargs):
        calls.append(self.n_slacks)
        return real(self, *args, **kwargs)

    monkeypatch.setattr(StepScorer, "fit", counting)
    return calls


def test_each_distinct_model_is_trained_once_and_indexed(store):
    out, jobs, fitted = store
    assert len(jobs) == 4 * 2 + 2 * 4  # four MRF methods x two folds; full and chained x four recipe kinds
    assert len({r["key"] for r in fitted}) == len(fitted)
    assert sum(len(r["uses"]) for r in fitted) == len(jobs)  # identical training sets share one model
    assert all(r["converged"] for r in fitted)
    assert sorted(p.name for p in out.iterdir()) == sorted([*(f"{r['key']}.npz" for r in fitted), "index.json"])


def test_evaluation_stages_load_the_stored_models_without_training(small, store, count_fits):
    records, contexts, meta, scenarios = small
    out, _, _ = store
    mrf = partial(ScorerMethod, **SETTINGS, store=str(out))
    methods = {"full": partial(mrf, "full", name="full"), "only_edge": partial(mrf, "edge", name="only_edge")}
    cross_validate(methods, contexts, meta, Benchmark.from_records(records), n_folds=2)
    evaluate_conditions({"full": partial(mrf, "full")}, contexts, meta, scenarios, [NoiseCondition(0.1, 0)],
                        Folds(folds=2), max_steps=20)
    evaluate_recipes(partial(mrf, "full"), contexts, meta, scenarios)
    evaluate_recipes(lambda: replace(METHODS["chained"](), store=str(out)), contexts, meta, scenarios)
    cross_validate({"dagger": lambda: replace(METHODS["dagger"](), store=str(out))}, contexts, meta,
                   Benchmark.from_records(records), n_folds=2)
    assert count_fits == []


def test_other_settings_are_never_served_from_the_store(small, store, count_fits):
    records, contexts, meta, scenarios = small
    out, _, _ = store
    other = ScorerMethod("full", **{**SETTINGS, "n_slacks": 1}, store=str(out))
    train = [i for i, m in enumerate(meta) if m.scenario_id != meta[0].scenario_id]
    other.fit([contexts[i] for i in train], [meta[i] for i in train])
    assert count_fits == [1]


def test_the_store_is_the_same_bytes_whether_trained_serially_or_in_parallel(small, store, tmp_path):
    records, contexts, meta, scenarios = small
    out, jobs, _ = store
    again = tmp_path / "folds"
    train_fold_models(METHODS, contexts, meta, scenarios, jobs, again, n_jobs=2)
    for path in out.iterdir():
        assert (again / path.name).read_bytes() == path.read_bytes(), path.name


@pytest.mark.parametrize("world, local", [("small", "store"), ("drawn", "drawn_store")])
def test_a_dask_cluster_trains_the_same_bytes_as_local_processes(world, local, request, tmp_path, monkeypatch):
    """The backend is a machine setting: a local Dask cluster (two worker processes) gives the store trained by
    local processes, on three paper-shaped rooms and on two drawn ones (the `dev` extra installs Dask)."""
    import distributed

    from taskseq.runtime.jobs import SCHEDULER_ENV

    records, contexts, meta, scenarios = request.getfixturevalue(world)
    out, jobs, fitted = request.getfixturevalue(local)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None,
                                  host="127.0.0.1") as cluster:
        monkeypatch.setenv(SCHEDULER_ENV, cluster.scheduler_address)
        again = tmp_path / "folds"
        on_cluster = train_fold_models(METHODS, contexts, meta, scenarios, jobs, again, n_jobs=1)
        assert cluster.scheduler.transition_counter > 0  # the jobs went through the cluster's scheduler
    assert len(on_cluster) == len(fitted)
    for path in out.iterdir():
        assert (again / path.name).read_bytes() == path.read_bytes(), path.name


def test_each_fit_starts_from_an_earlier_one_of_its_own_training_set_and_features(small):
    """Warm starts (`plan_tasks`): within one task, every start is an earlier fit of the same features and the
    same training steps, so no fit starts from one that saw its test steps; a model of select's grid starts from
    the same recipe at the nearest C, and DAgger's rollouts from its base."""
    records, contexts, meta, scenarios = small
    lineup = Lineup(Methods(), Selection(dict.fromkeys(specs(), 1.0), source="s"),
                    Learner(SETTINGS["tol"], SETTINGS["max_iter"], SETTINGS["n_slacks"]))
    made = lineup.mrf(["full", "relations", "chained", "dagger"])
    grid = {f"{m} C={C:g}": (lambda m=m, C=C: replace(made[m](), C=C, name=f"{m} C={C:g}"))
            for m in made for C in (1.0, 3.0)}
    jobs = training_jobs(grid, meta, scenarios, n_folds=2, seed=0, group_by="scenario")
    keyed: dict = {}
    for job in jobs:
        keyed.setdefault(grid[job.method]().key([contexts[i] for i in job.index]), []).append(job)
    unfitted = {k: grid[uses[0].method]() for k, uses in keyed.items()}
    tasks = plan_tasks(unfitted, keyed, contexts)
    assert sorted(k for keys, _ in tasks for k in keys) == sorted(keyed)
    assert len(tasks) == 2 * 2  # (full, relations) x two folds
    for keys, starts in tasks:
        assert len({(unfitted[k].features, keyed[k][0].index) for k in keys}) == 1
        steps = [contexts[i] for i in keyed[keys[0]][0].index]
        for i, (key, start) in enumerate(zip(keys, starts, strict=True)):
            method, base, warm = unfitted[key], start.base, start.warm
            assert (base is None) == (method.dagger_rounds == 0)
            assert base is None or (base < i and keys[base] == replace(method, dagger_rounds=0).key(steps))
            assert (warm is None) == (i == 0) and (warm is None or warm < i)
            if method.chained_starts and any(unfitted[k].chained_starts for k in keys[:i]):
                assert unfitted[keys[warm]].chained_starts and unfitted[keys[warm]].C != method.C  # same recipe
            elif warm is not None:
                assert not unfitted[keys[warm]].chained_starts  # else the plain model nearest its C
