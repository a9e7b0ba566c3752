"""Stage `train`: the MRF weights on every step of the benchmark (the model `taskseq plan` uses)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from ..evaluate.metrics import step_accuracy
from ..features.dataset import build_steps, read_features
from ..io import write_json_atomic, write_text_atomic
from ..learn.estimator import MRFPlanner
from ..learn.ssvm import learning_curve
from ..logs.people import people_records
from ..report.csvs import csv_text
from ..settings import Train
from ..track.mlflow_runs import NO_RUN, Tracker


def run(settings: Train, features: Path, model: Path, metrics: Path | None = None, curve: Path | None = None,
        tracker: Tracker = NO_RUN, people: Path | None = None) -> dict[str, Any]:
    """`people`: a folder of people's demonstrations whose steps are added to the training steps."""
    contexts, _ = read_features(features)
    n_people = 0
    if people is not None:
        records, _ = people_records(people)
        extra, _ = build_steps(records)
        contexts, n_people = contexts + extra, len(records)
    planner = MRFPlanner(settings.feature_set, **settings.ssvm).fit(contexts, progress=True)
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
    if people is not None:  # the file is the same as before when people's demonstrations are not asked for
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
    print(f"trained {settings.feature_set} model on {len(contexts)} steps: {ssvm.n_iter_} iterations ({state}), "
          f"{planner.fit_seconds_:.1f} s; teacher-forced training accuracy prim {acc['average/prim']:.1f}% "
          f"arg {acc['average/arg']:.1f}%; saved {model}")
    return out
