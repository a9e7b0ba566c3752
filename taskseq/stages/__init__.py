"""The pipeline's stages, one module each, registered in one table in the order `dvc.yaml` runs them.

Every stage module holds two functions:

- `settings(params, world_seed)`: the stage's own typed settings, picked from
  `taskseq.settings.Params` (the whole `params.yaml`, overrides applied);
  the keys it reads are exactly the stage's `params` in `dvc.yaml` (a test
  checks it);
- `run(settings, paths, tracker)` (plus `n_jobs` for stages that run work in
  parallel): calls the library, writes only the paths it is given, and logs
  to the tracker.

What a stage reads and writes is its `Paths` class in `taskseq.stages.paths`,
from which `taskseq` builds the stage's options (`taskseq.stages.command`).
The table below registers each stage with its help, its paths and whether it
runs work in parallel or on one world. Nothing here loads a stage.
"""

from dataclasses import dataclass

from . import paths as P


@dataclass(frozen=True)
class Stage:
    help: str  # one line, shown by `taskseq --help`
    paths: type  # its `Paths` class: the command's options
    parallel: bool = False  # takes `n_jobs`
    per_world: bool = False  # runs on one world's data (`--world-seed`)



STAGES: dict[str, Stage] = {
    "select": Stage("draw the development world; cross-validate each MRF method there to choose its own C",
                    P.SelectPaths, True),
    "generate": Stage("simulate the demonstrator and write demonstration logs (JSON Lines)", P.GeneratePaths,
                      per_world=True),
    "ingest": Stage("validate logs and write them as Parquet tables plus dataset metrics", P.IngestPaths,
                    per_world=True),
    "features": Stage("build every teacher-forced step's candidates and features from the Parquet tables",
                      P.FeaturesPaths, per_world=True),
    "train": Stage("fit the MRF weights with the structural SVM (the paper's 1-slack objective) on every step",
                   P.TrainPaths, per_world=True),
    "pddl": Stage("write the PDDL domain, a problem per scenario and its shortest plan (SAT)", P.PddlPaths,
                  per_world=True),
    "fold_models": Stage("train every MRF model the evaluation stages use, once, into a model store", P.FoldModelsPaths,
                   True, True),
    "crossval": Stage("cross-validate every method and write Table I, metrics and a confusion matrix",
                      P.CrossvalPaths, True, True),
    "noise": Stage("sequence accuracy with binary attributes flipped at test time", P.EvaluationPaths, True, True),
    "feedback": Stage("sequence accuracy when an observer picks among the top k at the first n steps",
                      P.EvaluationPaths, True, True),
    "recipes": Stage("chain programs into recipes in environments held out from training", P.EvaluationPaths,
                     per_world=True),
    "scenes": Stage("Table I and failures with whole rooms held out of training, paper-shaped and drawn (noise and "
                    "feedback there too), and models of the paper-shaped rooms run in drawn ones", P.ScenesPaths, True),
    "people": Stage("check people's demonstrations, count them, and compare the planner with and without them",
                    P.PeoplePaths),
    "teach": Stage("success on unseen environments after a scripted person demonstrates k tasks in each",
                   P.TeachPaths),
    "aggregate": Stage("every figure over the world seeds: mean ± sd tables, failures, noise, feedback, recipes",
                       P.AggregatePaths),
    "stats": Stage("confidence intervals of Table I by a bootstrap over worlds and scenarios; paired tests of methods",
                   P.StatsPaths),
    "report": Stage("write reports/summary.md: every result next to the paper's figures", P.ReportPaths),
}
