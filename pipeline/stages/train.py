"""Stage `train`: the MRF weights on every step of the benchmark (the model `taskseq plan` uses)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..evaluate.metrics import step_accuracy
from ..features.dataset import build_steps, read_features
from ..io import write_json_atomic, write_text_atomic
from ..learn.estimator import StepScorer
from ..learn.ssvm import learning_curve
from ..logs.people import people_records
from ..report.csvs import csv_text
from ..settings import Params, Train
from ..track.mlflow_runs import NO_RUN, Tracker
from .paths import TrainPaths


@dataclass(frozen=True)
class Settings:
    train: Train
    people_logs: Path | None  # people's demonstrations added to the training steps (`people.train`), or None


def settings(params: Params, world_seed: int | None = None) -> Settings:
    t, people = params.train, params.people
    logs, use = Path(people.logs), people.train  # both read, so the keys read never depend on the values
    return Settings(Train(C=t.C, tol=t.tol, max_iter=t.max_iter, n_slacks=t.n_slacks, feature_set=t.feature_set),
                    logs if use else None)


def run(settings: Settings, paths: TrainPaths, tracker: Tracker = NO_RUN) -> dict[str, Any]:
    """With `people.train`, people's demonstrations (`taskseq serve`) are added to the training steps."""
    model, metrics, curve = paths.model, paths.metrics, paths.curve
    contexts, _ = read_features(paths.features)
    n_people = 0
    if settings.people_logs is not None:
        records, _ = people_records(settings.people_logs)
        extra, _ = build_steps(records)
        contexts, n_people = contexts + extra, len(records)
    planner = StepScorer(settings.train.feature_set, **settings.train.ssvm).fit(contexts, progress=True)
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
    if settings.people_logs is not None:  # without them, the file is the same as before
        out["people_sequences"] = n_people
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
    print(f"trained {settings.train.feature_set} model on {len(contexts)} steps: {ssvm.n_iter_} iterations ({state}), "
          f"{planner.fit_seconds_:.1f} s; teacher-forced training accuracy prim {acc['average/prim']:.1f}% "
          f"arg {acc['average/arg']:.1f}%; saved {model}")
    return out
