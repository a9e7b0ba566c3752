"""Stage `scenes_world`: one world seed's rooms never seen in training, beside its paper-shaped results.

On the seed's paper-shaped world and on its drawn world (`drawn_world`:
rooms, furniture and objects the catalog never had) the same stages run as on
a reported world, with folds that hold out whole rooms, their new objects
with them: the fold models and Table I, and in the drawn world attribute noise
and feedback too. The MRF methods whose `experiments` name transfer
(params.yaml's `methods`) are also trained on every step of the paper-shaped
world and run on every scenario of the drawn one; their programs and steps are
written as a cross-validation writes them, so `taskseq stats` gives the
transfer's intervals and paired tests too. The `scenes` stage puts the seeds
together.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..demonstrations.benchmark import load_benchmark
from ..evaluate.metrics import summarize
from ..experiments.transfer import transfer
from ..features.dataset import read_features
from ..methods import Lineup
from ..report.csvs import SEQUENCE_COLUMNS, STEP_COLUMNS, csv_text, sequence_rows, step_rows
from ..report.csvs import TRANSFER_COLUMNS as TRANSFER
from ..runtime.atomic import write_text_atomic
from ..selection import read_selection
from ..settings import Crossval, Folds, Learner, Methods, Params, Procedural, Replay
from ..track.mlflow_runs import NO_RUN, Tracker
from . import crossval, feedback, fold_models, noise
from .options import CrossvalOptions, EvaluationOptions, FoldModelsOptions, ScenesWorldOptions


@dataclass(frozen=True)
class Settings:
    fold_models: fold_models.Settings
    crossval: crossval.Settings
    noise: noise.Settings
    feedback: feedback.Settings
    methods: Methods  # those whose experiments name transfer: trained on the paper-shaped world, run on the drawn one
    learner: Learner
    procedural: Procedural
    paper_shaped: bool = True  # the reported worlds are the paper's rooms; drawn ones leave no transfer to measure


def settings(params: Params, world_seed: int | None = None) -> Settings:
    c, learner = params.crossval, params.train.learner
    rooms = Folds(c.folds, "environment", c.seed)  # whole rooms held out, whatever crossval.group_by says
    replay = Replay(rooms, c.max_steps, learner)
    return Settings(
        fold_models=fold_models.Settings(rooms, learner, params.methods, False, params.procedural),
        crossval=crossval.Settings(Crossval(c.folds, "environment", c.seed, c.chance_seed, c.multiclass_C,
                                            c.multiclass_tol, c.ranking_C, c.max_steps), learner,
                                   params.pddl.horizon, params.methods, params.procedural),
        noise=noise.Settings(params.noise, replay, params.methods, params.procedural),
        feedback=feedback.Settings(params.feedback, replay, params.methods, params.procedural),
        methods=params.methods,
        learner=learner,
        procedural=params.procedural,
        paper_shaped=params.world.family == "paper",
    )


def run(settings: Settings, options: ScenesWorldOptions, tracker: Tracker = NO_RUN, n_jobs: int = 1) -> None:
    # a missing world, a wrong entry or a missing C stops here, before minutes of work
    for world, made_by in ((options.paper, "taskseq features"), (options.drawn, "taskseq drawn_world")):
        for part in ("features", "processed"):
            if not (world / part).is_dir():
                raise FileNotFoundError(f"{world / part}: no such folder; --paper and --drawn name world folders "
                                        f"with features and processed tables ({made_by} writes them)")
    _transferred(settings, options)
    print(f"the paper-shaped rooms of {options.paper}, each held out in turn")
    _held_out_rooms(settings, options, options.paper, options.paper_results, tracker, n_jobs)
    print(f"the drawn rooms of {options.drawn}, each held out in turn")
    evaluation = _held_out_rooms(settings, options, options.drawn, options.drawn_results, tracker, n_jobs)
    noise.run(settings.noise, evaluation, tracker, n_jobs)
    feedback.run(settings.feedback, evaluation, tracker, n_jobs)
    options.transfer_results.mkdir(parents=True, exist_ok=True)  # a declared output, empty when nothing transfers
    if settings.paper_shaped:
        _transfer(settings, options, tracker, n_jobs)


def _held_out_rooms(settings: Settings, options: ScenesWorldOptions, world: Path, here: Path, tracker: Tracker,
                    n_jobs: int) -> EvaluationOptions:
    """Fold models and Table I of one world's data (`world`: its features and tables), whole rooms held out, into
    `here`; the paths under which further evaluations of that world find its data and fold models."""
    data = {"features": world / "features", "processed": world / "processed", "selection": options.selection}
    fold_models.run(settings.fold_models, FoldModelsOptions(**data, output=here / "folds"), tracker, n_jobs)
    evaluation = EvaluationOptions(**data, model_store=here / "folds", output=here)
    crossval.run(settings.crossval, CrossvalOptions(**vars(evaluation), recordings=0), tracker, n_jobs)
    return evaluation


def _transfer(settings: Settings, options: ScenesWorldOptions, tracker: Tracker, n_jobs: int) -> None:
    """The transfer methods trained on the paper-shaped world and run on the drawn one: their programs and steps
    into `transfer_results` as a cross-validation's are written (for `taskseq stats`), their figures into the
    drawn world's results (transfer.csv)."""
    paper, drawn = options.paper, options.drawn
    train = (*read_features(paper / "features"), load_benchmark(paper / "processed"))
    test = (*read_features(drawn / "features"), load_benchmark(drawn / "processed"))
    methods = _transferred(settings, options)
    print(f"training {', '.join(methods)} on the paper-shaped world ({len(train[0])} steps) and running them "
          f"on the drawn one ({len(test[2].scenarios)} scenarios)")
    results, contexts, meta = transfer(methods, train, test, settings.crossval.crossval.max_steps, n_jobs)
    predicts_args = dict.fromkeys(methods, True)
    summary = summarize(results, contexts, predicts_args)
    moved = options.transfer_results
    write_text_atomic(moved / "crossval_sequences.csv", csv_text(SEQUENCE_COLUMNS, sequence_rows(results)))
    write_text_atomic(moved / "crossval_steps.csv", csv_text(STEP_COLUMNS, step_rows(results, contexts, meta,
                                                                                      predicts_args)))
    rows = [{"method": name, **{k: summary[name][k.replace("sequence_", "sequence/")] for k in TRANSFER}}
            for name in methods]
    write_text_atomic(options.drawn_results / "transfer.csv", csv_text(["method", *TRANSFER], rows,
                                                                       dict.fromkeys(TRANSFER, 2)))
    tracker.metrics({f"transfer.{r['method']}.{k}": r[k] for r in rows for k in TRANSFER})


def _transferred(settings: Settings, options: ScenesWorldOptions) -> dict[str, Any]:
    """The MRF methods the transfer experiment runs, by name, as factories of unfitted methods."""
    return Lineup(settings.methods, read_selection(options.selection), settings.learner,
                  procedural=settings.procedural).running("transfer")
