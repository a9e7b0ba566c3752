"""Stage `ingest`: validate the logs and write them as Parquet tables, with the dataset's counts."""

from __future__ import annotations

import sys
from typing import Any

from ..demonstrations.ingest import dataset_summary, load_logs, load_people_logs, people_folder, write_tables
from ..demonstrations.validate import LogError
from ..runtime.atomic import refuse_replacing_inputs, write_json_atomic
from ..settings import Params
from ..track.mlflow_runs import NO_RUN, Tracker, flatten
from ..words import counted
from .options import IngestOptions


def settings(params: Params, world_seed: int | None = None) -> None:
    """Ingesting reads no setting: the logs are taken as they are."""


def run(settings: None, options: IngestOptions, tracker: Tracker = NO_RUN) -> dict[str, Any]:
    """Raises `LogError` (file, record, field) or `FileNotFoundError` before anything is written.

    A folder of people's demonstrations (`--people`, or records `taskseq serve` wrote and none of the scripted
    demonstrator's, `demonstrations.ingest.people_folder`): a file with a problem is named on stderr and left
    out, and the others are ingested; it raises only when no file is usable. The benchmark's logs fail at their
    first problem."""
    input_dir, output, metrics = options.input, options.output, options.metrics
    refuse_replacing_inputs(output, input=input_dir)
    people = options.people
    if not people and people_folder(input_dir):
        people = True
        print(f"{input_dir}: records written by taskseq serve; ingested as a folder of people's demonstrations "
              "(as with --people: a file with a problem is left out)", file=sys.stderr)
    if people:
        tables, records, skipped = load_people_logs(input_dir)
        for err in skipped:
            print(f"left out {err.path} (the file stays where it is): {err}", file=sys.stderr)
        if not records:
            raise LogError(input_dir, 0, "(file)", f"no usable records: {counted(len(skipped), 'file')} left out")
    else:
        tables, _ = load_logs(input_dir)
    summary = dataset_summary(tables)
    write_tables(tables, output)
    if metrics:
        write_json_atomic(metrics, summary)
    tracker.metrics({k: v for k, v in flatten(summary).items() if isinstance(v, (int, float))})
    counts = ", ".join(counted(summary[k], k[:-1]) for k in ("steps", "scenarios", "environments"))
    print(f"ingested {counted(summary['sequences'], 'sequence')} ({counts}) into {output}")
    return summary

