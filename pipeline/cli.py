"""The `taskseq` command line: one subcommand per pipeline stage, plus tools.

Stages take their settings as options; `dvc.yaml` passes them from
`params.yaml`, so the command a stage runs is the command a user can type.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Sequence
from pathlib import Path

from .io import write_json_atomic

Handler = Callable[[argparse.Namespace], int]


def _generate(args: argparse.Namespace) -> int:
    from .logs.generate import generate

    counts = generate(args.seed, args.output)
    print(f"wrote {sum(counts.values())} demonstrations in {len(counts)} files to {args.output}")
    return 0


def _replay(args: argparse.Namespace) -> int:
    from .logs.validate import LogError, check_record, log_files, read_records

    n_ok, problems = 0, []
    try:
        files = log_files(Path(args.input))
    except FileNotFoundError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    for path in files:
        try:
            for item in read_records(path):
                try:
                    check_record(item)
                    n_ok += 1
                except LogError as err:
                    problems.append(str(err))
        except LogError as err:  # unreadable line: the rest of that file cannot be trusted
            problems.append(str(err))
    for p in problems:
        print(p, file=sys.stderr)
    print(f"{n_ok} demonstrations replay exactly; {len(problems)} with problems")
    return 1 if problems else 0


def _ingest(args: argparse.Namespace) -> int:
    from .logs.ingest import dataset_summary, load_logs, write_tables
    from .logs.validate import LogError

    try:
        tables, records = load_logs(args.input)
    except (LogError, FileNotFoundError) as err:
        print(f"error: {err}", file=sys.stderr)
        print("nothing was written", file=sys.stderr)
        return 1
    summary = dataset_summary(tables)
    write_tables(tables, args.output)
    if args.metrics:
        write_json_atomic(args.metrics, summary)
    print(
        f"ingested {summary['sequences']} sequences ({summary['steps']} steps, {summary['scenarios']} scenarios, "
        f"{summary['environments']} environments) into {args.output}"
    )
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="taskseq",
        description="Learn to sequence manipulation primitives for under-specified tasks (unrolled MRF + SSVM).",
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    def add(name: str, help_: str, handler: Handler) -> argparse.ArgumentParser:
        p = sub.add_parser(name, help=help_, description=help_)
        p.set_defaults(handler=handler)
        return p

    p = add("generate", "simulate the demonstrator and write demonstration logs (JSON Lines)", _generate)
    p.add_argument("--seed", type=int, default=0, help="seed of scenario draws and position jitter (default 0)")
    p.add_argument("--output", type=Path, default=Path("data/raw"), help="folder of *.jsonl logs (replaced)")

    p = add("replay", "re-execute every logged sequence and report states or goals that differ", _replay)
    p.add_argument("input", type=Path, help="folder of *.jsonl logs")

    p = add("ingest", "validate logs and write them as Parquet tables plus dataset metrics", _ingest)
    p.add_argument("--input", type=Path, default=Path("data/raw"), help="folder of *.jsonl logs")
    p.add_argument("--output", type=Path, default=Path("data/processed"), help="folder of Parquet tables (replaced)")
    p.add_argument("--metrics", type=Path, default=Path("reports/dataset.json"), help="dataset counts as JSON")
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    return args.handler(args)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
