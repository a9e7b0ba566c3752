"""Stage `train`: the shipped planner (the model `taskseq plan` uses), fitted on every step of the benchmark.

Its method is `train.method`: by default the MRF method the development
world ranked first (`best`, read from the `select` stage's file), or any MRF
method of Table I by name (`full` is the paper's model). A method that adds
training data beyond the logs (chained starts, DAgger) needs the training
scenarios, from the Parquet tables. The model file records the method, its
settings (its own C, as `select` chose it, and DAgger's rounds) and the
policy its programs pick steps with, which `taskseq plan` uses.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..demonstrations.benchmark import Benchmark, load_benchmark
from ..demonstrations.people import people_records
from ..evaluate.metrics import step_accuracy
from ..features.dataset import build_steps, read_features
from ..learn.ssvm import learning_curve
from ..methods import Lineup, method_spec
from ..report.csvs import csv_text
from ..runtime.atomic import write_json_atomic, write_text_atomic
from ..selection import read_selection
from ..settings import Methods, Params, Procedural, Train
from ..track.mlflow_runs import NO_RUN, Tracker
from .options import TrainOptions


@dataclass(frozen=True)
class Settings:
    train: Train
    people_logs: Path | None  # people's demonstrations added to the training steps (`people.train`), or None
    methods: Methods  # the shipped method's own settings
    procedural: Procedural = Procedural()  # params.yaml's `procedural`: the rooms a method may draw to train on


def settings(params: Params, world_seed: int | None = None) -> Settings:
    t, people = params.train, params.people
    logs, use = Path(people.logs), people.train  # both read, so the keys read never depend on the values
    return Settings(Train(tol=t.tol, max_iter=t.max_iter, n_slacks=t.n_slacks, method=t.method),
                    logs if use else None, params.methods, params.procedural)


def shipped_method(settings: Train, options: TrainOptions) -> tuple[str, str]:
    """The method to train and why: named in the settings, or the one the development world ranked first."""
    if settings.method != "best":
        return settings.method, "train.method"
    if options.selection is None:
        raise ValueError("train.method is 'best', the method the development world ranks first: give the file "
                         "`taskseq select` wrote with --selection, or name a method with --set train.method=NAME")
    method = read_selection(options.selection).method
    if method is None:
        raise ValueError(f"{options.selection}: no field 'method' (the method ranked first); the file predates the "
                         "ranking of methods: run `taskseq select` again, or name the method with "
                         "--set train.method=NAME")
    return method, f"ranked first on the development world ({options.selection})"


def run(settings: Settings, options: TrainOptions, tracker: Tracker = NO_RUN) -> dict[str, Any]:
    """With `people.train`, people's demonstrations (`taskseq serve`) are added to the training steps."""
    train = settings.train
    features, model, metrics, curve = options.features, options.model, options.metrics, options.curve
    name, chosen_by = shipped_method(train, options)
    method = Lineup(settings.methods, read_selection(options.selection), train.learner,
                    procedural=settings.procedural).mrf([name])[name]()
    contexts, meta = read_features(features)
    people = people_records(settings.people_logs)[0] if settings.people_logs is not None else []
    if people:
        extra, extra_meta = build_steps(people)
        contexts, meta = contexts + extra, meta + extra_meta
    scenarios = None
    if method.chained_starts or method.dagger_rounds:
        if options.processed is None:
            raise ValueError(f"method {name} adds chained starts or DAgger rounds to the logs: it needs the "
                             "training scenarios, from the Parquet tables (--processed)")
        scenarios = {**load_benchmark(options.processed).scenarios, **Benchmark.from_records(people).scenarios}
    planner = method.fit(contexts, meta, scenarios).planner_
    label = method_spec(name).label
    planner.save(model, n_steps=len(contexts), method=name, label=label, chosen_by=chosen_by,
                 chained_starts=method.chained_starts, dagger_rounds=method.dagger_rounds, policy=method.policy,
                 **({"people_sequences": len(people)} if people else {}),  # without them, the file is as before
                 **({"noise_rate": method.noise_rate, "noise_copies": method.noise_copies} if method.noise_copies
                    else {}))
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
        out["people_sequences"] = len(people)
    if metrics:
        write_json_atomic(metrics, {**out, "method": name})
    if curve:
        write_text_atomic(curve, csv_text(
            ["iteration", "primal", "best_primal", "dual", "gap", "n_constraints"],
            ({"iteration": it.iteration, "primal": it.primal, "best_primal": it.best_primal, "dual": it.dual,
              "gap": it.gap, "n_constraints": it.n_constraints} for it in ssvm.history_)))
    tracker.params({"method": name, "method.chosen_by": chosen_by})
    tracker.metrics({**{k: float(v) for k, v in out.items()}, "seconds": planner.fit_seconds_})
    tracker.curve(learning_curve(ssvm.history_))  # MLflow charts them against the iteration
    for path in (curve, model):
        if path:
            tracker.artifact(path)
    state = "converged" if ssvm.converged_ else "stopped at max_iter"
    print(f"trained {label} (method {name}, C={method.C:g}, policy {method.policy}, {chosen_by}) on {len(contexts)} "
          f"steps: last fit {ssvm.n_iter_} iterations ({state}), {planner.fit_seconds_:.1f} s in all; teacher-forced "
          f"training accuracy prim {acc['average/prim']:.1f}% arg {acc['average/arg']:.1f}%; saved {model}")
    return out
