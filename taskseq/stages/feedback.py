"""Stage `feedback`: sequence accuracy when an observer picks among the top k candidates at the first n steps.

Run for the paper's full model and the best added method (`ROBUSTNESS_METHODS`).
feedback_sequences.csv holds every program of
every (k, n) (DVC-cached, not in git), each condition's also in its MLflow
child run as a table.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from ..demonstrations.benchmark import load_benchmark
from ..evaluate.methods import method_params
from ..experiments.robustness import FeedbackCondition, evaluate_conditions, feedback_rows, feedback_steps
from ..features.dataset import read_features
from ..methods import Lineup, method_spec
from ..report.csvs import OUTCOME_COLUMNS, RATE_DECIMALS, csv_text, outcome_row
from ..report.figures import line_plot_png
from ..runtime.atomic import write_text_atomic
from ..selection import read_selection
from ..settings import Feedback, Methods, Params, Procedural, Replay
from ..track.mlflow_runs import NO_RUN, Tracker
from .options import EvaluationOptions

DECIMALS = dict.fromkeys(("sequence_arg", "sequence_prim", "success"), RATE_DECIMALS)


@dataclass(frozen=True)
class Settings:
    feedback: Feedback
    replay: Replay
    methods: Methods  # those whose experiments name feedback are run
    procedural: Procedural = Procedural()  # params.yaml's `procedural`: the rooms a method may draw to train on


def settings(params: Params, world_seed: int | None = None) -> Settings:
    return Settings(params.feedback, Replay.of(params), params.methods, params.procedural)


def run(settings: Settings, options: EvaluationOptions, tracker: Tracker = NO_RUN,
        n_jobs: int = 1) -> list[dict[str, Any]]:
    feedback = settings.feedback
    replay = settings.replay
    lineup = Lineup(settings.methods, read_selection(options.selection), replay.learner, store=options.store,
                    procedural=settings.procedural)
    methods = lineup.running("feedback")
    contexts, meta = read_features(options.features)
    bench = load_benchmark(options.processed)
    ns = feedback_steps(feedback, replay.max_steps)
    conditions = [FeedbackCondition(k, n) for k in feedback.k for n in ns]
    label = dict(zip(ns, feedback.n, strict=True))  # steps -> as the settings write them ("all")
    rows, sequences = [], []
    outcomes = evaluate_conditions(methods, contexts, meta, bench.scenarios, conditions, replay.folds,
                                   replay.max_steps, n_jobs=n_jobs)
    for name, results in outcomes.items():
        rows += [{"method": name, **r} for r in feedback_rows(feedback, replay.max_steps, results)]
        sequences += [{"method": name, "k": c.k, "n": label[c.n], **outcome_row(o)} for c, o in results]
    out = options.output
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
    series = {f"{method_spec(m).label}, top {k}": (list(range(len(ns))), [r["sequence_arg"] for r in rows
                                                                     if r["k"] == k and r["method"] == m], None)
              for m in methods for k in feedback.k}
    line_plot_png(series, str(out / "feedback.png"), "Sequence accuracy (arg) with an observer's feedback",
                  "steps with feedback", "% sequences correct", xticks=list(range(len(ns))),
                  xticklabels=list(feedback.n))
    for f in ("feedback.csv", "feedback.png"):
        tracker.artifact(out / f)
    print(text, end="")
    return rows
