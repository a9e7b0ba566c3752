"""Stage `select`: draw the development world and choose C on it by cross-validation.

The development world goes through the same generate, ingest and feature
steps as a reported world, into its own folder; only `selection.json` leaves
it. Every reported figure then uses the chosen C.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from ..evaluate.selection import select_C
from ..features.dataset import build_steps, write_features
from ..io import write_json_atomic
from ..logs.benchmark import Benchmark
from ..logs.generate import generate
from ..logs.ingest import load_logs, write_tables
from ..settings import Crossval, Learner, Select, World
from ..track.mlflow_runs import NO_RUN, Tracker


def run(world: World, select: Select, learner: Learner, crossval: Crossval, data: Path, output: Path,
        n_jobs: int = 1, tracker: Tracker = NO_RUN) -> dict[str, Any]:
    if world.dev_seed in world.seeds:
        raise ValueError(f"params.yaml: world.dev_seed {world.dev_seed} is also a reported seed; settings must "
                         "be chosen on a world that is never reported")
    data = Path(data)
    generate(world.dev_seed, data / "raw")
    tables, records = load_logs(data / "raw")
    write_tables(tables, data / "processed")
    contexts, meta = build_steps([r.record for r in records])
    write_features(contexts, meta, data / "features")
    bench = Benchmark.from_records([r.record for r in records])
    print(f"choosing C among {', '.join(f'{c:g}' for c in select.C)} on the development world (seed "
          f"{world.dev_seed}, {len(bench.scenarios)} scenarios), {crossval.folds} folds, {n_jobs} jobs")
    result = select_C(select.C, learner, crossval.fold_settings, contexts, meta, bench, crossval.max_steps,
                      n_jobs=n_jobs, verbose=5)
    result = {**result, "dev_seed": world.dev_seed}
    write_json_atomic(output, result)
    for c in result["candidates"]:
        with tracker.child(f"C={c['C']:g}", {"C": c["C"]}) as child:
            child.metrics({k: v for k, v in c.items() if k != "C"})
    tracker.metrics({"C": result["C"]})
    for c in result["candidates"]:
        print(f"C={c['C']:<6g} sequence arg {c['sequence_arg']:5.1f}  success {c['success']:5.1f}  "
              f"step arg {c['average_arg']:5.1f}")
    print(f"chose C={result['C']:g}; written to {output}")
    return result
