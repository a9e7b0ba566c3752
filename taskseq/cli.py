"""The `taskseq` command line: subcommands from the stage and tool tables, errors and signals to exit codes.

A stage's options come from its `Options` class (`taskseq.stages`), its settings from
`params.yaml` (`taskseq.settings`), and its MLflow run from `taskseq.track`;
this module only puts them together. Exit codes: 0 done; 1 a stage whose
input files were missing or bad, or a plan that did not reach its goal; 2 bad
input to a command, a value or a tool's file (with one line naming it); 130
and 143 stopped by Ctrl-C or SIGTERM. A stage that stops says what it wrote.
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Sequence

from .runtime import atomic, memory, stopping
from .stages import STAGES
from .stages.command import add_parser, execute, prepare
from .stages.options import inputs
from .tool_commands import TOOLS


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="taskseq",
        description="Learn to sequence manipulation primitives for under-specified tasks (unrolled MRF + SSVM). "
                    "Pipeline stages read their settings from params.yaml; `dvc repro` runs them all.",
    )
    parser.add_argument("--no-mlflow", action="store_true",
                        help="do not record pipeline stages in MLflow (default: record in mlflow.db at the root of the "
                             "DVC project run from, or at MLFLOW_TRACKING_URI; outside a project, with neither, "
                             "nothing is recorded)")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name in STAGES:
        add_parser(sub, name)
    for name, tool in TOOLS.items():
        tool.options(sub.add_parser(name, help=tool.help, description=tool.help))
    return parser


def _user_errors() -> tuple[type[BaseException], ...]:
    """The errors a user's files cause: a log that is not valid (`LogError`), and a path that cannot be read or
    written as given (`OSError`: a file or folder missing, a folder where a file goes, no permission)."""
    from .demonstrations.validate import LogError

    return LogError, OSError


def _stage(args: argparse.Namespace) -> int:
    """Run a stage, inside its MLflow run unless `--no-mlflow`."""
    module, settings, options, record = prepare(args)
    if args.no_mlflow:
        from .track.mlflow_runs import NO_RUN

        return execute(args, module, settings, options, NO_RUN)
    from .track.mlflow_runs import tracked

    labels = {"world_seed": args.world_seed} if getattr(args, "world_seed", None) is not None else None
    return tracked(args.command, record, inputs(options), labels,
                   lambda run: _guarded(args, lambda: execute(args, module, settings, options, run)))


def _guarded(args: argparse.Namespace, body) -> int:
    """`body`'s exit code, with the errors a user can cause turned into one line and an exit code."""
    try:
        return body()
    except BrokenPipeError:
        raise  # not the user's files: a reader that left early (`| head`), which `main` ends quietly
    except _user_errors() as err:  # missing or bad inputs are found before a stage writes
        # A path the system refuses (an output that is a folder, a file where a folder goes, no permission) is a
        # bad file like a missing one: exit code 1 for a stage, after what it wrote, 2 for a tool. Its line is
        # the system's reason and the path; a missing file keeps its message, which may be the command's own.
        if isinstance(err, OSError) and not isinstance(err, FileNotFoundError) and err.strerror:
            paths = " -> ".join(str(name) for name in (err.filename, err.filename2) if name is not None)
            message = f"{err.strerror}: {paths}" if paths else err.strerror
        else:
            message = str(err)
        print(f"error: {message}", file=sys.stderr)
        if args.command not in STAGES:
            return 2
        print(_written(), file=sys.stderr)
        return 1
    except ValueError as err:
        print(f"error: {err}", file=sys.stderr)
        if args.command in STAGES:
            print(_written(), file=sys.stderr)
        return 2
    except KeyError as err:  # a field missing from a hand-written environment file (`plan`)
        if args.command in STAGES:
            raise
        print(f"error: missing field {err}", file=sys.stderr)
        return 2


def _written() -> str:
    """What a stopped stage leaves: its outputs are replaced whole, each when it is complete (`runtime.atomic`)."""
    return "nothing was written" if not atomic.WRITTEN else (
        f"{len(atomic.WRITTEN)} of its files were already replaced (each whole): run it again")


def main(argv: Sequence[str] | None = None) -> int:
    """Run one command; Ctrl-C or SIGTERM ends it with one line, its run KILLED and no output replaced."""
    args = build_parser().parse_args(argv)
    atomic.WRITTEN.clear()  # what this command replaces (a process may run several: tests, notebooks)
    stopping.install()
    memory.keep_freed_memory()  # a large fit otherwise spends more time faulting pages in than computing
    # workers stopped mid-job leave semaphores the resource tracker (a child process) warns about at exit
    os.environ.setdefault("PYTHONWARNINGS", "ignore:resource_tracker:UserWarning")
    try:
        code = _guarded(args, lambda: _stage(args) if args.command in STAGES else TOOLS[args.command].run(args))
        sys.stdout.flush()  # a reader that left early (`taskseq plan --json | head`) is met here, not at exit
        return code
    except BrokenPipeError:
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # nothing more to say to a closed pipe
        return 1
    except KeyboardInterrupt as err:
        stopping.stopped()

        how = "SIGTERM" if isinstance(err, stopping.Stopped) else "Ctrl-C"
        from .track.mlflow_runs import tracking_uri

        recorded = args.command in STAGES and not args.no_mlflow and tracking_uri() is not None
        run = "; its MLflow run is marked KILLED" if recorded else ""
        print(f"taskseq {args.command}: stopped by {how}; {_written()}{run}", file=sys.stderr)
        return 143 if isinstance(err, stopping.Stopped) else 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
