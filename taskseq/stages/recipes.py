"""Stage `recipes`: programs chained into recipes, in environments held out from training.

Run for the methods whose entry in params.yaml's `methods` section names recipes: the paper's full model and
the added methods that chain programs best on the development world.
recipes_programs.csv holds every program of
every recipe run (DVC-cached, not in git), each recipe's also in its MLflow
child run as a table.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from ..demonstrations.benchmark import load_benchmark
from ..evaluate.methods import method_params
from ..experiments.recipes import PROGRAM_COLUMNS, RECIPES, evaluate_recipes, program_rows, recipe_report
from ..features.dataset import read_features
from ..methods import Lineup, method_spec
from ..report.csvs import csv_text
from ..runtime.atomic import write_json_atomic, write_text_atomic
from ..selection import read_selection
from ..settings import Learner, Methods, Params, Procedural, Recipes
from ..track.mlflow_runs import NO_RUN, Tracker
from .options import EvaluationOptions


@dataclass(frozen=True)
class Settings:
    recipes: Recipes
    max_steps: int  # step cap of each program
    learner: Learner
    methods: Methods  # those whose experiments name recipes are run
    procedural: Procedural = Procedural()  # params.yaml's `procedural`: the rooms a method may draw to train on


def settings(params: Params, world_seed: int | None = None) -> Settings:
    return Settings(params.recipes, params.crossval.max_steps, params.train.learner, params.methods,
                    params.procedural)


def run(settings: Settings, options: EvaluationOptions, tracker: Tracker = NO_RUN) -> dict[str, Any]:
    lineup = Lineup(settings.methods, read_selection(options.selection), settings.learner, store=options.store,
                    procedural=settings.procedural)
    methods = lineup.running("recipes")
    contexts, meta = read_features(options.features)
    scenarios = load_benchmark(options.processed).scenarios
    reports, programs = {}, []
    for method in methods:
        outcomes = evaluate_recipes(methods[method], contexts, meta, scenarios, max_steps=settings.max_steps,
                                    observer_k=settings.recipes.observer_k)
        reports[method] = report = recipe_report(outcomes)
        mine = [{"method": method, **r} for r in program_rows(outcomes)]
        programs += mine
        for name in dict.fromkeys(o.recipe for o in outcomes):
            runs = [o for o in outcomes if o.recipe == name]
            with tracker.child(f"{method} {name}", {**method_params(method, methods[method]()),
                                                    "recipe": name}) as child:
                child.metrics({"success_no_feedback": sum(o.success for o in runs if not o.feedback),
                               "success_feedback": sum(o.success for o in runs if o.feedback)})
                child.table([r for r in mine if r["recipe"] == name], "programs")
        totals = report["totals"]
        tracker.metrics({f"{method}.{k}": float(v) for k, v in totals.items()})
        print(f"== {method_spec(method).label}")
        for o in outcomes:
            print(f"{o.recipe:24s} {o.env_id} feedback={'yes' if o.feedback else 'no ':3s} "
                  f"{'SUCCESS' if o.success else 'failed '}  "
                  + " -> ".join(f"{t} [{st}]" for t, st, _ in o.programs))
        print(f"success: {totals['no_feedback']}/{len(RECIPES)} without feedback, "
              f"{totals['feedback_first_step']}/{len(RECIPES)} with one feedback at the start of each program")
    write_json_atomic(options.output / "recipes.json", {"methods": reports})
    write_text_atomic(options.output / "recipes_programs.csv", csv_text(["method", *PROGRAM_COLUMNS], programs))
    tracker.artifact(options.output / "recipes.json")
    return reports
