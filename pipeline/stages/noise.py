"""Stage `noise`: closed-loop sequence accuracy with binary attributes flipped at test time.

Run for the paper's full model and the best added method (`ROBUSTNESS_METHODS`).
noise_sequences.csv holds every program
of every rate and noise draw (DVC-cached, not in git), each rate's also in its
MLflow child run as a table.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from ..evaluate.fold_models import ROBUSTNESS_METHODS
from ..evaluate.labels import METHOD_LABELS
from ..evaluate.methods import method_params, table1_methods
from ..evaluate.robustness import Condition, evaluate_conditions, noise_curve, noise_runs
from ..features.dataset import read_features
from ..io import write_text_atomic
from ..logs.benchmark import load_benchmark
from ..report import paper
from ..report.csvs import OUTCOME_COLUMNS, csv_text, outcome_row
from ..report.tables import line_plot_png
from ..settings import Crossval, Learner, Noise
from ..track.mlflow_runs import NO_RUN, Tracker

RATE = {"rate": 1, "sequence_arg": 2, "sequence_arg_std": 2, "sequence_prim": 2, "success": 2}


def run(settings: Noise, crossval: Crossval, learner: Learner, features: Path, processed: Path, output: Path,
        store: Path | None = None, n_jobs: int = 1, tracker: Tracker = NO_RUN) -> list[dict[str, Any]]:
    contexts, meta = read_features(features)
    bench = load_benchmark(processed)
    methods = table1_methods(crossval, learner, store=None if store is None else str(store))
    conditions = [Condition("noise", r, s) for r in settings.rates for s in range(settings.seeds)]
    runs, curve, sequences = [], [], []
    chosen = {name: methods[name] for name in ROBUSTNESS_METHODS}
    outcomes = evaluate_conditions(chosen, contexts, meta, bench.scenarios, conditions, crossval.fold_settings,
                                   crossval.max_steps, settings.seed, n_jobs)
    for name, results in outcomes.items():
        mine = noise_runs(settings, results)
        runs += [{"method": name, **r} for r in mine]
        curve += [{"method": name, **r} for r in noise_curve(settings, mine)]
        sequences += [{"method": name, "rate": c.a, "draw": c.b, **outcome_row(o)} for c, o in results]
    out = Path(output)
    write_text_atomic(out / "noise_runs.csv", csv_text(["method", "rate", "seed", "sequence_arg", "sequence_prim",
                                                        "success"], runs, RATE))
    write_text_atomic(out / "noise_sequences.csv", csv_text(["method", "rate", "draw", *OUTCOME_COLUMNS],
                                                            sequences, {"rate": 1}))
    text = csv_text(["method", *RATE], curve, RATE)
    write_text_atomic(out / "noise.csv", text)
    for row in curve:
        name = row["method"]
        with tracker.child(f"noise {name} r={row['rate']}",
                           {**method_params(name, methods[name]()), "rate": row["rate"]}) as child:
            child.metrics({"sequence_arg": row["sequence_arg"], "sequence_arg_std": row["sequence_arg_std"],
                           "sequence_prim": row["sequence_prim"], "success": row["success"]})
            child.table([r for r in sequences if r["method"] == name and r["rate"] == row["rate"]], "sequences")
    series = {f"{METHOD_LABELS[m]} (mean, std over noise draws)":
              (list(settings.rates), [r["sequence_arg"] for r in curve if r["method"] == m],
               [r["sequence_arg_std"] for r in curve if r["method"] == m]) for m in ROBUSTNESS_METHODS}
    line_plot_png(series, str(out / "noise.png"), "Sequence accuracy (arg) with binary attributes flipped",
                  "probability of flipping each binary attribute", "% sequences correct",
                  reference={"paper": (list(paper.NOISE), list(paper.NOISE.values()))})
    for f in ("noise.csv", "noise_runs.csv", "noise.png"):
        tracker.artifact(out / f)
    print(text, end="")
    return curve
