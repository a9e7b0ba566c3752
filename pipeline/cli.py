"""The `taskseq` command line: argument parsing only.

One subcommand per pipeline stage (`pipeline/stages/`), plus tools. A stage's
options default to `pipeline/settings.py`, which equals `params.yaml`, so the
command a stage runs under DVC is the command a user can type. `--n-jobs` and
`--recordings` change no result and are not in `params.yaml`: their defaults
come from the machine (`TASKSEQ_N_JOBS`, or one job per CPU) and this file.

It runs past 300 lines because it holds every subcommand's parser with its
help text, which a user reads as one `--help`; it holds no stage logic.
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from . import settings as S
from . import stopping
from .stages import STAGES

RECORDINGS = 6  # Rerun recordings of the full model's programs written by crossval


def default_jobs() -> int:
    """Workers for parallel stages: `TASKSEQ_N_JOBS` if set, else one per CPU."""
    value = os.environ.get("TASKSEQ_N_JOBS")
    if value is None:
        return os.cpu_count() or 1
    if not value.isdigit() or int(value) < 1:
        raise SystemExit(f"error: TASKSEQ_N_JOBS must be a positive whole number, got {value!r}")
    return int(value)


def _store(path: Path | None) -> Path | None:
    """The fold-model store to load from, if one was named and exists."""
    if path is not None and not path.is_dir():
        print(f"warning: model store {path} does not exist; models will be trained", file=sys.stderr)
        return None
    return path


def _settings(cls: type, args: argparse.Namespace) -> Any:
    """A settings object from the parsed options (their dests are the settings' field names)."""
    return S.from_values(cls, vars(args))


def _learner(args: argparse.Namespace) -> S.Learner:
    """Learner settings from the options; C from `--selection` when a selection file is named."""
    learner = _settings(S.Learner, args)
    if getattr(args, "selection", None) is not None:
        from dataclasses import replace

        from .evaluate.selection import read_selection

        learner = replace(learner, C=read_selection(args.selection))
    return learner


def _fold_crossval(args: argparse.Namespace) -> S.Crossval:
    """noise and feedback: the folds of crossval (`--fold-seed`) and its step cap."""
    return S.Crossval(folds=args.folds, group_by=args.group_by, seed=args.fold_seed, max_steps=args.max_steps)


def dispatch(args: argparse.Namespace, tracker) -> int:
    """Call the stage or tool the arguments name; returns the exit code."""
    c = args.command
    if c in STAGES:
        stage = importlib.import_module(f"pipeline.stages.{c}")
    if c == "select":
        stage.run(S.World(seeds=tuple(args.seeds), dev_seed=args.dev_seed), S.Select(C=tuple(args.grid)),
                  _learner(args), _settings(S.Crossval, args), args.data, args.output, args.n_jobs, tracker)
    elif c == "aggregate":
        stage.run(S.World(seeds=tuple(args.seeds), dev_seed=args.dev_seed), args.worlds, args.output, tracker)
    elif c == "generate":
        stage.run(_settings(S.Generate, args), args.output, tracker)
    elif c == "ingest":
        stage.run(args.input, args.output, args.metrics, tracker)
    elif c == "features":
        stage.run(args.input, args.output, tracker)
    elif c == "train":
        train = _settings(S.Train, args)
        if args.selection is not None:
            from dataclasses import replace

            train = replace(train, C=_learner(args).C)
        stage.run(train, args.features, args.model, args.metrics, args.curve, tracker,
                  people=args.people_logs if args.with_people else None)
    elif c == "pddl":
        stage.run(_settings(S.Pddl, args), args.processed, args.output, tracker)
    elif c == "folds":
        stage.run(_settings(S.Folds, args), _learner(args), args.features, args.processed, args.output,
                  args.metrics, args.n_jobs, tracker)
    elif c == "crossval":
        stage.run(_settings(S.Crossval, args), _learner(args), S.Pddl(args.horizon), args.features,
                  args.processed, args.output, _store(args.model_store), args.methods, args.n_jobs,
                  args.recordings, args.recordings_dir, tracker)
    elif c == "noise":
        stage.run(_settings(S.Noise, args), _fold_crossval(args), _learner(args), args.features,
                  args.processed, args.output, _store(args.model_store), args.n_jobs, tracker)
    elif c == "feedback":
        stage.run(_settings(S.Feedback, args), _fold_crossval(args), _learner(args), args.features,
                  args.processed, args.output, _store(args.model_store), args.n_jobs, tracker)
    elif c == "recipes":
        stage.run(S.Crossval(max_steps=args.max_steps), _learner(args), args.features, args.processed,
                  args.output, _store(args.model_store), tracker)
    elif c == "people":
        stage.run(_settings(S.People, args), _learner(args), args.max_steps, args.features, args.output, tracker)
    elif c == "teach":
        stage.run(S.World(seeds=tuple(args.seeds), dev_seed=args.dev_seed), _settings(S.Teach, args), _learner(args),
                  args.max_steps, args.worlds, args.output, tracker)
    elif c == "report":
        stage.run(args.reports, args.output, args.plots_template, tracker)
    elif c == "replay":
        from .tools import replay

        n_ok, problems = replay(args.input)
        for p in problems:
            print(p, file=sys.stderr)
        print(f"{n_ok} demonstrations replay exactly; {len(problems)} with problems")
        return 1 if problems else 0
    elif c == "plan":
        from .tools import plan_task, print_program, program_json

        program, names = plan_task(args.model, args.env, args.record, args.task, args.max_steps, args.top_k)
        if args.json:
            print(program_json(program))
        else:
            print_program(program, names)
        return 0 if program.success else 1
    elif c == "serve":
        from .serve.server import serve

        return serve(args.host, args.port, args.data, args.model, args.top_k)
    elif c == "layout":
        from .serve.layout import write_environment

        print(f"wrote {args.output}: {write_environment(args.layout, args.output)} objects")
    elif c == "bench":
        from .bench import format_bench, run_bench
        from .io import write_json_atomic
        from .logs.benchmark import load_benchmark

        result = run_bench(load_benchmark(args.processed).records, **_learner(args).ssvm,
                           repeats=args.repeats)
        write_json_atomic(args.output, result)
        print(format_bench(result))
        print(f"written to {args.output}")
    return 0


def _feedback_steps(value: str) -> str:
    """A number of steps with feedback, or 'all'."""
    if value != "all" and not value.isdigit():
        raise argparse.ArgumentTypeError(f"expected a whole number of steps or 'all', got {value!r}")
    return value


def _switch(value: str) -> bool:
    """A params.yaml switch as DVC writes it into a command: true or false."""
    if value.lower() not in ("true", "false"):
        raise argparse.ArgumentTypeError(f"expected true or false, got {value!r}")
    return value.lower() == "true"


def _positive(value: str) -> int:
    if not value.isdigit() or int(value) < 1:
        raise argparse.ArgumentTypeError(f"expected a positive whole number, got {value!r}")
    return int(value)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="taskseq",
        description="Learn to sequence manipulation primitives for under-specified tasks (unrolled MRF + SSVM).",
    )
    parser.add_argument("--no-mlflow", action="store_true",
                        help="do not record pipeline stages in MLflow (default: record, see README)")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    def add(name: str, help_: str) -> argparse.ArgumentParser:
        return sub.add_parser(name, help=help_, description=help_)

    G, T, P, C, N, F = S.Generate(), S.Train(), S.Pddl(), S.Crossval(), S.Noise(), S.Feedback()
    W, SEL, PE, TE = S.World(), S.Select(), S.People(), S.Teach()

    def world_options(p: argparse.ArgumentParser) -> None:
        # dvc.yaml passes the `world` section as `${world}`, which DVC writes as --seeds ... --dev_seed ...
        p.add_argument("--seeds", type=int, nargs="+", default=list(W.seeds),
                       help=f"reported world seeds (default {' '.join(map(str, W.seeds))})")
        p.add_argument("--dev-seed", "--dev_seed", dest="dev_seed", type=int, default=W.dev_seed,
                       help=f"the development world's seed, never reported (default {W.dev_seed})")


    p = add("generate", "simulate the demonstrator and write demonstration logs (JSON Lines)")
    p.add_argument("--seed", type=int, default=G.seed, help=f"world seed: scenario draws and position jitter "
                                                             f"(default {G.seed})")
    p.add_argument("--output", type=Path, required=True, help="folder of *.jsonl logs (replaced)")

    p = add("replay", "re-execute every logged sequence and report states or goals that differ")
    p.add_argument("input", type=Path, help="folder of *.jsonl logs")

    p = add("ingest", "validate logs and write them as Parquet tables plus dataset metrics")
    p.add_argument("--input", type=Path, default=Path("data/worlds/0/raw"), help="folder of *.jsonl logs")
    p.add_argument("--output", type=Path, required=True, help="folder of Parquet tables (replaced)")
    p.add_argument("--metrics", type=Path, default=None, help="dataset counts as JSON (default: not written)")

    p = add("features", "build every teacher-forced step's candidates and features from the Parquet tables")
    p.add_argument("--input", type=Path, default=Path("data/worlds/0/processed"), help="folder of Parquet tables")
    p.add_argument("--output", type=Path, required=True, help="feature folder (replaced)")

    def training_options(p: argparse.ArgumentParser) -> None:
        p.add_argument("--C", type=float, default=T.C, help=f"slack weight, C * sum of slacks (default {T.C})")
        p.add_argument("--tol", type=float, default=T.tol, help=f"relative primal-dual gap to stop at "
                                                                 f"(default {T.tol:g})")
        p.add_argument("--max-iter", type=int, default=T.max_iter,
                       help=f"cutting-plane iterations at most (default {T.max_iter})")
        p.add_argument("--n-slacks", type=int, default=T.n_slacks,
                       help="slack groups of the cutting plane, one cut each per iteration; 0 gives every step "
                            "its own slack (the n-slack problem), 1 is the classic 1-slack algorithm; the optimum is "
                            f"the same for every value (default {T.n_slacks})")
        p.add_argument("--dagger-rounds", type=int, default=T.dagger_rounds,
                       help="rounds of on-policy data (roll out, ask the demonstrator, refit) of the methods "
                            f"that use DAgger (default {T.dagger_rounds})")

        p.add_argument("--selection", type=Path, default=None,
                       help="take C from this file written by `taskseq select` (overrides --C)")

    def store_option(p: argparse.ArgumentParser) -> None:
        p.add_argument("--model-store", type=Path, default=None,
                       help="folder written by `taskseq folds`: models trained on the same steps with the same "
                            "settings are loaded from it instead of trained again (default: train)")

    def jobs_option(p: argparse.ArgumentParser, what: str) -> None:
        p.add_argument("--n-jobs", type=_positive, default=None,
                       help=f"{what} in parallel (joblib; default: $TASKSEQ_N_JOBS, else one per CPU); "
                            "changes no result")

    p = add("train", "fit the MRF weights with the structural SVM (the paper's 1-slack objective) on every step")
    p.add_argument("--features", type=Path, default=Path("data/worlds/0/features"), help="feature folder")
    p.add_argument("--feature-set", choices=("full", "edge", "clique"), default=T.feature_set,
                   help="families of the score: all six, edge terms only, or clique terms only")
    training_options(p)
    p.add_argument("--model", type=Path, required=True, help="model file to write (.npz)")
    p.add_argument("--metrics", type=Path, default=None, help="training metrics (JSON; default: not written)")
    p.add_argument("--curve", type=Path, default=None, help="objective per iteration (CSV; default: not written)")
    p.add_argument("--people-logs", type=Path, default=Path(PE.logs),
                   help=f"folder of people's demonstrations (taskseq serve; default {PE.logs})")
    p.add_argument("--with-people", type=_switch, default=PE.train,
                   help=f"true: add people's demonstrations to the training steps (default {str(PE.train).lower()})")

    p = add("plan", "plan a program for a task in an environment with a trained model")
    p.add_argument("--model", type=Path, default=Path("models/mrf.npz"), help="model file (.npz)")
    p.add_argument("--env", type=Path, required=True,
                   help="environment: a JSON file with 'objects' and 'state', or a .jsonl log")
    p.add_argument("--record", type=int, default=1, help="with a .jsonl log: which record (line) to take, from 1")
    p.add_argument("--task", required=True, help='the task, e.g. "pour(obj27)" or "pick_and_place(obj40,obj04)"')
    p.add_argument("--max-steps", type=int, default=C.max_steps, help="stop after this many primitives (default 20)")
    p.add_argument("--top-k", type=int, default=3, help="candidates shown per step (default 3)")
    p.add_argument("--json", action="store_true", help="print the program as JSON")

    def data_options(p: argparse.ArgumentParser) -> None:
        p.add_argument("--features", type=Path, default=Path("data/worlds/0/features"), help="feature folder")
        p.add_argument("--processed", type=Path, default=Path("data/worlds/0/processed"),
                       help="folder of Parquet tables")
        p.add_argument("--world-seed", type=int, default=None,
                       help="the seed of the world these data were drawn with, given to every MLflow child run "
                            "as a param so runs of several worlds can be compared; changes no result")

    def fold_options(p: argparse.ArgumentParser, seed: str = "--seed") -> None:
        """The fold assignment, shared by every stage that evaluates on folds so their folds agree."""
        p.add_argument("--folds", type=int, default=C.folds, help=f"number of folds (default {C.folds})")
        p.add_argument("--group-by", choices=("scenario", "environment"), default=C.group_by,
                       help="keep whole scenarios, or whole environments (unseen environments), in one fold")
        p.add_argument(seed, type=int, default=C.seed, help=f"seed of the fold assignment (default {C.seed})")

    p = add("crossval", "cross-validate every method and write Table I, metrics and a confusion matrix")
    data_options(p)
    fold_options(p)
    p.add_argument("--methods", nargs="+", default=None, help="methods to run (default: all of Table I)")
    p.add_argument("--chance-seed", type=int, default=C.chance_seed, help="seed of the chance baseline")
    p.add_argument("--multiclass-C", type=float, default=C.multiclass_C, help="C of the multiclass SVM")
    p.add_argument("--ranking-C", type=float, default=C.ranking_C,
                   help="C of the role-ranking SVMs (symb-plan-svm)")
    p.add_argument("--horizon", type=int, default=P.horizon, help="longest plan of the symbolic baselines")
    training_options(p)
    store_option(p)
    p.add_argument("--max-steps", type=int, default=C.max_steps, help="step cap of closed-loop runs")
    jobs_option(p, "folds run")
    p.add_argument("--recordings", type=int, default=RECORDINGS,
                   help=f"Rerun recordings of the full model's programs, spread over the scenarios, written to "
                        f"--recordings-dir (default {RECORDINGS}); changes no result")
    p.add_argument("--recordings-dir", type=Path, default=None,
                   help="folder for the recordings (default OUTPUT/recordings)")
    p.add_argument("--output", type=Path, required=True, help="folder for the tables and metrics")

    def robustness_options(p: argparse.ArgumentParser) -> None:
        data_options(p)
        fold_options(p, "--fold-seed")
        training_options(p)
        store_option(p)
        p.add_argument("--max-steps", type=int, default=C.max_steps, help="step cap of closed-loop runs")
        jobs_option(p, "folds run")
        p.add_argument("--output", type=Path, required=True, help="folder for CSV and PNG")

    p = add("noise", "sequence accuracy of the full model with binary attributes flipped at test time")
    robustness_options(p)
    p.add_argument("--rates", type=float, nargs="+", default=list(N.rates), help="flip probabilities")
    p.add_argument("--seeds", type=int, default=N.seeds, help="noise draws per rate")
    p.add_argument("--seed", type=int, default=N.seed, help="seed of the noise draws")

    p = add("feedback", "sequence accuracy when an observer picks among the top k at the first n steps")
    robustness_options(p)
    p.add_argument("--k", type=int, nargs="+", default=list(F.k), help="candidates offered to the observer")
    p.add_argument("--n", nargs="+", type=_feedback_steps, default=list(F.n),
                   help="steps with feedback (a number or 'all')")

    p = add("recipes", "chain programs into recipes in environments held out from training")
    data_options(p)
    training_options(p)
    store_option(p)
    p.add_argument("--max-steps", type=int, default=C.max_steps, help="step cap of each program")
    p.add_argument("--output", type=Path, required=True, help="folder for recipes.json")

    p = add("folds", "train every MRF model the evaluation stages use, once, into a model store")
    data_options(p)
    fold_options(p)
    training_options(p)
    jobs_option(p, "models trained")
    p.add_argument("--output", type=Path, required=True, help="model store folder to write (replaced)")
    p.add_argument("--metrics", type=Path, default=None, help="training times and objectives (JSON)")

    p = add("select", "draw the development world and choose C on it by cross-validation")
    world_options(p)
    p.add_argument("--grid", type=float, nargs="+", default=list(SEL.C),
                   help=f"values of C to try (default {' '.join(f'{c:g}' for c in SEL.C)})")
    fold_options(p)
    p.add_argument("--max-steps", type=int, default=C.max_steps, help="step cap of closed-loop runs")
    training_options(p)
    jobs_option(p, "fits")
    p.add_argument("--data", type=Path, required=True,
                   help="folder for the development world's logs, tables and features (replaced)")
    p.add_argument("--output", type=Path, required=True, help="the choice (JSON)")

    p = add("aggregate", "every figure over the world seeds: mean ± sd tables, failures, noise, feedback, recipes")
    world_options(p)
    p.add_argument("--worlds", type=Path, default=Path("reports/worlds"),
                   help="folder of the per-world results, one subfolder per seed")
    p.add_argument("--output", type=Path, required=True, help="folder for the tables over seeds")

    p = add("people", "check people's demonstrations, count them, and compare the planner with and without them")
    p.add_argument("--logs", type=Path, default=Path(PE.logs), help=f"folder of their logs (default {PE.logs})")
    p.add_argument("--features", type=Path, default=Path("data/worlds/0/features"),
                   help="the steps the planner is trained on before them")
    training_options(p)
    p.add_argument("--max-steps", type=int, default=C.max_steps, help="step cap of closed-loop runs")
    p.add_argument("--output", type=Path, required=True, help="folder for dataset.json and before_after.{json,md}")

    p = add("teach", "success on unseen environments after a scripted person demonstrates k tasks in each")
    world_options(p)
    p.add_argument("--worlds", type=Path, default=Path("data/worlds"),
                   help="folder of the worlds' data, one subfolder per seed with its processed tables")
    p.add_argument("--environments", nargs="+", default=list(TE.environments),
                   help=f"environments held out of training (default {' '.join(TE.environments)})")
    p.add_argument("--k", type=int, nargs="+", default=list(TE.k), help="tasks demonstrated per environment")
    p.add_argument("--seed", type=int, default=TE.seed, help="seed of the order tasks are demonstrated in")
    training_options(p)
    p.add_argument("--max-steps", type=int, default=C.max_steps, help="step cap of closed-loop runs")
    p.add_argument("--output", type=Path, required=True, help="folder for teach.{csv,md,png} and teach_seeds.csv")

    p = add("report", "write reports/summary.md: every result next to the paper's figures")
    p.add_argument("--reports", type=Path, default=Path("reports"), help="folder of the stages' results")
    p.add_argument("--output", type=Path, required=True, help="Markdown file to write")
    p.add_argument("--plots-template", type=Path, default=None,
                   help="also write the offline page template of `dvc plots show` here (default: not written)")

    p = add("pddl", "write the PDDL domain, a problem per scenario and its shortest plan (SAT)")
    p.add_argument("--processed", type=Path, default=Path("data/worlds/0/processed"), help="folder of Parquet tables")
    p.add_argument("--output", type=Path, required=True, help="folder to write (replaced)")
    p.add_argument("--horizon", type=int, default=P.horizon, help=f"longest plan searched (default {P.horizon})")

    p = add("serve", "a web page where people demonstrate tasks and correct the planner (records: DATA/people)")
    p.add_argument("--host", default="127.0.0.1", help="address to listen on (default 127.0.0.1: this machine only)")
    p.add_argument("--port", type=int, default=8765, help="port (default 8765; 0 picks a free one)")
    p.add_argument("--data", type=Path, default=Path("data"),
                   help="data folder: records are appended to DATA/people/<environment>.jsonl, environment files "
                        "are offered from DATA/environments/ (default: data)")
    p.add_argument("--model", type=Path, default=Path("models/mrf.npz"), help="planner of the assist page (.npz)")
    p.add_argument("--top-k", type=int, default=3, help="proposals shown per step in assist (default 3)")

    p = add("layout", "write an environment file (for serve and plan) from a short YAML layout of new objects")
    p.add_argument("layout", type=Path, help="layout file (YAML): objects, furniture, items, robot_x")
    p.add_argument("--output", type=Path, required=True, help="environment file to write (.json)")

    p = add("bench", "time training, per-step inference (10 to 100 objects) and features memory")
    p.add_argument("--processed", type=Path, default=Path("data/worlds/0/processed"), help="folder of Parquet tables")
    training_options(p)
    p.add_argument("--repeats", type=int, default=50, help="timed repetitions per environment size")
    p.add_argument("--output", type=Path, required=True, help="results (JSON)")
    return parser


class _StageFailed(Exception):
    def __init__(self, code: int) -> None:
        super().__init__(f"stage ended with exit code {code}")
        self.code = code


def _run(args: argparse.Namespace, tracker) -> int:
    """Dispatch, turning the errors a user can cause into a message and exit code 2."""
    from .logs.validate import LogError

    try:
        return dispatch(args, tracker)
    except (LogError, FileNotFoundError) as err:  # missing or bad inputs are found before a stage writes
        print(f"error: {err}", file=sys.stderr)
        if args.command not in STAGES:
            return 2
        print("nothing was written", file=sys.stderr)
        return 1
    except ValueError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    except KeyError as err:  # a field missing from a hand-written environment file (`plan`)
        if args.command in STAGES:
            raise
        print(f"error: missing field {err}", file=sys.stderr)
        return 2


def main(argv: Sequence[str] | None = None) -> int:
    """Run one command; Ctrl-C or SIGTERM ends it with one line, its run KILLED and no output replaced."""
    args = build_parser().parse_args(argv)
    stopping.install()
    # workers stopped mid-job leave semaphores the resource tracker (a child process) warns about at exit
    os.environ.setdefault("PYTHONWARNINGS", "ignore:resource_tracker:UserWarning")
    try:
        return _main(args)
    except KeyboardInterrupt as err:
        from .io import WRITTEN

        how = "SIGTERM" if isinstance(err, stopping.Stopped) else "Ctrl-C"
        run = "; its MLflow run is marked KILLED" if args.command in STAGES and not args.no_mlflow else ""
        written = "nothing was written" if not WRITTEN else (
            f"{len(WRITTEN)} of its files were already replaced (each whole): run it again")
        print(f"taskseq {args.command}: stopped by {how}; {written}{run}", file=sys.stderr)
        return 143 if isinstance(err, stopping.Stopped) else 130


def _main(args: argparse.Namespace) -> int:
    if getattr(args, "n_jobs", 0) is None:
        args.n_jobs = default_jobs()
    if args.command not in STAGES or args.no_mlflow:
        from .track.mlflow_runs import NO_RUN

        return _run(args, NO_RUN)
    from .track.mlflow_runs import TrackingFailed, stage_run

    params = {k: v for k, v in vars(args).items() if k not in ("command", "no_mlflow")}
    inputs = [Path(getattr(args, k)) for k in ("input", "features", "processed") if getattr(args, k, None)]
    try:
        labels = {"world_seed": args.world_seed} if getattr(args, "world_seed", None) is not None else None
        with stage_run(args.command, params, inputs, labels) as run:
            code = _run(args, run)
            if code:
                raise _StageFailed(code)  # the run is marked FAILED on the way out
    except _StageFailed as failed:
        return failed.code
    except TrackingFailed as err:  # the outputs are written; the record of the run is not
        print(f"error: taskseq {args.command}: {err}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
