"""Stage `generate`: simulate the demonstrator over the benchmark's scenarios and write JSON Lines logs."""

from __future__ import annotations

from pathlib import Path

from ..logs.generate import generate
from ..settings import Generate
from ..track.mlflow_runs import NO_RUN, Tracker


def run(settings: Generate, output: Path, tracker: Tracker = NO_RUN) -> dict[str, int]:
    counts = generate(settings.seed, output)
    tracker.metrics({"demonstrations": sum(counts.values()), "files": len(counts)})
    print(f"wrote {sum(counts.values())} demonstrations in {len(counts)} files to {output}")
    return counts
