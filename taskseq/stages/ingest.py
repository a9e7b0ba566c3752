"""Stage `ingest`: validate the logs and write them as Parquet tables, with the dataset's counts."""

from __future__ import annotations

from typing import Any

from ..io import write_json_atomic
from ..logs.ingest import dataset_summary, load_logs, write_tables
from ..settings import Params
from ..track.mlflow_runs import NO_RUN, Tracker, flatten
from .paths import IngestPaths


def settings(params: Params, world_seed: int | None = None) -> None:
    """Ingesting reads no setting: the logs are taken as they are."""


def run(settings: None, paths: IngestPaths, tracker: Tracker = NO_RUN) -> dict[str, Any]:
    """Raises `LogError` (file, record, field) or `FileNotFoundError` before anything is written."""
    input_dir, output, metrics = paths.input, paths.output, paths.metrics
    tables, _ = load_logs(input_dir)
    summary = dataset_summary(tables)
    write_tables(tables, output)
    if metrics:
        write_json_atomic(metrics, summary)
    tracker.metrics({k: v for k, v in flatten(summary).items() if isinstance(v, (int, float))})
    print(f"ingested {summary['sequences']} sequences ({summary['steps']} steps, {summary['scenarios']} scenarios, "
          f"{summary['environments']} environments) into {output}")
    return summary
