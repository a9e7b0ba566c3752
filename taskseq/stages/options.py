"""Each stage's command-line options (`dvc.yaml` passes these and nothing else): what it reads and writes, and
the few choices of one run that are not settings of `params.yaml` (the methods to run, the recordings to make,
whether a folder holds people's demonstrations).

One frozen dataclass per stage, `<Stage>Options`; `taskseq` turns each field into an option
(`model_store` into `--model-store`), with the field's help and default. A
field without a default is a required option. Fields marked `input` are
hashed into the stage's MLflow run (`data.hash`), so two runs can be told
apart by what they read. The module imports nothing heavy: the command line
is built from it without loading any stage.
"""

from __future__ import annotations

from dataclasses import MISSING, dataclass, field, fields
from pathlib import Path
from typing import Any

WORLD = Path("data/worlds/0")  # inputs default to the first reported world's data
# what becomes of an output folder that exists (`runtime.atomic.atomic_directory`)
REPLACED = "(replaced whole; refused if it holds a file this run does not write again)"


def option(help: str, default: Any = MISSING, *, input: bool = False, kind: type = Path,
           nargs: str | None = None) -> Any:
    """A field that becomes a command-line option."""
    meta = {"help": help, "input": input, "kind": kind, "nargs": nargs}
    return field(metadata=meta) if default is MISSING else field(default=default, metadata=meta)


def _selection() -> Any:
    return option("take each MRF method's C from this file written by `taskseq select` (default: no file: every "
                  "method at C = 3, taskseq.selection.UNTUNED_C, untuned)", None)


def _store() -> Any:
    return option("folder written by `taskseq fold_models`: models trained on the same steps with the same settings "
                  "are loaded from it instead of trained again (default: no store: every model is trained in this "
                  "run)", None)


@dataclass(frozen=True, kw_only=True)
class WorldFolderOptions:
    """A whole world drawn into one folder: its logs (raw), tables (processed), features and what drawing it cost
    (world.json, dataset.json)."""

    output: Path = option("folder for the world's raw, processed and features subfolders, world.json and "
                          "dataset.json " + REPLACED)


@dataclass(frozen=True, kw_only=True)
class ChooseCOptions:
    method: str = option("the MRF method whose C to choose (a name of params.yaml's methods section)", kind=str)
    world: Path = option("the development world's folder as `taskseq dev_world` writes it (its world.json, "
                         "processed tables and features)", Path("data/dev"), input=True)
    output: Path = option("the method's choice: every C tried with its figures, the chosen C (JSON)")


@dataclass(frozen=True, kw_only=True)
class SelectOptions:
    choices: Path = option("folder of the files `taskseq choose_C` wrote, one per method (NAME.json)",
                           Path("reports/select"), input=True)
    output: Path = option("each method's C and the ranking (JSON; the file every `--selection` option reads)")


@dataclass(frozen=True, kw_only=True)
class GenerateOptions:
    output: Path = option("folder of *.jsonl logs " + REPLACED)
    metrics: Path | None = option("what drawing the world cost: rooms, redraws by reason (JSON; default: not "
                                  "written)", None)


@dataclass(frozen=True, kw_only=True)
class IngestOptions:
    input: Path = option("folder of *.jsonl logs", WORLD / "raw", input=True)
    output: Path = option("folder of Parquet tables " + REPLACED)
    metrics: Path | None = option("dataset counts as JSON (default: not written)", None)
    people: bool = option("the folder holds people's demonstrations (`taskseq serve`): a file with a problem is "
                          "reported and left out, and an object id may mean different objects in different "
                          "environments (versions of a room)", False, kind=bool)


@dataclass(frozen=True, kw_only=True)
class FeaturesOptions:
    input: Path = option("folder of Parquet tables", WORLD / "processed", input=True)
    output: Path = option("feature folder " + REPLACED)


@dataclass(frozen=True, kw_only=True)
class TrainOptions:
    features: Path = option("feature folder", WORLD / "features", input=True)
    processed: Path | None = option("folder of Parquet tables: the training scenarios, which methods with chained "
                                    "starts or DAgger need (default: not read)", None, input=True)
    selection: Path | None = option("the file `taskseq select` wrote: each method's C, and the method when "
                                    "train.method is best, as params.yaml has it (then required); without it a "
                                    "method named by train.method trains at C = 3 (taskseq.selection.UNTUNED_C)",
                                    None)
    model: Path = option("model file to write (.npz)")
    metrics: Path | None = option("training metrics (JSON; default: not written)", None)
    curve: Path | None = option("objective per iteration (CSV; default: not written)", None)


@dataclass(frozen=True, kw_only=True)
class PddlOptions:
    processed: Path = option("folder of Parquet tables", WORLD / "processed", input=True)
    output: Path = option("folder to write " + REPLACED)


@dataclass(frozen=True, kw_only=True)
class WorldOptions:
    """The data of one world, and the choice of C: what every evaluation stage reads."""

    features: Path = option("feature folder", WORLD / "features", input=True)
    processed: Path = option("folder of Parquet tables", WORLD / "processed", input=True)
    selection: Path | None = _selection()


@dataclass(frozen=True, kw_only=True)
class FoldModelsOptions(WorldOptions):
    output: Path = option("model store folder to write " + REPLACED)
    metrics: Path | None = option("training times and objectives (JSON; default: not written)", None)


@dataclass(frozen=True, kw_only=True)
class EvaluationOptions(WorldOptions):
    model_store: Path | None = _store()
    output: Path = option("folder for the results")

    @property
    def store(self) -> str | None:
        """The model store as the methods take it (`ScorerMethod.store`), or None to train."""
        return None if self.model_store is None else str(self.model_store)


@dataclass(frozen=True, kw_only=True)
class CrossvalOptions(EvaluationOptions):
    methods: tuple[str, ...] | None = option("run only these methods (default: every method of Table I)", None,
                                             kind=str, nargs="+")
    recordings: int = option("Rerun recordings of the full model's programs, spread over the scenarios; changes no "
                             "result", 6, kind=int)
    recordings_dir: Path | None = option("folder for the recordings (default OUTPUT/recordings)", None)


@dataclass(frozen=True, kw_only=True)
class ScenesWorldOptions:
    selection: Path | None = _selection()
    paper: Path = option("the paper-shaped world's folder: its features and processed tables (its rooms held out "
                         "in turn, and the transfer's training data)", WORLD, input=True)
    drawn: Path = option("the drawn world's folder as `taskseq drawn_world` writes it", Path("data/drawn/0"),
                         input=True)
    paper_results: Path = option("folder for the paper-shaped world's fold models and results, rooms held out "
                                 + REPLACED)
    drawn_results: Path = option("folder for the drawn world's fold models and results, rooms held out, noise and "
                                 "feedback among them " + REPLACED)
    transfer_results: Path = option("folder for the programs and steps of the models trained on the paper-shaped "
                                    "world and run in the drawn one, as a cross-validation writes them (replaced; "
                                    "empty when the reported worlds are drawn themselves)")


@dataclass(frozen=True, kw_only=True)
class ScenesOptions:
    results: Path = option("folder of the per-world results of `taskseq scenes_world`: paper/SEED, drawn/SEED and "
                           "transfer/SEED", Path("data/scenes"), input=True)
    worlds: Path = option("folder of the drawn worlds, one subfolder per seed with its world.json and dataset.json",
                          Path("data/drawn"), input=True)
    output: Path = option("folder for the tables over seeds")


@dataclass(frozen=True, kw_only=True)
class PeopleOptions:
    features: Path = option("the steps the planner is trained on before people's demonstrations", WORLD / "features",
                            input=True)
    selection: Path | None = _selection()
    output: Path = option("folder for dataset.json and before_after.{json,md}")


@dataclass(frozen=True, kw_only=True)
class TeachOptions:
    worlds: Path = option("folder of the drawn worlds (`taskseq drawn_world`'s), one subfolder per seed with its "
                          "processed tables", Path("data/drawn"), input=True)
    selection: Path | None = option("the file `taskseq select` wrote: the shipped planner is the method it ranks "
                                    "first, at its C", Path("reports/selection.json"), input=True)
    output: Path = option("folder for teach.{csv,md,png}, teach_seeds.csv and teach_programs.csv")


@dataclass(frozen=True, kw_only=True)
class AggregateOptions:
    worlds: Path = option("folder of the per-world results, one subfolder per seed", Path("reports/worlds"),
                          input=True)
    output: Path = option("folder for the tables over seeds")


@dataclass(frozen=True, kw_only=True)
class StatsOptions:
    worlds: Path = option("folder of the per-world results, one subfolder per seed (their crossval_sequences.csv "
                          "and crossval_steps.csv)", Path("reports/worlds"), input=True)
    output: Path = option("folder for the intervals and comparisons")
    selection: Path | None = option("also compare every added method with the method ranked first in this file "
                                    "written by `taskseq select` (the shipped planner; default: no file, no such "
                                    "comparison)", None, input=True)


@dataclass(frozen=True, kw_only=True)
class ReportOptions:
    reports: Path = option("folder of the stages' results", Path("reports"), input=True)
    output: Path = option("Markdown file to write")
    plots_template: Path | None = option("also write the offline page template of `dvc plots show` here "
                                         "(default: not written)", None)


def inputs(options: Any) -> list[Path]:
    """The inputs the stage was given, for the hash of what it read."""
    return [getattr(options, f.name) for f in fields(options) if f.metadata["input"] and getattr(options, f.name)]
