"""Stage `folds`: every MRF model the evaluation stages use, trained once into a content-addressed store."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

from ..evaluate.fold_models import train_fold_models, training_jobs
from ..evaluate.methods import mrf_methods
from ..features.dataset import read_features
from ..io import write_json_atomic
from ..logs.benchmark import load_benchmark
from ..settings import Folds, Learner
from ..track.mlflow_runs import NO_RUN, Tracker


def run(folds: Folds, learner: Learner, features: Path, processed: Path, output: Path, metrics: Path | None = None,
        n_jobs: int = 1, tracker: Tracker = NO_RUN) -> dict[str, Any]:
    contexts, meta = read_features(features)
    bench = load_benchmark(processed)
    methods = mrf_methods(learner)
    jobs = training_jobs(methods, meta, bench.scenarios, folds.folds, folds.seed, folds.group_by)
    print(f"training {len(jobs)} fold models ({folds.folds} folds grouped by {folds.group_by}, recipes) "
          f"with {n_jobs} jobs")
    start = time.perf_counter()
    records = train_fold_models(methods, contexts, meta, bench.scenarios, jobs, output, n_jobs=n_jobs, verbose=5)
    wall = time.perf_counter() - start
    out = {"models": len(records), "wall_seconds": wall, "fit_seconds": sum(r["seconds"] for r in records),
           "iterations": sum(r["iterations"] for r in records),
           "all_converged": all(r["converged"] for r in records)}
    if metrics:
        write_json_atomic(metrics, {**out, "per_model": [
            {k: r[k] for k in ("features", "uses", "steps", "fitted_steps", "iterations", "converged", "seconds",
                               "primal_objective", "dual_objective")} for r in records]})
    tracker.metrics({k: float(v) for k, v in out.items()})
    for r in records:  # one child per model: its settings, and its objectives and gap per iteration
        uses = r["uses"]
        with tracker.child(f"{r['features']} {uses[0]['training_set']}", {
                "method": ",".join(dict.fromkeys(u["method"] for u in uses)), "feature_set": r["features"],
                "C": r["C"], "chained_starts": r["chained_starts"], "dagger_rounds": r["dagger_rounds"],
                "training_set": uses[0]["training_set"], "steps": r["steps"]}) as child:
            child.metrics({"iterations": r["iterations"], "seconds": r["seconds"],
                           "primal_objective": r["primal_objective"], "dual_objective": r["dual_objective"]})
            child.curve(r["curve"])
    print(f"trained {len(records)} models in {wall:.1f} s ({out['fit_seconds']:.1f} s of fitting, "
          f"{out['iterations']} iterations); written to {output}")
    return out
