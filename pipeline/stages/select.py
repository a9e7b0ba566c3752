"""Stage `select`: draw the development world, choose C on it by cross-validation, rank the MRF methods at that C.

The development world goes through the same generate, ingest and feature
steps as a reported world, into its own folder; only `selection.json` leaves
it. Every reported figure then uses the chosen C, and the `train` stage ships
the method ranked first.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

from ..evaluate.methods import mrf_methods
from ..evaluate.selection import rank_methods, select_C
from ..features.dataset import build_steps, write_features
from ..io import write_json_atomic
from ..logs.benchmark import Benchmark
from ..logs.generate import generate
from ..logs.ingest import load_logs, write_tables
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
                    Learner(tol=t.tol, max_iter=t.max_iter, n_slacks=t.n_slacks, dagger_rounds=t.dagger_rounds),
                    c.fold_settings, c.max_steps)


def run(settings: Settings, paths: SelectPaths, tracker: Tracker = NO_RUN, n_jobs: int = 1) -> dict[str, Any]:
    world, select, folds = settings.world, settings.select, settings.folds
    if world.dev_seed in world.seeds:
        raise ValueError(f"params.yaml: world.dev_seed {world.dev_seed} is also a reported seed; settings must "
                         "be chosen on a world that is never reported")
    mrf_methods(settings.learner, names=select.methods)  # an unknown name stops here, before minutes of work
    data, output = paths.data, paths.output
    generate(Generate(world.dev_seed, world.family, settings.procedural), data / "raw")
    tables, records = load_logs(data / "raw")
    write_tables(tables, data / "processed")
    contexts, meta = build_steps([r.record for r in records])
    write_features(contexts, meta, data / "features")
    bench = Benchmark.from_records([r.record for r in records])
    print(f"choosing C among {', '.join(f'{c:g}' for c in select.C)} on the development world (seed "
          f"{world.dev_seed}, {len(bench.scenarios)} scenarios), {folds.folds} folds, {n_jobs} jobs")
    result = select_C(select.C, settings.learner, folds, contexts, meta, bench, settings.max_steps,
                      n_jobs=n_jobs, verbose=5)
    best = next(c for c in result["candidates"] if c["C"] == result["C"])
    known = {"full": {k: best[k] for k in ("sequence_arg", "success", "average_arg")}}
    print(f"ranking {', '.join(select.methods)} at C={result['C']:g} on the same folds")
    ranking = rank_methods(select.methods, replace(settings.learner, C=result["C"]), folds, contexts, meta, bench,
                           settings.max_steps, known, n_jobs=n_jobs, verbose=5)
    result = {**result, "dev_seed": world.dev_seed, "method": ranking[0]["method"], "methods": ranking,
              "method_criterion": "sequence_arg, then success, then the order of select.methods"}
    write_json_atomic(output, result)
    for c in result["candidates"]:
        with tracker.child(f"C={c['C']:g}", {"C": c["C"]}) as child:
            child.metrics({k: v for k, v in c.items() if k != "C"})
    tracker.metrics({"C": result["C"]})
    for c in result["candidates"]:
        print(f"C={c['C']:<6g} sequence arg {c['sequence_arg']:5.1f}  success {c['success']:5.1f}  "
              f"step arg {c['average_arg']:5.1f}")
    for r in ranking:
        with tracker.child(f"method={r['method']}", {"method": r["method"], "C": result["C"]}) as child:
            child.metrics({k: v for k, v in r.items() if k != "method"})
        print(f"{r['method']:<12} sequence arg {r['sequence_arg']:5.1f}  success {r['success']:5.1f}  "
              f"step arg {r['average_arg']:5.1f}")
    tracker.params({"method": result["method"]})
    print(f"chose C={result['C']:g} and method {result['method']}; written to {output}")
    return result
