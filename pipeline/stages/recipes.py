"""Stage `recipes`: programs chained into recipes, in environments held out from training.

Run for the paper's full model and the added method that chains programs best (`RECIPE_METHODS`).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from ..evaluate.fold_models import RECIPE_METHODS
from ..evaluate.methods import METHOD_LABELS, table1_methods
from ..evaluate.recipes import RECIPES, evaluate_recipes, recipe_report
from ..features.dataset import read_features
from ..io import write_json_atomic
from ..logs.benchmark import load_benchmark
from ..settings import Crossval, Learner
from ..track.mlflow_runs import NO_RUN, Tracker


def run(crossval: Crossval, learner: Learner, features: Path, processed: Path, output: Path,
        store: Path | None = None, tracker: Tracker = NO_RUN) -> dict[str, Any]:
    contexts, meta = read_features(features)
    scenarios = load_benchmark(processed).scenarios
    methods = table1_methods(crossval, learner, store=None if store is None else str(store))
    reports = {}
    for method in RECIPE_METHODS:
        outcomes = evaluate_recipes(methods[method], contexts, meta, scenarios, max_steps=crossval.max_steps)
        reports[method] = report = recipe_report(outcomes)
        for name in dict.fromkeys(o.recipe for o in outcomes):
            mine = [o for o in outcomes if o.recipe == name]
            with tracker.child(f"{method} {name}", {"method": method, "recipe": name}) as child:
                child.metrics({"success_no_feedback": sum(o.success for o in mine if not o.feedback),
                               "success_feedback": sum(o.success for o in mine if o.feedback)})
        totals = report["totals"]
        tracker.metrics({f"{method}.{k}": float(v) for k, v in totals.items()})
        print(f"== {METHOD_LABELS[method]}")
        for o in outcomes:
            print(f"{o.recipe:24s} {o.env_id} feedback={'yes' if o.feedback else 'no ':3s} "
                  f"{'SUCCESS' if o.success else 'failed '}  "
                  + " -> ".join(f"{t} [{st}]" for t, st, _ in o.programs))
        print(f"success: {totals['no_feedback']}/{len(RECIPES)} without feedback, "
              f"{totals['feedback_first_step']}/{len(RECIPES)} with one feedback at the start of each program")
    write_json_atomic(Path(output) / "recipes.json", {"methods": reports})
    tracker.artifact(Path(output) / "recipes.json")
    return reports
