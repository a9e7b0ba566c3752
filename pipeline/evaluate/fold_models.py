"""Every MRF model the evaluation stages use, trained once (the `folds` stage).

Cross-validation fits the full, edge-only and clique-only models on each
training fold; attribute noise and feedback replay the full model of the same
folds; recipes fit the full model once per recipe kind without that kind's
environments. This module lists those training sets, trains each distinct
(feature set, settings, training steps) once, in parallel, and writes the
models into a `ModelStore` folder, where the stages find them by content.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from joblib import Parallel, delayed

from ..features.context import StepContext
from ..features.dataset import StepMeta
from ..io import atomic_directory, write_json_atomic
from ..learn.store import ModelStore
from ..sim.scenarios import Scenario
from .crossval import scenario_folds, training_index
from .methods import ADDED_METHODS, MRFMethod
from .recipes import recipe_training_sets

CROSSVAL_FEATURES = {"full": "full", "only_edge": "edge", "only_clique": "clique", "relations": "relations"}
ROBUSTNESS_METHODS = ("full", *ADDED_METHODS)  # the methods noise, feedback and recipes run


@dataclass(frozen=True)
class TrainingJob:
    method: str  # a crossval method name (full, only_edge, only_clique)
    training_set: str  # "fold 3", or "recipes: serve-sweet-tea"
    index: tuple[int, ...]  # training steps


def training_jobs(meta: list[StepMeta], scenarios: dict[str, Scenario], n_folds: int, seed: int,
                  group_by: str) -> list[TrainingJob]:
    """The MRF fits of crossval (every MRF method x folds) and recipes (each robustness method per kind)."""
    jobs = []
    folds = scenario_folds(scenarios, n_folds, seed, group_by)
    for method in CROSSVAL_FEATURES:
        for k, test in enumerate(folds):
            jobs.append(TrainingJob(method, f"fold {k}", tuple(training_index(meta, test))))
    for method in ROBUSTNESS_METHODS:
        for name, index in recipe_training_sets(meta).items():
            jobs.append(TrainingJob(method, f"recipes: {name}", tuple(index)))
    return jobs


def _fit(make: Callable[[str], MRFMethod], contexts: list[StepContext], meta: list[StepMeta],
         job: TrainingJob) -> MRFMethod:
    return make(CROSSVAL_FEATURES[job.method]).fit([contexts[i] for i in job.index], [meta[i] for i in job.index])


def train_fold_models(make: Callable[[str], MRFMethod], contexts: list[StepContext], meta: list[StepMeta],
                      jobs: list[TrainingJob], output: Path | str, n_jobs: int = 1,
                      verbose: int = 0) -> list[dict[str, Any]]:
    """Fit every job's model once and write the store to `output` (replaced as a whole, atomically).

    `make(features)` builds an unfitted `MRFMethod` with the learner settings.
    Returns one record per model: key, uses (method, training set), steps,
    settings, iterations, objective, and the seconds it took; `index.json` in
    the store holds all but the seconds, so the same inputs give the same bytes.
    """
    keyed: dict[str, list[TrainingJob]] = {}
    for job in jobs:
        key = make(CROSSVAL_FEATURES[job.method]).key([contexts[i] for i in job.index])
        keyed.setdefault(key, []).append(job)
    keys = list(keyed)
    fitted = Parallel(n_jobs=n_jobs, verbose=verbose if n_jobs != 1 else 0)(  # joblib fails on verbose serial runs
        delayed(_fit)(make, contexts, meta, keyed[k][0]) for k in keys
    )
    records = []
    with atomic_directory(output) as tmp:
        store = ModelStore(tmp)
        for key, method in zip(keys, fitted, strict=True):
            ssvm = method.fit_.ssvm
            record = {
                "key": key,
                "features": method.features,
                "uses": [{"method": j.method, "training_set": j.training_set} for j in keyed[key]],
                "steps": len(keyed[key][0].index),
                **method.learner_params(),
                "iterations": ssvm.n_iter_,
                "converged": bool(ssvm.converged_),
                "primal_objective": ssvm.primal_objective_,
                "dual_objective": ssvm.dual_objective_,
            }
            store.save(key, method.model_, method.w_, {k: v for k, v in record.items() if k != "uses"})
            records.append(record)
        write_json_atomic(tmp / "index.json", {"models": records})
    return [{**r, "seconds": m.fit_.seconds} for r, m in zip(records, fitted, strict=True)]
