"""Stage `generate`: simulate the demonstrator over the benchmark's scenarios and write JSON Lines logs."""

from __future__ import annotations

from ..logs.generate import generate
from ..settings import Generate, Params
from ..track.mlflow_runs import NO_RUN, Tracker
from .paths import GeneratePaths


def settings(params: Params, world_seed: int | None = None) -> Generate:
    """The world drawn is the one the command names (`--world-seed`); `params.yaml` lists which are reported."""
    if world_seed is None:
        raise ValueError("generate: name the world to draw with --world-seed N")
    return Generate(seed=world_seed)


def run(settings: Generate, paths: GeneratePaths, tracker: Tracker = NO_RUN) -> dict[str, int]:
    output = paths.output
    counts = generate(settings.seed, output)
    tracker.metrics({"demonstrations": sum(counts.values()), "files": len(counts)})
    print(f"wrote {sum(counts.values())} demonstrations in {len(counts)} files to {output}")
    return counts
