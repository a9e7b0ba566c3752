"""Stage `select`: draw the development world, choose each MRF method's C on it by cross-validation, rank them.

The development world goes through the same generate, ingest and feature
steps as a reported world, into its own folder; only `selection.json` leaves
it. Every reported figure then uses each method's chosen C, and the `train`
stage ships the method ranked first.
"""

from __future__ import annotations

import tempfile
import time
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from .. import methods as _every_method  # noqa: F401  (the added methods register themselves: Table I whole)
from ..demonstrations.benchmark import Benchmark
from ..demonstrations.generate import generate
from ..demonstrations.ingest import load_logs, write_tables
from ..evaluate.methods import mrf_methods
from ..experiments.selection import CRITERION, DevData, choose_C, cross_validate_settings, rank_methods
from ..features.dataset import build_steps, write_features
from ..runtime.atomic import write_json_atomic
from ..settings import Folds, Generate, Learner, Params, Procedural, Select, World
from ..track.mlflow_runs import NO_RUN, Tracker
from .paths import SelectPaths


@dataclass(frozen=True)
class Settings:
    world: World
    procedural: Procedural  # the rooms' distribution, when world.family draws them
    select: Select
    learner: Learner  # C is the value tried; the rest (DAgger's rounds too) as `train` sets it
    folds: Folds
    max_steps: int  # step cap of closed-loop runs


def settings(params: Params, world_seed: int | None = None) -> Settings:
    t, c = params.train, params.crossval
    return Settings(params.world, params.procedural, params.select,
                    Learner(tol=t.tol, max_iter=t.max_iter, n_slacks=t.n_slacks, dagger_rounds=t.dagger_rounds,
                            noise_rate=t.noise_rate, noise_copies=t.noise_copies),
                    c.fold_settings, c.max_steps)


def run(settings: Settings, paths: SelectPaths, tracker: Tracker = NO_RUN, n_jobs: int = 1) -> dict[str, Any]:
    world, select, folds = settings.world, settings.select, settings.folds
    if world.dev_seed in world.seeds:
        raise ValueError(f"params.yaml: world.dev_seed {world.dev_seed} is also a reported seed; settings must "
                         "be chosen on a world that is never reported")
    mrf_methods(settings.learner, names=select.methods)  # an unknown name stops here, before minutes of work
    data, output = paths.data, paths.output
    rooms = replace(settings.procedural, environments=select.environments)  # the development world's own size
    generate(Generate(world.dev_seed, world.family, rooms), data / "raw")
    tables, records = load_logs(data / "raw")
    write_tables(tables, data / "processed")
    contexts, meta = build_steps([r.record for r in records])
    write_features(contexts, meta, data / "features")
    bench = Benchmark.from_records([r.record for r in records])
    dev = DevData(contexts, meta, bench, folds, settings.max_steps)
    print(f"choosing C for {', '.join(select.methods)} among {' '.join(f'{c:g}' for c in select.C)} (extended at "
          f"an edge, {select.max_extensions} times at most) on the development world (seed {world.dev_seed}, "
          f"{len(bench.scenarios)} scenarios), {folds.folds} folds, {n_jobs} jobs")
    rounds: list[float] = []  # each round's seconds
    # the rounds' fold models (2.6 MB each, about 100 in the first round) are read by this stage alone: not kept
    with tempfile.TemporaryDirectory(prefix="taskseq-select-") as scratch:

        def evaluate(pending: dict[str, tuple[float, ...]]) -> dict[str, dict[float, dict[str, float]]]:
            print(f"round {len(rounds)}: " + "; ".join(f"{m} C={' '.join(f'{c:g}' for c in v)}"
                                                      for m, v in pending.items()))
            start = time.perf_counter()
            out = cross_validate_settings(pending, settings.learner, dev, Path(scratch) / str(len(rounds)), n_jobs,
                                          verbose=5)
            rounds.append(time.perf_counter() - start)
            return out

        chosen = choose_C(select.methods, select.C, evaluate, select.max_extensions)
    ranking = rank_methods(chosen)
    result = {"C": chosen["full"]["C"], "criterion": CRITERION, "dev_seed": world.dev_seed,
              "grid": list(select.C), "max_extensions": select.max_extensions, "settings": chosen,
              "method": ranking[0]["method"], "methods": ranking,
              "method_criterion": "sequence_arg, then success, then the order of select.methods"}
    write_json_atomic(output, result)
    for name, choice in chosen.items():
        for c in choice["candidates"]:
            with tracker.child(f"{name} C={c['C']:g}", {"method": name, "C": c["C"]}) as child:
                child.metrics({k: v for k, v in c.items() if k != "C"})
            print(f"{name:<10} C={c['C']:<8g} sequence arg {c['sequence_arg']:5.1f}  success {c['success']:5.1f}  "
                  f"step arg {c['average_arg']:5.1f}")
        capped = " (the cap stopped it at an edge)" if choice["capped"] else ""
        print(f"{name:<10} chose C={choice['C']:g} after {choice['extensions']} extensions{capped}")
    tracker.metrics({"C": result["C"], "seconds": sum(rounds),
                     **{f"C.{name}": choice["C"] for name, choice in chosen.items()}})
    for r in ranking:
        print(f"{r['method']:<10} C={r['C']:<8g} sequence arg {r['sequence_arg']:5.1f}  success "
              f"{r['success']:5.1f}  step arg {r['average_arg']:5.1f}")
    tracker.params({"method": result["method"]})
    print(f"{len(rounds)} rounds took {' + '.join(f'{s:.0f}' for s in rounds)} s; chose method "
          f"{result['method']} at C={ranking[0]['C']:g}; written to {output}")
    return result
