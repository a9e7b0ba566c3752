"""A stage as a command: its options built from its `Options` class, its settings from `params.yaml`, one run.

Every stage takes the same few options besides its own: `--params` (the
settings file), `--set section.key=value` (one setting overridden, as
`dvc exp run -S` writes it), `--world-seed` for stages on one world's data,
and `--n-jobs` for stages that run work in parallel. So the command DVC runs
is the command a user can type, and a setting has one name everywhere: its
key in `params.yaml`.
"""

from __future__ import annotations

import argparse
import importlib
from contextlib import AbstractContextManager, nullcontext
from dataclasses import MISSING, fields
from pathlib import Path
from typing import Any

from ..runtime.cache import folder as cache_folder
from ..runtime.jobs import default_jobs
from ..settings import Params
from . import STAGES


def positive(value: str) -> int:
    """A positive whole number from the command line."""
    if not value.isdigit() or int(value) < 1:
        raise argparse.ArgumentTypeError(f"expected a positive whole number, got {value!r}")
    return int(value)


def seed(value: str) -> int:
    """A world seed from the command line: a whole number, 0 or more (NumPy's generators take no negative seed)."""
    if not value.isdigit():
        raise argparse.ArgumentTypeError(f"expected a whole number, 0 or more, got {value!r}")
    return int(value)


def add_parser(sub: Any, name: str) -> None:
    """The stage's subcommand: an option per field of its `Options` class, then the options every stage shares."""
    stage = STAGES[name]
    p = sub.add_parser(name, help=stage.help, description=f"{stage.help}. Settings are read from params.yaml "
                       "(the keys this stage's `params` list in dvc.yaml names); --set overrides one.")
    for f in fields(stage.options):
        if f.metadata["kind"] is bool:  # a switch, off unless given
            p.add_argument("--" + f.name.replace("_", "-"), dest=f.name, action="store_true", help=f.metadata["help"])
            continue
        required = f.default is MISSING
        shown = "" if required or f.default is None else f" (default {f.default})"
        p.add_argument("--" + f.name.replace("_", "-"), dest=f.name, type=f.metadata["kind"], required=required,
                       nargs=f.metadata["nargs"], default=None if required else f.default,
                       help=f.metadata["help"] + shown)
    p.add_argument("--params", type=Path, default=None,
                   help="settings file (default: params.yaml if it exists, else the built-in defaults, which equal "
                        "the repository's params.yaml)")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="SECTION.KEY=VALUE",
                   help="override one setting, e.g. --set train.tol=1e-4 or --set 'noise.rates=0 0.2' (repeatable)")
    if stage.draws:
        p.add_argument("--world-seed", type=seed, required=True,
                       help="the world to draw: the same seed draws the same rooms and demonstrations, bit for bit")
    elif stage.per_world:
        p.add_argument("--world-seed", type=seed, default=None,
                       help="the world these data were drawn with: a label of the MLflow runs, so runs of several "
                            "worlds can be compared (changes no result)")
    if stage.cached:
        p.add_argument("--cache", type=Path, default=None, metavar="DIR",
                       help="keep every fit and every fold's program outcomes in DIR, and read back those already "
                            "there from the same code and inputs (default: $TASKSEQ_CACHE, else no cache); "
                            "changes no result")
    if stage.parallel:
        p.add_argument("--n-jobs", type=positive, default=None,
                       help="work run in parallel (joblib; default: $TASKSEQ_N_JOBS, else one per CPU); "
                            "changes no result")


def load_params(args: argparse.Namespace) -> Params:
    """The settings in force: the file, then the overrides (each method's C is not one: the stages read it from
    their `--selection` file, `taskseq.selection`)."""
    if args.params is not None and not args.params.exists():
        raise FileNotFoundError(f"{args.params}: no such settings file")
    return Params.load(args.params or Path("params.yaml"), args.overrides)


def prepare(args: argparse.Namespace) -> tuple[Any, Any, Any, dict[str, Any]]:
    """The stage's module, settings and options from the parsed command line, and what its run records."""
    stage = STAGES[args.command]
    module = importlib.import_module(f"{__package__}.{args.command}")
    options = stage.options(**{f.name: getattr(args, f.name) for f in fields(stage.options)})
    params = load_params(args)
    world_seed = getattr(args, "world_seed", None)
    settings = module.settings(params, world_seed)
    record = {**params.flat(), **{f"cli.{f.name}": getattr(options, f.name) for f in fields(options)}}
    if world_seed is not None:
        record["cli.world_seed"] = world_seed
    return module, settings, options, record


def execute(args: argparse.Namespace, module: Any, settings: Any, options: Any, tracker: Any) -> int:
    """Run the stage; its exit code (0: every output written)."""
    with _cache(getattr(args, "cache", None)):
        if STAGES[args.command].parallel:
            module.run(settings, options, tracker, args.n_jobs or default_jobs())
        else:
            module.run(settings, options, tracker)
    return 0


def _cache(directory: Path | None) -> AbstractContextManager[None]:
    """`--cache` in force during the run, for this process and the workers it starts (through the environment,
    as `taskseq.runtime.cache` reads it); the environment as it was without the option."""
    return nullcontext() if directory is None else cache_folder(directory)
