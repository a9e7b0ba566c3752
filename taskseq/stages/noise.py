"""Stage `noise`: closed-loop sequence accuracy with binary attributes flipped at test time.

Run for the paper's full model and the best added method (`ROBUSTNESS_METHODS`).
noise_sequences.csv holds every program
of every rate and noise draw (DVC-cached, not in git), each rate's also in its
MLflow child run as a table.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from ..demonstrations.benchmark import load_benchmark
from ..evaluate.methods import method_params
from ..experiments.robustness import NoiseCondition, evaluate_conditions, noise_curve, noise_runs
from ..features.dataset import read_features
from ..methods import Lineup, method_spec
from ..report import paper
from ..report.csvs import OUTCOME_COLUMNS, RATE_DECIMALS, csv_text, outcome_row
from ..report.figures import line_plot_png
from ..runtime.atomic import write_text_atomic
from ..selection import read_selection
from ..settings import Methods, Noise, Params, Procedural, Replay
from ..track.mlflow_runs import NO_RUN, Tracker
from .options import EvaluationOptions

RATE = {"rate": 1, **dict.fromkeys(("sequence_arg", "sequence_arg_std", "sequence_prim", "success"), RATE_DECIMALS)}


@dataclass(frozen=True)
class Settings:
    noise: Noise
    replay: Replay
    methods: Methods  # those whose experiments name noise are run
    procedural: Procedural = Procedural()  # params.yaml's `procedural`: the rooms a method may draw to train on


def settings(params: Params, world_seed: int | None = None) -> Settings:
    return Settings(params.noise, Replay.of(params), params.methods, params.procedural)


def run(settings: Settings, options: EvaluationOptions, tracker: Tracker = NO_RUN,
        n_jobs: int = 1) -> list[dict[str, Any]]:
    noise = settings.noise
    replay = settings.replay
    lineup = Lineup(settings.methods, read_selection(options.selection), replay.learner, store=options.store,
                    procedural=settings.procedural)
    methods = lineup.running("noise")
    contexts, meta = read_features(options.features)
    bench = load_benchmark(options.processed)
    conditions = [NoiseCondition(r, s) for r in noise.rates for s in range(noise.draws)]
    runs, curve, sequences = [], [], []
    outcomes = evaluate_conditions(methods, contexts, meta, bench.scenarios, conditions, replay.folds,
                                   replay.max_steps, noise.seed, n_jobs)
    for name, results in outcomes.items():
        mine = noise_runs(noise, results)
        runs += [{"method": name, **r} for r in mine]
        curve += [{"method": name, **r} for r in noise_curve(noise, mine)]
        sequences += [{"method": name, "rate": c.rate, "draw": c.draw, **outcome_row(o)} for c, o in results]
    out = options.output
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
    series = {f"{method_spec(m).label} (mean, std over noise draws)":
              (list(noise.rates), [r["sequence_arg"] for r in curve if r["method"] == m],
               [r["sequence_arg_std"] for r in curve if r["method"] == m]) for m in methods}
    line_plot_png(series, str(out / "noise.png"), "Sequence accuracy (arg) with binary attributes flipped",
                  "probability of flipping each binary attribute", "% sequences correct",
                  reference={"paper": (list(paper.NOISE), list(paper.NOISE.values()))})
    for f in ("noise.csv", "noise_runs.csv", "noise.png"):
        tracker.artifact(out / f)
    print(text, end="")
    return curve
