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
                        "(replaced whole, and only when the whole release is valid)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")


def _import(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    from .ingest import format_summary, import_release

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
    p.add_argument("--release", type=Path, required=True, help="the release folder (as for import); only read")
    p.add_argument("--output", type=Path, required=True,
                   help="folder to write report.json and tables.md into (replaced whole when the run ends)")
    p.add_argument("--params", type=Path, default=Path("params.yaml"),
                   help="settings file whose `veil` section sets folds, C_grid, max_steps, methods, policies "
                        "(default params.yaml; the built-in defaults where it has no such section)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")


def _evaluate(args: argparse.Namespace) -> int:
    from dataclasses import asdict

    from tqdm import tqdm

    from .experiment import read_settings, run_experiment, tables, write_reports

    settings = read_settings(args.params)
    start = time.perf_counter()

    def bar(items):
        return tqdm(items, desc="closed loop", unit="sequence", leave=False, disable=args.quiet or None,
                    file=sys.stderr)

    def body(run) -> int:
        report = run_experiment(args.release, settings, progress=bar)
        write_reports(report, args.output)
        record(run, report)
        run.artifact(args.output / "tables.md")
        print(tables(report))
        print(f"written to {args.output} in {time.perf_counter() - start:.0f} s")
        return 0

    return _tracked(args, "veil-evaluate", {**asdict(settings), "release": str(args.release)}, body)


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

SUBCOMMANDS: dict[str, SubCommand] = {
    "import": SubCommand(
        "check a VEIL-500 release, replay its sequences (skipping steps the domain refuses, counted by reason) and "
        "write Parquet tables; on any error in the release: exit code 2, one line naming file, line and element, "
        "nothing written", _import_options, _import),
    "evaluate": SubCommand(
        "every method (baselines and MRF rows) over folds of held-out environments: next-step accuracy with the "
        "people's history and closed-loop runs (goal reached, edit distance to people); writes report.json and "
        "tables.md", _evaluate_options, _evaluate),
}

HELP = "VEIL-500 (Tell Me Dave): import people's sequences from a release folder, evaluate methods on them "\
       "(docs/veil.md)"


def options(p: argparse.ArgumentParser) -> None:
    sub = p.add_subparsers(dest="veil_command", required=True, metavar="SUBCOMMAND")
    for name, cmd in SUBCOMMANDS.items():
        cmd.options(sub.add_parser(name, help=cmd.help, description=cmd.help))


def run(args: argparse.Namespace) -> int:
    return SUBCOMMANDS[args.veil_command].run(args)
