"""One route for every world the pipeline draws into a folder of its own: generate, ingest, features.

The reported worlds run these as three stages each (`generate`, `ingest`,
`features` in dvc.yaml, their outputs under `data/worlds/SEED`); the
development world (`dev_world`) and each seed's drawn world (`drawn_world`)
run the same three stage functions in one process, into one folder, with two
small manifests beside the data: `world.json` (family, seed, rooms, what
drawing cost) and `dataset.json` (the ingested counts). Later stages read the
world's seed and family from `world.json` instead of taking them again.
"""

from __future__ import annotations

from pathlib import Path

from ..settings import Generate
from ..track.mlflow_runs import NO_RUN, Tracker
from . import features, generate, ingest
from .generate import MANIFEST
from .options import FeaturesOptions, GenerateOptions, IngestOptions


def draw_world(world: Generate, folder: Path, tracker: Tracker = NO_RUN) -> None:
    """Draw `world` into `folder`: raw/ (logs), processed/ (tables), features/, world.json and dataset.json."""
    raw, processed = folder / "raw", folder / "processed"
    with tracker.child("generate", {"world_seed": world.seed}) as child:
        generate.run(world, GenerateOptions(output=raw, metrics=folder / MANIFEST), child)
    with tracker.child("ingest", {"world_seed": world.seed}) as child:
        ingest.run(None, IngestOptions(input=raw, output=processed, metrics=folder / "dataset.json"), child)
    with tracker.child("features", {"world_seed": world.seed}) as child:
        features.run(None, FeaturesOptions(input=processed, output=folder / "features"), child)

