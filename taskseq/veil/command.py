"""The `taskseq veil` command's sub-commands: one table, so that more (train, evaluate, ...) are added as entries.

`taskseq.commands` registers `veil` with `options` and `run` below; each entry of `SUBCOMMANDS` has a help line, a
function adding its options and a function running it (returning the exit code).
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path


@dataclass(frozen=True)
class SubCommand:
    help: str
    options: Callable[[argparse.ArgumentParser], None]
    run: Callable[[argparse.Namespace], int]


def _import_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--release", type=Path, required=True,
                   help="the release folder (Objects.xml, data.xml, domainKnowledge.pddl, ControllerInstructions.xml, "
                        "Environments/kitchen/kitchenN.xml, Environments/livingRoom/livingRoomN.xml); only read")
    p.add_argument("--output", type=Path, required=True,
                   help="folder to write sequences.parquet, steps.parquet, objects.parquet and import.json into "
                        "(replaced whole, and only when the whole release is valid; never the release folder or "
                        "one holding it)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")


def _import(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    from ..runtime.atomic import refuse_replacing_inputs
    from .ingest import format_summary, import_release

    refuse_replacing_inputs(args.output, release=args.release)
    start = time.perf_counter()

    def bar(items):
        return tqdm(items, desc="replaying", unit="sequence", disable=args.quiet or None, file=sys.stderr)

    def body(run) -> int:
        summary = import_release(args.release, args.output, progress=bar)
        run.metrics({k: float(v) for k, v in summary.items() if isinstance(v, int | float)})
        run.artifact(args.output / "import.json")
        print(format_summary(summary))
        print(f"written to {args.output} in {time.perf_counter() - start:.1f} s")
        return 0

    return _tracked(args, "veil-import", {"release": str(args.release)}, body)

def _evaluate_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--release", type=Path, required=True,
                   help="the release folder (as for import), or any folder of its format; only read")
    p.add_argument("--output", type=Path, required=True,
                   help="folder to write report.json and tables.md into (replaced whole when the run ends; never the "
                        "release folder or one holding it)")
    p.add_argument("--model", type=Path, default=None,
                   help="a trained model (`taskseq veil train`): evaluate it on every sequence of the folder, with "
                        "the goals it was trained toward, instead of cross-validating every method")
    p.add_argument("--params", type=Path, default=Path("params.yaml"),
                   help="settings file whose `veil` section sets folds, C_grid, max_steps, methods, policies "
                        "(default params.yaml; the built-in defaults where it has no such section)")
    p.add_argument("--recordings-dir", type=Path, default=None,
                   help="write Rerun recordings of a few closed-loop runs per fold here (`recordings` in the settings)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")


def _evaluate(args: argparse.Namespace) -> int:
    from dataclasses import asdict

    from tqdm import tqdm

    from ..runtime.atomic import holds, refuse_replacing_inputs
    from .experiment import evaluate_model, read_settings, run_experiment, tables, write_reports

    refuse_replacing_inputs(args.output, release=args.release, model=args.model, params=args.params)
    if args.recordings_dir is not None and holds(args.output, args.recordings_dir):
        raise ValueError(f"--recordings-dir {args.recordings_dir} lies in --output {args.output}, which is replaced "
                         "whole when the run ends, recordings included: give a folder outside it")
    settings = read_settings(args.params)
    start = time.perf_counter()

    def bar(items):
        return tqdm(items, desc="closed loop", unit="sequence", leave=False, disable=args.quiet or None,
                    file=sys.stderr)

    def body(run) -> int:
        if args.model is not None:
            from .persist import load_mrf

            model, _ = load_mrf(args.model)
            report = evaluate_model(model, args.release, settings, progress=bar)
        else:
            from ..runtime.jobs import default_jobs

            report = run_experiment(args.release, settings, n_jobs=default_jobs(), recordings_dir=args.recordings_dir)
        write_reports(report, args.output)
        record(run, report)
        run.artifact(args.output / "tables.md")
        print(tables(report))
        print(f"written to {args.output} in {time.perf_counter() - start:.0f} s")
        return 0

    return _tracked(args, "veil-evaluate", {**asdict(settings), "release": str(args.release),
                                            "model": str(args.model) if args.model else None}, body)


def record(run, report: dict) -> None:
    """A child run per method: its next-step accuracy, per policy the goal reached and edit distance, and the
    seconds it took over all folds (C's choice, fits and runs): where the time goes."""
    for name, parts in report["next_step"].items():
        with run.child(name, {"method": name}) as child:
            values = {f"next_step_{part}": figure["mean"] for part, figure in parts.items()}
            for key, figures in report["closed_loop"].items():
                method, _, policy = key.partition("/")
                if method == name:
                    values |= {f"{policy}_{f}": figures[f]["mean"] for f in ("goal_share", "edit_distance", "exact")}
            seconds = report.get("seconds", {}).get(name, [])
            child.metrics(values | {"seconds": float(sum(seconds))})


def _tracked(args: argparse.Namespace, stage: str, params: dict, body: Callable[..., int]) -> int:
    """`body` inside the command's MLflow run, as the pipeline's stages are recorded (none with --no-mlflow)."""
    from ..track.mlflow_runs import NO_RUN, tracked

    if args.no_mlflow:
        return body(NO_RUN)
    return tracked(stage, params, [args.release], None, body)

def _train_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--release", type=Path, required=True, help="the release folder to train on (every sequence)")
    p.add_argument("--output", type=Path, required=True, help="model file to write (.npz; replaced when done)")
    p.add_argument("--params", type=Path, default=Path("params.yaml"),
                   help="settings file whose `veil` section gives the MRF rows and C grid to choose from (an inner "
                        "held-out environment number of the release decides; default params.yaml)")


def _train(args: argparse.Namespace) -> int:
    from .experiment import read_settings, train_model
    from .persist import save_mrf

    settings = read_settings(args.params)

    def body(run) -> int:
        start = time.perf_counter()
        from ..runtime.jobs import default_jobs

        model = train_model(args.release, settings, n_jobs=default_jobs())
        save_mrf(args.output, model)
        method = model.method
        run.params({"chosen_method": method.name, "chosen_C": method.C, "lookahead_width": model.lookahead_width})
        run.metrics({"seconds": time.perf_counter() - start})
        print(f"{method.name} (C = {method.C:g}, goal lookahead's width {model.lookahead_width}) trained on "
              f"{len(model.trained_on)} environments, written to {args.output}")
        return 0

    return _tracked(args, "veil-train", {"release": str(args.release), "C_grid": list(settings.C_grid)}, body)


def _plan_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--model", type=Path, required=True, help="a trained model (`taskseq veil train`)")
    p.add_argument("--environment", type=Path, required=True,
                   help="an environment file in the release's format (Environments/kitchen/kitchenN.xml, ...)")
    p.add_argument("--objective", required=True,
                   help="the objective, as the model knows it (one of the objectives of the release it was trained on)")
    p.add_argument("--release", type=Path, default=None,
                   help="the folder whose Objects.xml, domainKnowledge.pddl and ControllerInstructions.xml describe "
                        "the domain (default: the folder holding the environment's Environments/ folder)")
    p.add_argument("--policy", choices=("plain", "feasible", "lookahead"), default="lookahead",
                   help="plain: the best-scored step; feasible: the best-scored step the domain lets run; lookahead "
                        "(default): stop where the goal the model was trained toward holds, else of its best runnable "
                        "steps the one whose imagined run reaches most of that goal (docs/veil.md)")
    p.add_argument("--max-steps", type=int, default=40, help="steps at most (default 40)")


def _plan(args: argparse.Namespace) -> int:
    return plan_in_environment(args.model, args.environment, args.objective, args.release, args.policy,
                               args.max_steps)


def plan_in_environment(model: Path, environment: Path, objective: str, release: Path | None = None,
                        policy: str = "lookahead", max_steps: int = 40) -> int:
    """Print the steps a trained model takes toward `objective` in an environment file, and the goal reached;
    exit code 0 when it chose `done` with the goal reached, else 1 (`taskseq veil plan`, and `taskseq plan` given
    a release's environment file)."""
    from .evaluate import Executor, lift, rollout
    from .lookahead import planner
    from .metrics import goal_share
    from .persist import load_mrf
    from .plan import domain_of, environment_state

    if max_steps < 1:
        raise ValueError(f"--max-steps must be at least 1, got {max_steps}")
    trained, _ = load_mrf(model)
    method, goals = trained.method, trained.goals
    if objective not in method.vocabulary.objectives:
        raise ValueError(f"objective {objective!r} is not one the model knows: "
                         f"{', '.join(method.vocabulary.objectives)}")
    domain = domain_of(environment, release)
    state = environment_state(environment, domain)
    executor = Executor(domain)
    runner, rollout_policy = planner(method, goals, executor, policy, trained.lookahead_width)
    steps, final, refused, stopped = rollout(runner, executor, state, objective, rollout_policy, max_steps)
    for i, s in enumerate(steps, start=1):
        print(f"{i:3d}  {s}")
    goal = goals.get(objective, frozenset())
    reached = goal_share(lift(final), goal) if goal else None
    print(("status: done" if stopped else f"status: stopped after {max_steps} steps")
          + (f"; {refused} refused" if refused else "")
          + (f"; goal reached {100 * reached:.0f}% ({len(goal)} facts)" if reached is not None else ""))
    return 0 if stopped and reached in (None, 1.0) else 1

SUBCOMMANDS: dict[str, SubCommand] = {
    "import": SubCommand(
        "check a VEIL-500 release, replay its sequences (skipping steps the domain refuses, counted by reason) and "
        "write Parquet tables; on any error in the release: exit code 2, one line naming file, line and element, "
        "nothing written", _import_options, _import),
    "evaluate": SubCommand(
        "every method (baselines and MRF rows) over folds of held-out environments: next-step accuracy with the "
        "people's history and closed-loop runs (goal reached, edit distance to people); writes report.json and "
        "tables.md", _evaluate_options, _evaluate),
    "train": SubCommand(
        "train the MRF on every sequence of a release (its row and C chosen on an inner held-out environment "
        "number) and write a model file", _train_options, _train),
    "plan": SubCommand(
        "plan a sequence for an objective in an environment file with a trained model, step by step in the domain",
        _plan_options, _plan),
}

HELP = ("VEIL-500 (Tell Me Dave): import people's sequences from a release folder, evaluate methods on them, "
        "train a model and plan with it (docs/veil.md)")


def options(p: argparse.ArgumentParser) -> None:
    sub = p.add_subparsers(dest="veil_command", required=True, metavar="SUBCOMMAND")
    for name, cmd in SUBCOMMANDS.items():
        cmd.options(sub.add_parser(name, help=cmd.help, description=cmd.help))


def run(args: argparse.Namespace) -> int:
    return SUBCOMMANDS[args.veil_command].run(args)
