"""Stage `fold_models`: every MRF model the evaluation stages use, trained once into a content-addressed store.

Its metrics file holds what the fits computed (iterations, objectives), which
are the same bytes on every run, so `dvc.lock` stays as committed after a
fresh clone re-runs the pipeline; the fits' times go to the stage's MLflow run.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any

from ..demonstrations.benchmark import load_benchmark
from ..experiments.fold_models import train_fold_models, training_jobs
from ..features.dataset import read_features
from ..methods import Lineup
from ..runtime.atomic import refuse_replacing_inputs, write_json_atomic
from ..selection import read_selection
from ..settings import Folds, Learner, Methods, Params, Procedural
from ..track.mlflow_runs import NO_RUN, Tracker
from .options import FoldModelsOptions


@dataclass(frozen=True)
class Settings:
    folds: Folds
    learner: Learner
    methods: Methods
    recipes: bool = True  # also those the recipes experiment runs, once per recipe kind (every step outside it)
    procedural: Procedural = Procedural()  # params.yaml's `procedural`: the rooms a method may draw to train on


def settings(params: Params, world_seed: int | None = None) -> Settings:
    return Settings(params.crossval.fold_settings, params.train.learner, params.methods, procedural=params.procedural)


def run(settings: Settings, options: FoldModelsOptions, tracker: Tracker = NO_RUN, n_jobs: int = 1) -> dict[str, Any]:
    folds, output = settings.folds, options.output
    refuse_replacing_inputs(output, features=options.features, processed=options.processed,
                            selection=options.selection)
    lineup = Lineup(settings.methods, read_selection(options.selection), settings.learner,
                    procedural=settings.procedural)
    methods = lineup.mrf()  # a method without its C stops here, before minutes of work
    recipe_methods = lineup.names("recipes") if settings.recipes else []
    contexts, meta = read_features(options.features)
    bench = load_benchmark(options.processed)
    jobs = training_jobs(methods, meta, bench.scenarios, folds.folds, folds.seed, folds.group_by, recipe_methods)
    recipes = ", recipes" if recipe_methods else ""
    print(f"training {len(jobs)} fold models ({folds.folds} folds grouped by {folds.group_by}{recipes}) "
          f"with {n_jobs} jobs")
    start = time.perf_counter()
    records = train_fold_models(methods, contexts, meta, bench.scenarios, jobs, output, n_jobs=n_jobs, verbose=5)
    wall = time.perf_counter() - start
    out = {"models": len(records), "iterations": sum(r["iterations"] for r in records),
           "all_converged": all(r["converged"] for r in records)}
    if options.metrics:  # what the fits computed, the same bytes on every run; their times go to MLflow only
        write_json_atomic(options.metrics, {**out, "per_model": [
            {k: r[k] for k in ("features", "uses", "steps", "fitted_steps", "iterations", "converged",
                               "primal_objective", "dual_objective")} for r in records]})
    # the seconds of fits done now: one read back from the fit cache reports the fit that stored it
    times = {"wall_seconds": wall, "fit_seconds": sum(r["seconds"] for r in records if not r["from_cache"]),
             "from_cache": sum(r["from_cache"] for r in records)}
    tracker.metrics({k: float(v) for k, v in {**out, **times}.items()})
    for r in records:  # one child per model: its settings, and its objectives and gap per iteration
        uses = r["uses"]
        with tracker.child(f"{r['features']} {uses[0]['training_set']}", {
                "method": ",".join(dict.fromkeys(u["method"] for u in uses)), "feature_set": r["features"],
                "C": r["C"], "chained_starts": r["chained_starts"], "dagger_rounds": r["dagger_rounds"],
                **{k: r[k] for k in ("noise_rate", "noise_copies") if k in r},
                "training_set": uses[0]["training_set"], "steps": r["steps"]}) as child:
            child.metrics({"iterations": r["iterations"], "seconds": r["seconds"],
                           "primal_objective": r["primal_objective"], "dual_objective": r["dual_objective"]})
            child.curve(r["curve"])
    reused = f", {times['from_cache']} of them read from the fit cache" if times["from_cache"] else ""
    print(f"trained {len(records)} models in {wall:.1f} s ({times['fit_seconds']:.1f} s of fitting, "
          f"{out['iterations']} iterations{reused}); written to {output}")
    return out
