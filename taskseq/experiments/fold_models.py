"""Every MRF model the evaluation stages use, trained once (the `fold_models` stage).

Cross-validation fits every MRF method of Table I on each training fold;
attribute noise and feedback replay the models of the same folds; recipes fit
each of their methods once per recipe kind without that kind's environments.
This module lists those training sets, trains each distinct (method settings,
training steps) once, in parallel, and writes the models into a `ModelStore`
folder, where the stages find them by content.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from ..evaluate.methods import ScorerMethod
from ..features.context import StepContext
from ..features.dataset import StepMeta
from ..learn.ssvm import learning_curve
from ..learn.store import ModelStore
from ..runtime.atomic import atomic_directory, write_json_atomic
from ..runtime.jobs import Shared, run_jobs
from ..sim.scenarios import Scenario
from .crossval import scenario_folds, training_index
from .recipes import recipe_training_sets

MakeScorerMethod = Callable[[], ScorerMethod]


@dataclass(frozen=True)
class TrainingJob:
    method: str  # a method name of Table I (an MRF one)
    training_set: str  # "fold 3", or "recipes: serve-sweet-tea"
    index: tuple[int, ...]  # training steps


def training_jobs(methods: Mapping[str, MakeScorerMethod], meta: list[StepMeta], scenarios: dict[str, Scenario],
                  n_folds: int, seed: int, group_by: str,
                  recipe_methods: Sequence[str] = ()) -> list[TrainingJob]:
    """The MRF fits of crossval (every method x folds) and recipes (each of `recipe_methods` per kind)."""
    jobs = []
    folds = scenario_folds(scenarios, n_folds, seed, group_by)
    for method in methods:
        for k, test in enumerate(folds):
            jobs.append(TrainingJob(method, f"fold {k}", tuple(training_index(meta, test))))
    for method in (m for m in recipe_methods if m in methods):
        for name, index in recipe_training_sets(meta).items():
            jobs.append(TrainingJob(method, f"recipes: {name}", tuple(index)))
    return jobs


@dataclass(frozen=True)
class Start:
    """Where a fit of a task starts: positions of earlier fits in the same task (`plan_tasks`)."""

    base: int | None  # the same settings without DAgger: DAgger's first rollouts use it
    warm: int | None  # the same recipe at the nearest C, else the plain model: the learner starts from its cuts


def _fit(makes: tuple[MakeScorerMethod, ...], starts: tuple[Start, ...], contexts: list[StepContext],
         meta: list[StepMeta], scenarios: dict[str, Scenario], index: tuple[int, ...]) -> list[ScorerMethod]:
    """Fit the models of one task in turn, each from the earlier ones its start names; returned without their cuts
    (a neighbour's start, not worth sending back from a worker)."""
    steps, steps_meta = [contexts[i] for i in index], [meta[i] for i in index]
    fitted: list[ScorerMethod] = []
    for make, start in zip(makes, starts, strict=True):
        fitted.append(make().fit(steps, steps_meta, scenarios,
                                 base=None if start.base is None else fitted[start.base].planner_,
                                 warm=None if start.warm is None else fitted[start.warm].planner_))
    for method in fitted:
        method.planner_.drop_cuts()
    return fitted


def _plain(method: ScorerMethod) -> bool:
    """Fitted on the demonstrated steps alone: the model any other of its features and steps can start from."""
    return method.learner_params() == method.plain().learner_params()


def _recipe(method: ScorerMethod) -> dict[str, Any]:
    """What a model is trained on and how, but for C: models of one recipe share their training data."""
    return {k: v for k, v in method.learner_params().items() if k != "C"}


def plan_tasks(unfitted: Mapping[str, ScorerMethod], keyed: Mapping[str, list[TrainingJob]],
               contexts: list[StepContext]) -> list[tuple[list[str], list[Start]]]:
    """The fits grouped into tasks, one per (features, training steps), each fit starting from an earlier one.

    Within a task the models of the demonstrated steps alone come first, by
    increasing C, each starting from the one before. Every other model starts
    from the same settings at the nearest C fitted before it (select's grid:
    its data, chained starts or noisy copies or drawn rooms included, are the
    same), else from the plain model nearest its C (its data begin with the
    plain model's); a DAgger model's first rollouts use its base, the same
    settings without DAgger. A start never crosses training sets, so no fit
    starts from one that saw its test steps. Returns each task's keys in
    fitting order with each one's `Start`.
    """
    groups: dict[tuple[str, tuple[int, ...]], list[str]] = {}
    for key, uses in keyed.items():
        groups.setdefault((unfitted[key].features, uses[0].index), []).append(key)
    out = []
    for (_, index), keys in groups.items():
        keys = sorted(keys, key=lambda k: (not _plain(unfitted[k]), bool(unfitted[k].dagger_rounds),
                                           unfitted[k].C))
        position = {k: i for i, k in enumerate(keys)}
        steps = [contexts[i] for i in index]
        plans: list[Start] = []
        for i, key in enumerate(keys):
            method = unfitted[key]
            base = position.get(replace(method, dagger_rounds=0).key(steps)) if method.dagger_rounds else None
            # the same training data at another C when fitted already (all its steps' cuts), else the plain model
            same = [j for j in range(i) if _recipe(unfitted[keys[j]]) == _recipe(method)]
            plain = [j for j in range(i) if _plain(unfitted[keys[j]])]
            warm = min(same or plain, key=lambda j: (abs(math.log(unfitted[keys[j]].C / method.C)),
                                                     unfitted[keys[j]].C), default=None)
            plans.append(Start(base, warm))
        out.append((keys, plans))
    return out


def _expected_cost(method: ScorerMethod, n_steps: int) -> float:
    """A fit's time against an edge-only fit of as many steps (medians of `folds.json`): long ones start first."""
    cost = {"edge": 1.0, "clique": 1.5, "full": 1.5}.get(method.features, 2.5) * n_steps
    return (cost * (2.0 if method.chained_starts else 1.0) * (2.0 if method.dagger_rounds else 1.0)
            * (1 + method.noise_copies))


def train_fold_models(methods: Mapping[str, MakeScorerMethod], contexts: list[StepContext], meta: list[StepMeta],
                      scenarios: dict[str, Scenario], jobs: list[TrainingJob], output: Path | str, n_jobs: int = 1,
                      verbose: int = 0) -> list[dict[str, Any]]:
    """Fit every job's model once and write the store to `output` (replaced as a whole, atomically).

    `methods[name]()` builds the job's unfitted `ScorerMethod` (without a store);
    `scenarios` are the benchmark's, which methods that consult the
    demonstrator read (only those of a job's training steps). A DAgger model
    starts from the model of the same steps and settings without DAgger: when
    that model is a job too, both are fitted in one task, the base first, so it
    is never fitted twice. Tasks run in parallel, the longest first.
    Returns one record per model: key, uses (method, training set), steps,
    settings, iterations, objective, the seconds it took, its learning curve and
    whether it was read from the fit cache (`learn.fit_cache`; then the seconds are
    those of the fit that stored it); `index.json` in the store holds all but
    the last three, so the same inputs give the same bytes.
    """
    keyed: dict[str, list[TrainingJob]] = {}
    for job in jobs:
        key = methods[job.method]().key([contexts[i] for i in job.index])
        keyed.setdefault(key, []).append(job)

    make = {key: methods[uses[0].method] for key, uses in keyed.items()}  # the factory a key's workers call
    unfitted = {key: f() for key, f in make.items()}
    tasks = plan_tasks(unfitted, keyed, contexts)
    cost = [sum(_expected_cost(unfitted[k], len(keyed[k][0].index)) for k in keys) for keys, _ in tasks]
    steps, shared_meta, shared_scenarios = Shared(contexts), Shared(meta), Shared(scenarios)
    parts = run_jobs([(_fit, (tuple(make[k] for k in keys), tuple(plans), steps, shared_meta, shared_scenarios,
                              keyed[keys[0]][0].index)) for keys, plans in tasks], n_jobs, verbose, cost=cost,
                     stored_first=True)
    fitted = {k: m for (keys, _), part in zip(tasks, parts, strict=True) for k, m in zip(keys, part, strict=True)}
    records, seconds, curves, cached = [], [], [], []
    with atomic_directory(output) as tmp:
        store = ModelStore(tmp)
        # models without DAgger first, then DAgger's: the store's index keeps one order whatever the tasks were
        for key in sorted(keyed, key=lambda k: bool(unfitted[k].dagger_rounds)):
            method = fitted[key]
            planner = method.planner_
            ssvm = planner.ssvm_
            record = {
                "key": key,
                "features": method.features,
                "uses": [{"method": j.method, "training_set": j.training_set} for j in keyed[key]],
                "steps": len(keyed[key][0].index),
                "fitted_steps": planner.n_steps_,
                **method.learner_params(),
                "iterations": ssvm.n_iter_,
                "converged": bool(ssvm.converged_),
                "primal_objective": ssvm.primal_objective_,
                "dual_objective": ssvm.dual_objective_,
            }
            store.save(key, planner, {k: v for k, v in record.items() if k != "uses"})
            records.append(record)
            seconds.append(planner.fit_seconds_)
            curves.append(learning_curve(ssvm.history_))
            cached.append(planner.from_cache_)
        write_json_atomic(tmp / "index.json", {"models": records})
    return [{**r, "seconds": t, "curve": c, "from_cache": f}
            for r, t, c, f in zip(records, seconds, curves, cached, strict=True)]

