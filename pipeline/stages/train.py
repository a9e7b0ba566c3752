"""Stage `train`: the MRF weights on every step of the benchmark (the model `taskseq plan` uses)."""

from __future__ import annotations

from typing import Any

from ..evaluate.metrics import step_accuracy
from ..features.dataset import read_features
from ..io import write_json_atomic, write_text_atomic
from ..learn.estimator import StepScorer
from ..learn.ssvm import learning_curve
from ..report.csvs import csv_text
from ..settings import Params, Train
from ..track.mlflow_runs import NO_RUN, Tracker
from .paths import TrainPaths


def settings(params: Params, world_seed: int | None = None) -> Train:
    t = params.train
    return Train(C=t.C, tol=t.tol, max_iter=t.max_iter, n_slacks=t.n_slacks, feature_set=t.feature_set)


def run(settings: Train, paths: TrainPaths, tracker: Tracker = NO_RUN) -> dict[str, Any]:
    features, model, metrics, curve = paths.features, paths.model, paths.metrics, paths.curve
    contexts, _ = read_features(features)
    planner = StepScorer(settings.feature_set, **settings.ssvm).fit(contexts, progress=True)
    planner.save(model, n_steps=len(contexts))
    ssvm = planner.ssvm_
    acc = step_accuracy(contexts, planner.predict(contexts))
    last = ssvm.history_[-1]
    out = {
        "train_average_prim": acc["average/prim"],
        "train_average_arg": acc["average/arg"],
        "train_done_arg": acc.get("done/arg", float("nan")),
        "iterations": ssvm.n_iter_,
        "converged": bool(ssvm.converged_),
        "primal_objective": ssvm.primal_objective_,
        "dual_objective": ssvm.dual_objective_,
        "relative_gap": last.gap / max(1.0, abs(last.best_primal)),
    }
    if metrics:
        write_json_atomic(metrics, out)
    if curve:
        write_text_atomic(curve, csv_text(
            ["iteration", "primal", "best_primal", "dual", "gap", "n_constraints"],
            ({"iteration": it.iteration, "primal": it.primal, "best_primal": it.best_primal, "dual": it.dual,
              "gap": it.gap, "n_constraints": it.n_constraints} for it in ssvm.history_)))
    tracker.metrics({**{k: float(v) for k, v in out.items()}, "seconds": planner.fit_seconds_})
    tracker.curve(learning_curve(ssvm.history_))  # MLflow charts them against the iteration
    for path in (curve, model):
        if path:
            tracker.artifact(path)
    state = "converged" if ssvm.converged_ else "stopped at max_iter"
    print(f"trained {settings.feature_set} model on {len(contexts)} steps: {ssvm.n_iter_} iterations ({state}), "
          f"{planner.fit_seconds_:.1f} s; teacher-forced training accuracy prim {acc['average/prim']:.1f}% "
          f"arg {acc['average/arg']:.1f}%; saved {model}")
    return out
