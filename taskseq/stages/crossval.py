"""Stage `crossval`: every method of Table I over grouped folds, teacher-forced and closed-loop.

Writes Table I (long CSV, Markdown, LaTeX), the per-method summary, the metrics
DVC tracks, every teacher-forced step's outcome, every closed-loop program (also each method's own in its MLflow
child run, as a table), a confusion matrix of the full model and, when asked,
Rerun recordings of some of its programs.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..demonstrations.benchmark import load_benchmark
from ..evaluate.methods import method_params
from ..evaluate.metrics import confusion, headline_metrics, summarize
from ..experiments.crossval import cross_validate
from ..features.dataset import read_features
from ..methods import Lineup, method_labels
from ..plan.symbolic.files import file_stem
from ..report.csvs import SEQUENCE_COLUMNS, STEP_COLUMNS, csv_text, sequence_rows, step_rows
from ..report.figures import confusion_png
from ..report.tables import table_rows, to_csv, to_latex, to_markdown
from ..runtime.atomic import write_json_atomic, write_text_atomic
from ..selection import read_selection
from ..settings import Crossval, Learner, Methods, Params, Procedural
from ..track.mlflow_runs import NO_RUN, Tracker
from .options import CrossvalOptions


@dataclass(frozen=True)
class Settings:
    crossval: Crossval
    learner: Learner
    horizon: int  # longest plan of the symbolic baselines
    methods: Methods
    procedural: Procedural = Procedural()  # params.yaml's `procedural`: the rooms a method may draw to train on


def settings(params: Params, world_seed: int | None = None) -> Settings:
    return Settings(params.crossval, params.train.learner, params.pddl.horizon, params.methods, params.procedural)


def _spread(ids: list[str], n: int) -> frozenset[str]:
    """`n` of the ids, evenly spaced in sorted order: the scenarios whose programs are recorded."""
    ids = sorted(ids)
    return frozenset(ids[:: max(1, len(ids) // n)][:n]) if n > 0 else frozenset()


def run(settings: Settings, options: CrossvalOptions, tracker: Tracker = NO_RUN, n_jobs: int = 1) -> dict[str, Any]:
    crossval, methods, output = settings.crossval, options.methods, options.output
    lineup = Lineup(settings.methods, read_selection(options.selection), settings.learner, crossval, settings.horizon,
                    options.store, settings.procedural)
    every = lineup.names()
    unknown = set(methods or []) - set(every)
    if unknown:
        raise ValueError(f"unknown methods {sorted(unknown)}; known: {', '.join(every)}")
    factories = lineup.factories([name for name in every if methods is None or name in methods])
    contexts, meta = read_features(options.features)
    bench = load_benchmark(options.processed)
    print(f"cross-validating {', '.join(factories)} over {crossval.folds} folds grouped by {crossval.group_by} "
          f"({len(bench.scenarios)} scenarios, {len(contexts)} steps, {n_jobs} jobs)")
    recorded = _spread(list(bench.scenarios), options.recordings)
    results = cross_validate(factories, contexts, meta, bench, n_folds=crossval.folds, seed=crossval.seed,
                             group_by=crossval.group_by, max_steps=crossval.max_steps, n_jobs=n_jobs, verbose=5,
                             keep_programs={"full": recorded})
    predicts_args = {k: v().predicts_args for k, v in factories.items()}
    summary = summarize(results, contexts, predicts_args)
    rows = table_rows(summary, method_labels())
    out = Path(output)
    write_text_atomic(out / "table1.csv", to_csv(rows))
    write_text_atomic(out / "table1.md", to_markdown(rows))
    caption = (f"{crossval.folds}-fold cross-validation grouped by {crossval.group_by} on {len(bench.scenarios)} "
               "scenarios: percentage of primitives (prim) and of primitives with arguments (arg) right, "
               "teacher-forced, and of closed-loop sequences equal to a demonstration.")
    write_text_atomic(out / "table1.tex", to_latex(rows, caption))
    write_json_atomic(out / "crossval.json", summary)
    write_json_atomic(out / "metrics.json", headline_metrics(summary))
    sequences = sequence_rows(results)
    write_text_atomic(out / "crossval_sequences.csv", csv_text(SEQUENCE_COLUMNS, sequences))
    write_text_atomic(out / "crossval_steps.csv", csv_text(STEP_COLUMNS, step_rows(results, contexts, meta,
                                                                                   predicts_args)))
    for name, entry in summary.items():
        with tracker.child(name, method_params(name, factories[name]())) as child:
            child.metrics({k.replace("/", "_"): v for k, v in entry["steps"].items()})
            child.metrics({k: v for k, v in entry.items() if k in ("sequence/prim", "sequence/arg", "success",
                                                                    "goal_reached")})
            child.table([r for r in sequences if r["method"] == name], "sequences")
    if "full" in factories:
        full = [r for r in results if r.method == "full"]
        index = [i for r in full for i in r.step_index]
        preds = [y for r in full for y in r.step_predictions]
        confusion_png(confusion([contexts[i] for i in index], preds), str(out / "confusion.png"),
                      "full model, teacher-forced, cross-validated")
    if recorded:  # Rerun takes half a second to import; `scenes_world` runs this stage recording nothing
        from ..track.recordings import record_program
    for r in results:
        for sid, program in r.programs.items():
            path = Path(options.recordings_dir or out / "recordings") / f"{file_stem(sid)}.rrd"
            record_program(path, sid, program, bench.scenarios[sid].demonstrations[0])
            tracker.artifact(path, "recordings")
    for f in ("table1.csv", "table1.md", "table1.tex", "metrics.json", "confusion.png"):
        tracker.artifact(out / f)
    print(to_markdown(rows))
    return summary
