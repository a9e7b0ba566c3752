"""Stage `generate`: simulate the demonstrator over the benchmark's scenarios and write JSON Lines logs."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from ..demonstrations.generate import generate
from ..runtime.atomic import write_json_atomic
from ..settings import Generate, Params
from ..track.mlflow_runs import NO_RUN, Tracker
from .options import GenerateOptions

MANIFEST = "world.json"  # what a world folder says of its world (`stages.world_folder`): family, seed, rooms, cost


def settings(params: Params, world_seed: int | None = None) -> Generate:
    """The world drawn is the one the command names (`--world-seed`); `params.yaml` lists which are reported."""
    if world_seed is None:
        raise ValueError("generate: name the world to draw with --world-seed N")
    return Generate(world_seed, params.world.family, params.procedural)


def run(settings: Generate, options: GenerateOptions, tracker: Tracker = NO_RUN) -> dict[str, int]:
    output = options.output
    counts, report = generate(settings, output)
    tracker.metrics({"demonstrations": sum(counts.values()), "files": len(counts),
                     "redraws": sum(report.redraws.values())})
    if options.metrics is not None:
        write_json_atomic(options.metrics, {"family": settings.family, "seed": settings.seed, **report.as_dict(),
                                          "demonstrations": sum(counts.values())})
    redrawn = f" ({sum(report.redraws.values())} rooms redrawn)" if report.redraws else ""
    print(f"wrote {sum(counts.values())} demonstrations in {len(counts)} files to {output}{redrawn}")
    return counts


def read_manifest(folder: Path) -> dict[str, Any]:
    """The world.json of a world folder (`stages.world_folder`): the seed and family it was drawn with."""
    path = folder / MANIFEST
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such file; draw the world first (taskseq dev_world or drawn_world)")
    return json.loads(path.read_text())
