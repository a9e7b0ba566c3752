"""Stage `scenes`: generalisation to rooms never seen in training, beside the paper-shaped results.

Each reported world seed also draws a procedural world (`procedural` in
params.yaml: rooms, furniture and objects the catalog never had). On it the
same stages run as on a paper-shaped world, with folds that hold out whole
rooms, their new objects with them: generate, ingest, features, the fold
models, Table I, attribute noise and feedback. The MRF methods whose
`experiments` name transfer (params.yaml's `methods`) are also trained on every step of the seed's paper-shaped
world and run on every scenario of its drawn world; their programs and steps go to
`data/scenes/transfer/<seed>/` in the files a cross-validation writes, so
`taskseq stats` gives the transfer's intervals and paired tests too. The tables over seeds
(mean ± sd) are written as the `aggregate` stage writes the paper-shaped ones.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from ..demonstrations.benchmark import load_benchmark
from ..evaluate.metrics import summarize
from ..experiments.transfer import transfer
from ..features.dataset import read_features
from ..methods import Lineup, method_labels
from ..report.csvs import SEQUENCE_COLUMNS, STEP_COLUMNS, csv_text, sequence_rows, step_rows
from ..report.seeds import curve_over_seeds, json_over_seeds, world_dirs
from ..runtime.atomic import write_json_atomic, write_text_atomic
from ..selection import read_selection
from ..settings import Crossval, Folds, Generate, Learner, Methods, Params, Replay, World
from ..track.mlflow_runs import NO_RUN, Tracker
from . import aggregate, crossval, features, feedback, fold_models, generate, ingest, noise
from .options import (
    AggregateOptions,
    CrossvalOptions,
    EvaluationOptions,
    FeaturesOptions,
    FoldModelsOptions,
    GenerateOptions,
    IngestOptions,
    ScenesOptions,
)

TRANSFER = ("sequence_arg", "sequence_prim", "success", "goal_reached")
# the reported worlds are drawn (world.family procedural): the drawn world of a seed is then the reported world
# itself, scenario for scenario, so nothing is trained on one and tested on the other
NO_TRANSFER = ("Not measured: the reported worlds are drawn (`world.family: procedural`), so a seed's drawn world "
               "is its reported world and no paper-shaped world is there to train on.\n")


@dataclass(frozen=True)
class Settings:
    world: Generate  # family procedural; the seed is each of `seeds` in turn
    seeds: tuple[int, ...]
    fold_models: fold_models.Settings
    crossval: crossval.Settings
    noise: noise.Settings
    feedback: feedback.Settings
    methods: Methods  # those whose experiments name transfer: trained on the paper-shaped world, run on the drawn one
    learner: Learner
    paper_shaped: bool = True  # the reported worlds are the paper's rooms; drawn ones leave no transfer to measure


def settings(params: Params, world_seed: int | None = None) -> Settings:
    c, learner = params.crossval, params.train.learner
    rooms = Folds(c.folds, "environment", c.seed)  # whole rooms held out, whatever crossval.group_by says
    replay = Replay(rooms, c.max_steps, learner)
    return Settings(
        world=Generate(family="procedural", procedural=params.procedural),
        seeds=params.world.seeds,
        fold_models=fold_models.Settings(rooms, learner, params.methods, False, params.procedural),
        crossval=crossval.Settings(Crossval(c.folds, "environment", c.seed, c.chance_seed, c.multiclass_C,
                                            c.ranking_C, c.max_steps), learner, params.pddl.horizon, params.methods,
                                            params.procedural),
        noise=noise.Settings(params.noise, replay, params.methods, params.procedural),
        feedback=feedback.Settings(params.feedback, replay, params.methods, params.procedural),
        methods=params.methods,
        learner=learner,
        paper_shaped=params.world.family == "paper",
    )


def run(settings: Settings, options: ScenesOptions, tracker: Tracker = NO_RUN, n_jobs: int = 1) -> dict[str, Any]:
    _transferred(settings, options)  # a wrong entry or a missing C stops here, before minutes of work
    data, out = Path(options.data), Path(options.output)
    for seed in settings.seeds:
        with tracker.child(f"world={seed}", {"world_seed": seed}) as child:
            print(f"world seed {seed}: the paper-shaped rooms, each held out in turn")
            _held_out_rooms(settings, options, Path(options.paper) / str(seed), data / "paper" / str(seed), child,
                            n_jobs)
            print(f"world seed {seed}: {settings.world.procedural.environments} drawn rooms")
            _drawn_world(settings, options, seed, data / "drawn" / str(seed), data / "transfer" / str(seed), child,
                         n_jobs)
    world = World(seeds=settings.seeds)
    aggregate.run(world, AggregateOptions(worlds=data / "paper", output=out / "paper"), tracker)
    aggregate.run(replace(world, family="procedural"), AggregateOptions(worlds=data / "drawn", output=out / "drawn"),
                  tracker)
    dirs = world_dirs(data / "drawn", settings.seeds)
    draws = json_over_seeds(dirs, "world.json")
    write_json_atomic(out / "drawn" / "worlds.json", {str(s): d for s, d in draws.items()})
    per_seed, over_seeds = curve_over_seeds(dirs, "transfer.csv", ["method"], TRANSFER) if settings.paper_shaped \
        else ([], [])
    write_text_atomic(out / "transfer_seeds.csv",
                      csv_text(["world_seed", "method", *TRANSFER], per_seed, dict.fromkeys(TRANSFER, 2)))
    columns = ["method"] + [c for v in TRANSFER for c in (v, f"{v}_sd")]
    write_text_atomic(out / "transfer.csv", csv_text(columns, over_seeds, dict.fromkeys(columns[1:], 2)))
    # unrounded, for what formats the means again (the summary): a figure rounded twice can differ from transfer.md
    write_json_atomic(out / "transfer.json", {r["method"]: {c: r[c] for c in columns[1:]} for r in over_seeds})
    table = transfer_markdown(over_seeds, len(settings.seeds)) if settings.paper_shaped else NO_TRANSFER
    write_text_atomic(out / "transfer.md", table)
    tracker.metrics({f"transfer.{r['method']}.{k}": r[k] for r in over_seeds for k in TRANSFER})
    print(table)
    return {"transfer": over_seeds}


def _held_out_rooms(settings: Settings, options: ScenesOptions, world: Path, here: Path, tracker: Tracker,
                    n_jobs: int) -> EvaluationOptions:
    """Fold models and Table I of one world's data (`world`: its features and tables), whole rooms held out, into
    `here`; the paths under which further evaluations of that world find its data and fold models."""
    data = {"features": world / "features", "processed": world / "processed", "selection": options.selection}
    fold_models.run(settings.fold_models, FoldModelsOptions(**data, output=here / "folds"), tracker, n_jobs)
    evaluation = EvaluationOptions(**data, model_store=here / "folds", output=here)
    crossval.run(settings.crossval, CrossvalOptions(**vars(evaluation), recordings=0), tracker, n_jobs)
    return evaluation


def _drawn_world(settings: Settings, options: ScenesOptions, seed: int, here: Path, moved: Path, tracker: Tracker,
                 n_jobs: int) -> None:
    """The per-world stages on the drawn world `seed`, into `here`, then the transfer from the paper-shaped one
    (when the reported worlds are paper-shaped), its programs and steps into `moved` as a cross-validation's are
    written (for `taskseq stats`)."""
    raw, processed, feats = here / "raw", here / "processed", here / "features"
    generate.run(replace(settings.world, seed=seed), GenerateOptions(output=raw, metrics=here / "world.json"), tracker)
    ingest.run(None, IngestOptions(input=raw, output=processed, metrics=here / "dataset.json"), tracker)
    features.run(None, FeaturesOptions(input=processed, output=feats), tracker)
    evaluation = _held_out_rooms(settings, options, here, here, tracker, n_jobs)
    noise.run(settings.noise, evaluation, tracker, n_jobs)
    feedback.run(settings.feedback, evaluation, tracker, n_jobs)
    if not settings.paper_shaped:
        return
    paper = Path(options.paper) / str(seed)
    train = (*read_features(paper / "features"), load_benchmark(paper / "processed"))
    test = (*read_features(feats), load_benchmark(processed))
    methods = _transferred(settings, options)
    print(f"training {', '.join(methods)} on the paper-shaped world {seed} ({len(train[0])} steps) and running them "
          f"on the drawn one ({len(test[2].scenarios)} scenarios)")
    results, contexts, meta = transfer(methods, train, test, settings.crossval.crossval.max_steps, n_jobs)
    predicts_args = dict.fromkeys(methods, True)
    summary = summarize(results, contexts, predicts_args)
    write_text_atomic(moved / "crossval_sequences.csv", csv_text(SEQUENCE_COLUMNS, sequence_rows(results)))
    write_text_atomic(moved / "crossval_steps.csv", csv_text(STEP_COLUMNS, step_rows(results, contexts, meta,
                                                                                      predicts_args)))
    rows = [{"method": name, **{k: summary[name][k.replace("sequence_", "sequence/")] for k in TRANSFER}}
            for name in methods]
    write_text_atomic(here / "transfer.csv", csv_text(["method", *TRANSFER], rows, dict.fromkeys(TRANSFER, 2)))
    tracker.metrics({f"transfer.{r['method']}.{k}": r[k] for r in rows for k in TRANSFER})


def _transferred(settings: Settings, options: ScenesOptions) -> dict[str, Any]:
    """The MRF methods the transfer experiment runs, by name, as factories of unfitted methods."""
    return Lineup(settings.methods, read_selection(options.selection), settings.learner,
                  procedural=settings.world.procedural).running("transfer")


def transfer_markdown(rows: list[dict[str, Any]], n_seeds: int) -> str:
    """The transfer table: each method trained on the paper-shaped rooms, run in drawn ones."""
    labels = method_labels()
    lines = [f"Trained on every step of the paper-shaped world, run on every scenario of the drawn world of the same "
             f"seed: % of programs, mean ± sd over {n_seeds} world seeds.", "",
             "| method | " + " | ".join(k.replace("_", " ") for k in TRANSFER) + " |",
             "|---|" + "---:|" * len(TRANSFER)]
    lines += [f"| {labels.get(r['method'], r['method'])} | "
              + " | ".join(f"{r[k]:.1f} ± {r[f'{k}_sd']:.1f}" for k in TRANSFER) + " |" for r in rows]
    return "\n".join(lines) + "\n"
