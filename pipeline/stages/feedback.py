"""Stage `feedback`: sequence accuracy when an observer picks among the top k candidates at the first n steps.

Run for the paper's full model and the best added method (`ROBUSTNESS_METHODS`).
feedback_sequences.csv holds every program of
every (k, n) (DVC-cached, not in git), each condition's also in its MLflow
child run as a table.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from ..evaluate.fold_models import ROBUSTNESS_METHODS
from ..evaluate.labels import METHOD_LABELS
from ..evaluate.methods import method_params, table1_methods
from ..evaluate.robustness import Condition, evaluate_conditions, feedback_rows, feedback_steps
from ..features.dataset import read_features
from ..io import write_text_atomic
from ..logs.benchmark import load_benchmark
from ..report.csvs import OUTCOME_COLUMNS, csv_text, outcome_row
from ..report.tables import line_plot_png
from ..settings import Crossval, Feedback, Learner
from ..track.mlflow_runs import NO_RUN, Tracker

DECIMALS = {"sequence_arg": 2, "sequence_prim": 2, "success": 2}


def run(settings: Feedback, crossval: Crossval, learner: Learner, features: Path, processed: Path, output: Path,
        store: Path | None = None, n_jobs: int = 1, tracker: Tracker = NO_RUN) -> list[dict[str, Any]]:
    contexts, meta = read_features(features)
    bench = load_benchmark(processed)
    methods = table1_methods(crossval, learner, store=None if store is None else str(store))
    ns = feedback_steps(settings, crossval.max_steps)
    conditions = [Condition("feedback", k, n) for k in settings.k for n in ns]
    label = dict(zip(ns, settings.n, strict=True))  # steps -> as the settings write them ("all")
    rows, sequences = [], []
    chosen = {name: methods[name] for name in ROBUSTNESS_METHODS}
    outcomes = evaluate_conditions(chosen, contexts, meta, bench.scenarios, conditions, crossval.fold_settings,
                                   crossval.max_steps, n_jobs=n_jobs)
    for name, results in outcomes.items():
        rows += [{"method": name, **r} for r in feedback_rows(settings, crossval.max_steps, results)]
        sequences += [{"method": name, "k": int(c.a), "n": label[c.b], **outcome_row(o)} for c, o in results]
    out = Path(output)
    text = csv_text(["method", "k", "n", "sequence_arg", "sequence_prim", "success"], rows, DECIMALS)
    write_text_atomic(out / "feedback.csv", text)
    write_text_atomic(out / "feedback_sequences.csv", csv_text(["method", "k", "n", *OUTCOME_COLUMNS], sequences))
    for r in rows:
        name = r["method"]
        with tracker.child(f"feedback {name} k={r['k']} n={r['n']}",
                           {**method_params(name, methods[name]()), "k": r["k"], "n": r["n"]}) as child:
            child.metrics({k: r[k] for k in DECIMALS})
            child.table([q for q in sequences if (q["method"], q["k"], q["n"]) == (name, r["k"], r["n"])],
                        "sequences")
    series = {f"{METHOD_LABELS[m]}, top {k}": (list(range(len(ns))), [r["sequence_arg"] for r in rows
                                                                     if r["k"] == k and r["method"] == m], None)
              for m in ROBUSTNESS_METHODS for k in settings.k}
    line_plot_png(series, str(out / "feedback.png"), "Sequence accuracy (arg) with an observer's feedback",
                  "steps with feedback", "% sequences correct", xticks=list(range(len(ns))),
                  xticklabels=list(settings.n))
    for f in ("feedback.csv", "feedback.png"):
        tracker.artifact(out / f)
    print(text, end="")
    return rows
