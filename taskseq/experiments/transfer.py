"""Models trained on one world and run on another's scenarios: the paper-shaped rooms against drawn ones.

The models are trained as the fold models are (`fold_models.train_fold_models`,
one training set: every step of the first world), so the methods that share
a feature set start where a neighbour ended and DAgger starts from its base
model instead of fitting it again. Then both worlds' steps and scenarios go
into one pool whose single fold tests every scenario of the second world, so
training sees exactly the first world's steps and the same fold machinery
(teacher-forced steps, closed-loop programs, judging) runs as in
cross-validation, each method loading its model from the store.
"""

from __future__ import annotations

import tempfile
from collections.abc import Callable
from functools import partial
from pathlib import Path

from ..demonstrations.benchmark import Benchmark
from ..evaluate.methods import ScorerMethod, configured
from ..features.context import StepContext
from ..features.dataset import StepMeta
from ..runtime.jobs import Shared, run_jobs
from .crossval import FoldResult, run_fold
from .fold_models import TrainingJob, train_fold_models

World = tuple[list[StepContext], list[StepMeta], Benchmark]


def transfer(methods: dict[str, Callable[[], ScorerMethod]], train: World, test: World, max_steps: int,
             n_jobs: int = 1) -> tuple[list[FoldResult], list[StepContext], list[StepMeta]]:
    """Each method fitted on every step of `train` and run on every scenario of `test`; the results, and the pooled
    steps and their metadata that their `step_index` points into (for `metrics.summarize`, `report.csvs.step_rows`)."""
    (train_contexts, train_meta, train_bench), (test_contexts, test_meta, test_bench) = train, test
    shared_ids = set(train_bench.scenarios) & set(test_bench.scenarios)
    if shared_ids:
        raise ValueError(f"the two worlds share scenario ids, e.g. {sorted(shared_ids)[0]}: a transfer test needs "
                         "scenarios the training world does not have")
    contexts, meta = train_contexts + test_contexts, train_meta + test_meta
    bench = Benchmark([], {**train_bench.scenarios, **test_bench.scenarios},
                      {**train_bench.states, **test_bench.states}, {**train_bench.actions, **test_bench.actions})
    tested = frozenset(test_bench.scenarios)
    every_step = tuple(range(len(train_contexts)))
    with tempfile.TemporaryDirectory(prefix="taskseq-transfer-") as tmp:
        store = str(Path(tmp) / "models")
        train_fold_models(methods, train_contexts, train_meta, train_bench.scenarios,
                          [TrainingJob(name, "transfer", every_step) for name in methods], store, n_jobs)
        steps, shared_meta, scenarios, demos = Shared(contexts), Shared(meta), Shared(bench.scenarios), Shared(bench)
        jobs = [(run_fold, (partial(configured, make, store=store), 0, steps, shared_meta, scenarios, tested, max_steps,
                            demos)) for make in methods.values()]
        results = run_jobs(jobs, n_jobs, stored_first=True)
    return results, contexts, meta
