"""Stage `features`: every teacher-forced step's candidates and features, from the Parquet tables."""

from __future__ import annotations

from ..demonstrations.ingest import read_tables, records_from_tables
from ..features.context import candidate_index
from ..features.dataset import build_steps, write_features
from ..runtime.atomic import refuse_replacing_inputs
from ..settings import Params
from ..track.mlflow_runs import NO_RUN, Tracker
from .options import FeaturesOptions


def settings(params: Params, world_seed: int | None = None) -> None:
    """The features read no setting: every candidate of every step is built."""


def run(settings: None, options: FeaturesOptions, tracker: Tracker = NO_RUN) -> int:
    input_dir, output = options.input, options.output
    refuse_replacing_inputs(output, input=input_dir)
    records = records_from_tables(read_tables(input_dir))
    contexts, meta = build_steps(records)
    write_features(contexts, meta, output)
    n_cand = sum(len(candidate_index(c.n)[0]) for c in contexts)
    tracker.metrics({"steps": len(contexts), "candidates": n_cand, "sequences": len(records)})
    print(f"wrote {len(contexts)} steps ({n_cand} candidates) from {len(records)} sequences to {output}")
    return len(contexts)
