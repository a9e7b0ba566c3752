"""The pipeline's stages, one module each, registered in one table in the order `dvc.yaml` runs them.

Every stage module holds two functions:

- `settings(params, world_seed)`: the stage's own typed settings, picked from
  `taskseq.settings.Params` (the whole `params.yaml`, overrides applied);
  the keys it reads are exactly the stage's `params` in `dvc.yaml` (a test
  checks it);
- `run(settings, options, tracker)` (plus `n_jobs` for stages that run work in
  parallel): calls the library, writes only the paths its options give, and
  logs to the tracker.

What a stage reads and writes, and the few choices of a run that are not
settings (which methods to run, how many recordings), is its `Options` class in
`taskseq.stages.options`, from which `taskseq` builds the stage's command-line
options (`taskseq.stages.command`). The table below registers each stage with
its help, its options and whether it runs work in parallel or on one world.
Nothing here loads a stage.
"""

from dataclasses import dataclass

from . import options as opts


@dataclass(frozen=True)
class Stage:
    help: str  # one line, shown by `taskseq --help`
    options: type  # its `Options` class: the command's options
    parallel: bool = False  # takes `n_jobs`
    per_world: bool = False  # runs on one world's data (`--world-seed`)
    draws: bool = False  # draws the world `--world-seed` names (required), where other stages only label runs with it
    cached: bool = False  # fits models or runs programs: takes `--cache` (`taskseq.runtime.cache`)
    # the methods whose modules it loads (`taskseq.methods.method_spec`): "" none (a stage that writes tables reads
    # the labels from taskseq/methods/labels.json), "all" every one (Table I), an experiment's (those whose entry of
    # params.yaml's `methods` names it), or "shipped": the one method `train.method` names, or when it says best the
    # one reports/selection.json ranks first
    runs: str = ""
    # dvc.yaml runs it once per method it runs (`NAME@method`), each run depending on that method's module alone
    per_method: bool = False


STAGES: dict[str, Stage] = {
    "dev_world": Stage("draw the development world (logs, tables, features) into one folder",
                       opts.WorldFolderOptions),
    "choose_C": Stage("cross-validate one MRF method on the development world at each C of the grid to choose its C",
                      opts.ChooseCOptions, True, cached=True, runs="select", per_method=True),
    "select": Stage("rank the MRF methods, each at the C the development world chose for it", opts.SelectOptions),
    "generate": Stage("simulate the demonstrator and write demonstration logs (JSON Lines)", opts.GenerateOptions,
                      per_world=True, draws=True),
    "ingest": Stage("validate logs and write them as Parquet tables plus dataset metrics", opts.IngestOptions,
                    per_world=True),
    "features": Stage("build every teacher-forced step's candidates and features from the Parquet tables",
                      opts.FeaturesOptions, per_world=True),
    "train": Stage("fit the MRF weights with the structural SVM (the paper's 1-slack objective) on every step",
                   opts.TrainOptions, per_world=True, cached=True, runs="shipped"),
    "pddl": Stage("write the PDDL domain, a problem per scenario and its shortest plan (SAT)", opts.PddlOptions,
                  per_world=True),
    "fold_models": Stage("train every MRF model the evaluation stages use, once, into a model store",
                         opts.FoldModelsOptions, True, True, cached=True, runs="all"),
    "crossval": Stage("cross-validate every method and write Table I, metrics and a confusion matrix",
                      opts.CrossvalOptions, True, True, cached=True, runs="all"),
    "noise": Stage("sequence accuracy with binary attributes flipped at test time", opts.EvaluationOptions, True, True,
                   cached=True, runs="noise"),
    "feedback": Stage("sequence accuracy when an observer picks among the top k at the first n steps",
                      opts.EvaluationOptions, True, True, cached=True, runs="feedback"),
    "recipes": Stage("chain programs into recipes in environments held out from training", opts.EvaluationOptions,
                     per_world=True, runs="recipes"),
    "drawn_world": Stage("draw a world of rooms by a reported world's seed (logs, tables, features) into one folder",
                         opts.WorldFolderOptions, per_world=True, draws=True),
    "scenes_world": Stage("one world seed with whole rooms held out of training, paper-shaped and drawn (noise and "
                          "feedback there too), and models of the paper-shaped rooms run in drawn ones",
                          opts.ScenesWorldOptions, True, True, cached=True, runs="all"),
    "scenes": Stage("Table I, failures and the transfer with rooms held out, over the world seeds",
                    opts.ScenesOptions),
    "people": Stage("check people's demonstrations, count them, and compare the planner with and without them",
                    opts.PeopleOptions, cached=True),
    "teach": Stage("the shipped planner in drawn rooms it never saw, after a scripted person shows k tasks in each",
                   opts.TeachOptions, True, cached=True, runs="shipped"),
    "aggregate": Stage("every figure over the world seeds: mean ± sd tables, failures, noise, feedback, recipes",
                       opts.AggregateOptions),
    "stats": Stage("confidence intervals of Table I by a bootstrap over worlds and scenarios; paired tests of methods",
                   opts.StatsOptions),
    "report": Stage("write reports/summary.md: every result next to the paper's figures", opts.ReportOptions),
}
