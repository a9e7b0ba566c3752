"""The sub-commands of `taskseq` that are not pipeline stages, as one table: each one's help, options and runner.

`replay`, `plan`, `serve`, `layout`, `bench`, `scaling`, `cache` and `veil` are each
an entry of `TOOLS`: its help, a function adding its options to its parser
and a function running it from the parsed options (returning the exit code).
A runner only reads its options and prints; the work is the product's
(`taskseq.product`, `taskseq.serve`), the benchmarks' (`taskseq.bench`) or
VEIL's (`taskseq.veil`), imported when the command runs. `taskseq.cli` builds
the subcommands from this table and from the stages' (`taskseq.stages`).
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from .settings import Crossval
from .stages.command import positive


@dataclass(frozen=True)
class Tool:
    help: str
    options: Callable[[argparse.ArgumentParser], None]
    run: Callable[[argparse.Namespace], int]


def _replay_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("input", type=Path, help="folder of *.jsonl logs, or one log file")


def _replay(args: argparse.Namespace) -> int:
    from .demonstrations.validate import LogError, check_record, log_files, read_records

    if args.input.is_file() and args.input.suffix != ".jsonl":
        raise ValueError(f"{args.input}: not a log of demonstrations (JSON Lines, .jsonl); replay re-executes the "
                         "sequences a log records" + (", and a .json file is an environment" if args.input.suffix
                                                      == ".json" else ""))
    n_ok, problems = 0, []  # records that replay exactly, problems found
    for path in [args.input] if args.input.is_file() else log_files(args.input):
        try:
            for item in read_records(path):
                try:
                    check_record(item)
                    n_ok += 1
                except LogError as err:
                    problems.append(str(err))
        except LogError as err:  # unreadable line: the rest of that file cannot be trusted
            problems.append(str(err))
    for problem in problems:
        print(problem, file=sys.stderr)
    if not n_ok and not problems:
        raise ValueError(f"{args.input}: holds no demonstration: its log files are empty")
    replay = "demonstration replays" if n_ok == 1 else "demonstrations replay"
    print(f"{n_ok} {replay} exactly; {len(problems)} with problems")
    return 1 if problems else 0


def _plan_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--model", type=Path, default=Path("models/mrf.npz"),
                   help="model file (.npz; default models/mrf.npz, the planner `dvc repro` ships)")
    p.add_argument("--env", type=Path, required=True,
                   help="environment: a JSON file with 'objects' and 'state', or a .jsonl log; or a VEIL-500 "
                        "environment file (.xml, with a model of `taskseq veil train`; the task is then an objective "
                        "the release names, docs/veil.md)")
    p.add_argument("--record", type=positive, default=1,
                   help="with a .jsonl log: which record (line) to take, from 1 (default 1: the first)")
    p.add_argument("--task", required=True,
                   help='the task, each object by its id or by a name only it has there: pour(LIQUID) into '
                        'any other container, pour_to(LIQUID,CONTAINER), stir(LIQUID), throw_away(OBJECT) or '
                        'pick_and_place(OBJECT,PLACE); e.g. "pour(obj27)", "pour(milk)" or '
                        '"pick_and_place(obj40,obj04)"')
    p.add_argument("--max-steps", type=positive, default=Crossval.max_steps,
                   help=f"stop after this many primitives (default {Crossval.max_steps})")
    p.add_argument("--top-k", type=positive, default=3, help="candidates shown per step (default 3)")
    p.add_argument("--json", action="store_true", help="print the program as JSON")


def _plan(args: argparse.Namespace) -> int:
    if args.env.suffix.lower() == ".xml":  # an environment of a VEIL-500 release: its own domain and model
        from .veil.command import plan_in_environment

        return plan_in_environment(args.model, args.env, args.task, max_steps=args.max_steps)
    from .product import plan_task, print_program, program_json

    program, specs, model = plan_task(args.model, args.env, args.record, args.task, args.max_steps, args.top_k)
    # which planner runs: on stdout before the program, on stderr when stdout carries JSON
    print(f"planner {args.model}: {model}", file=sys.stderr if args.json else sys.stdout)
    if args.json:
        print(program_json(program, specs))
    else:
        print_program(program, specs)
    return 0 if program.success else 1


def _bench_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--processed", type=Path, default=Path("data/worlds/0/processed"),
                   help="folder of Parquet tables (default data/worlds/0/processed)")
    p.add_argument("--params", type=Path, default=None,
                   help="settings file whose `train` section sets the learner (default: params.yaml, else defaults)")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="SECTION.KEY=VALUE",
                   help="override one setting, e.g. --set train.tol=1e-4 (repeatable)")
    p.add_argument("--selection", type=Path, default=None,
                   help="take the full model's C from this file written by `taskseq select` (default: no file: "
                        "C = 3, taskseq.selection.UNTUNED_C)")
    p.add_argument("--repeats", type=positive, default=50, help="timed repetitions per environment size (default 50)")
    p.add_argument("--output", type=Path, required=True, help="results (JSON)")


def _bench(args: argparse.Namespace) -> int:
    from .bench.speed import format_bench, run_bench
    from .demonstrations.benchmark import load_benchmark
    from .runtime.atomic import write_json_atomic
    from .selection import read_selection
    from .stages.command import load_params

    learner = load_params(args).train
    result = run_bench(load_benchmark(args.processed).records, C=read_selection(args.selection).of("full"),
                       tol=learner.tol, max_iter=learner.max_iter, n_slacks=learner.n_slacks, repeats=args.repeats)
    write_json_atomic(args.output, result)
    print(format_bench(result))
    print(f"written to {args.output}")
    return 0


def _scaling_options(p: argparse.ArgumentParser) -> None:
    from .bench.scaling import EVALUATE, PREPARE

    p.add_argument("--rooms", nargs="+", required=True, metavar="N",
                   help="world sizes in rooms (13 is the paper's size), e.g. --rooms 13 39 130")
    p.add_argument("--stages", nargs="*", default=list(EVALUATE), metavar="STAGE",
                   help=f"stages timed after {', '.join(PREPARE)} (which always run), among {' '.join(EVALUATE)} "
                        f"(default: all; crossval, noise and feedback need folds)")
    p.add_argument("--methods", nargs="+", default=None, help="crossval's methods (default: every method of Table I)")
    p.add_argument("--world-seed", type=int, default=0, help="seed of the drawn worlds (default 0)")
    p.add_argument("--params", type=Path, default=None,
                   help="settings file of the stages and of the timed fit (default: params.yaml, else defaults)")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="SECTION.KEY=VALUE",
                   help="override one setting in every stage, e.g. --set train.tol=0.1 (repeatable)")
    p.add_argument("--selection", type=Path, default=None,
                   help="C of the stages and of the timed fit, from this file written by `taskseq select` "
                        "(default: no file: C = 3, taskseq.selection.UNTUNED_C)")
    p.add_argument("--C", type=float, default=None, help="C of the timed fit (default: the full model's, as the "
                   "stages take it)")
    p.add_argument("--tol", type=float, default=1e-3, help="relative gap the timed fit stops at (default 1e-3)")
    p.add_argument("--n-jobs", type=positive, default=None,
                   help="processes of the parallel stages (default: $TASKSEQ_N_JOBS, else one per CPU)")
    p.add_argument("--keep", type=Path, default=None,
                   help="keep each world's data, models, results and stage logs in KEEP/rooms-N (replaced; "
                        "default: a temporary folder, removed)")
    p.add_argument("--plot", type=Path, default=None, help="figure to write (.png; default: not written)")
    p.add_argument("--output", type=Path, required=True, help="results (JSON)")


def _scaling(args: argparse.Namespace) -> int:
    from .bench.scaling import Plan, format_scaling, parse_rooms, plot_scaling, run_scaling
    from .runtime.atomic import write_json_atomic
    from .runtime.jobs import default_jobs
    from .selection import read_selection
    from .stages.command import load_params

    learner = load_params(args).train
    C = read_selection(args.selection).of("full") if args.C is None else args.C
    plan = Plan(rooms=parse_rooms(args.rooms), stages=tuple(args.stages), C=C, tol=args.tol,
                max_iter=learner.max_iter, n_slacks=learner.n_slacks, world_seed=args.world_seed,
                n_jobs=args.n_jobs or default_jobs(), methods=None if args.methods is None else tuple(args.methods),
                params=args.params, overrides=tuple(args.overrides), selection=args.selection)
    def write(so_far: dict) -> None:  # after every measurement: a run stopped part way keeps what it measured
        write_json_atomic(args.output, so_far)
        if args.plot is not None:
            plot_scaling(so_far, args.plot)

    result = run_scaling(plan, args.keep, update=write)
    print(format_scaling(result))
    print(f"written to {args.output}" + (f" and {args.plot}" if args.plot is not None else ""))
    return 0


def _serve_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--host", default="127.0.0.1", help="address to listen on (default 127.0.0.1: this machine only)")
    p.add_argument("--port", type=_port, default=8765, help="port (default 8765; 0 picks a free one)")
    p.add_argument("--data", type=Path, default=Path("data"),
                   help="data folder: records are appended to DATA/people/<environment>.jsonl, environment files "
                        "are offered from DATA/environments/ (default: data)")
    p.add_argument("--model", type=Path, default=Path("models/mrf.npz"),
                   help="planner of the assist page (.npz; default models/mrf.npz)")
    p.add_argument("--top-k", type=positive, default=3, help="proposals shown per step in assist (default 3)")


def _port(value: str) -> int:
    """A TCP port from the command line: 0 (any free one) to 65535."""
    if not value.isdigit() or int(value) > 65535:
        raise argparse.ArgumentTypeError(f"expected a port from 0 to 65535, got {value!r}")
    return int(value)


def _serve(args: argparse.Namespace) -> int:
    from .serve.server import serve

    return serve(args.host, args.port, args.data, args.model, args.top_k)


def _layout_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("layout", type=Path, help="layout file (YAML): objects, furniture, items, robot_x")
    p.add_argument("--output", type=Path, required=True, help="environment file to write (.json)")


def _layout(args: argparse.Namespace) -> int:
    from .serve.layout import write_environment

    print(f"wrote {args.output}: {write_environment(args.layout, args.output)} objects")
    return 0


def _days(value: str) -> float:
    """A number of days above zero from the command line."""
    try:
        days = float(value)
    except ValueError:
        days = float("nan")
    if not days > 0 or days == float("inf"):
        raise argparse.ArgumentTypeError(f"expected a number of days above 0, got {value!r}")
    return days


def _cache_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("folder", type=Path, nargs="?", default=Path(".cache"),
                   help="the cache folder (default: .cache, the one `dvc repro` fills)")
    drop = p.add_mutually_exclusive_group()
    drop.add_argument("--unused-for", type=_days, metavar="DAYS",
                      help="delete the entries no run has written or read in the last DAYS days")
    drop.add_argument("--clear", action="store_true", help="delete every entry (the next run fits everything again)")


def _cache(args: argparse.Namespace) -> int:
    import time

    from .runtime.cache import prune, usage

    if args.clear or args.unused_for is not None:
        removed, freed = prune(args.folder, None if args.clear else args.unused_for * 86400.0, time.time())
        why = "" if args.clear else f" unused for {args.unused_for:g} days"
        print(f"deleted {removed} files{why} ({_size(freed)})")
    kinds = usage(args.folder)
    print(f"{args.folder}:")
    for kind in kinds:
        used = "never" if kind.last_used is None else time.strftime("%Y-%m-%d %H:%M", time.localtime(kind.last_used))
        print(f"  {kind.kind:9s} {kind.entries:6d} entries  {_size(kind.size):>8s}  last used {used}")
    return 0


def _size(size: int) -> str:
    """Bytes as a person reads them: 812 B, 40.2 kB, 136.9 MB."""
    for unit, scale in (("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if size >= scale:
            return f"{size / scale:.1f} {unit}"
    return f"{size} B"


def _veil_options(p: argparse.ArgumentParser) -> None:
    from .veil.command import options

    options(p)


def _veil(args: argparse.Namespace) -> int:
    from .veil.command import run

    return run(args)


TOOLS: dict[str, Tool] = {
    "replay": Tool("re-execute every logged sequence and report states or goals that differ", _replay_options,
                   _replay),
    "plan": Tool("plan a program for a task in an environment with a trained model", _plan_options, _plan),
    "serve": Tool("a web page where people demonstrate tasks and correct the planner (records: DATA/people)",
                  _serve_options, _serve),
    "layout": Tool("write an environment file (for serve and plan) from a short YAML layout of new objects",
                   _layout_options, _layout),
    "bench": Tool("time training, per-step inference (10 to 100 objects) and features memory", _bench_options,
                  _bench),
    "scaling": Tool("draw procedural worlds of several sizes and time every per-world stage, training to the gap, "
                    "its memory and per-step inference", _scaling_options, _scaling),
    "cache": Tool("what the cache of fits, programs' outcomes, steps (drawn rooms', DAgger's rollouts) and plans "
                  "holds "
                  "(docs/pipeline.md), "
                  "and deleting the entries no run has used for a while", _cache_options, _cache),
    "veil": Tool("VEIL-500 (Tell Me Dave): import people's sequences from a release folder (docs/veil.md)",
                 _veil_options, _veil),
}
