"""Stage `pddl`: the PDDL domain, a problem per scenario and its shortest plan, for symbolic planners."""

from __future__ import annotations

from pathlib import Path

from ..demonstrations.benchmark import load_benchmark
from ..plan.symbolic.files import write_pddl
from ..runtime.atomic import refuse_replacing_inputs
from ..settings import Params, Pddl
from ..track.mlflow_runs import NO_RUN, Tracker
from .options import PddlOptions


def settings(params: Params, world_seed: int | None = None) -> Pddl:
    return Pddl(params.pddl.horizon)


def run(settings: Pddl, options: PddlOptions, tracker: Tracker = NO_RUN) -> dict[str, int]:
    processed, output = options.processed, options.output
    refuse_replacing_inputs(output, processed=processed)
    counts = write_pddl(load_benchmark(processed).scenarios, output, horizon=settings.horizon)
    tracker.metrics(counts)
    tracker.artifact(Path(output) / "domain.pddl")
    print(f"wrote the domain, {counts['problems']} problems and {counts['plans']} shortest plans to {output}"
          + (f"; {counts['no_plan']} without a plan within horizon {settings.horizon}" if counts["no_plan"] else ""))
    return counts
