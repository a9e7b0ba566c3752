"""Stage `select`: choose each MRF method's C on the development world by cross-validation, and rank them.

The development world is drawn by the `dev_world` stage into its own folder
(the same generate, ingest and features steps as a reported world); this
stage reads its features and tables, and only `selection.json` leaves it.
Every reported figure then uses each method's chosen C, and the `train`
stage ships the method ranked first.
"""

from __future__ import annotations

import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..demonstrations.benchmark import load_benchmark
from ..experiments.selection import CRITERION, DevData, choose_C, cross_validate_settings, rank_methods
from ..features.dataset import read_features
from ..methods import PAPER_MODEL, Lineup
from ..runtime.atomic import write_json_atomic
from ..settings import Folds, Learner, Methods, Params, Procedural, Select
from ..track.mlflow_runs import NO_RUN, Tracker
from .generate import read_manifest
from .options import SelectOptions


@dataclass(frozen=True)
class Settings:
    seeds: tuple[int, ...]  # the reported world seeds, which the development world's may not be
    procedural: Procedural  # the rooms' distribution (a method trained also on drawn rooms draws them from it)
    select: Select
    learner: Learner  # the structural SVM's settings as `train` sets them; C is the value tried
    folds: Folds
    max_steps: int  # step cap of closed-loop runs
    methods: Methods  # those whose experiments name select get their own C, then are ranked


def settings(params: Params, world_seed: int | None = None) -> Settings:
    c = params.crossval
    return Settings(params.world.seeds, params.procedural, params.select, params.train.learner, c.fold_settings,
                    c.max_steps, params.methods)


def run(settings: Settings, options: SelectOptions, tracker: Tracker = NO_RUN, n_jobs: int = 1) -> dict[str, Any]:
    select, folds = settings.select, settings.folds
    dev_seed = read_manifest(options.world)["seed"]
    if dev_seed in settings.seeds:
        raise ValueError(f"{options.world}: the development world's seed {dev_seed} is also a reported seed; "
                         "settings must be chosen on a world that is never reported")
    # a wrong entry stops here, before minutes of work
    lineup = Lineup(settings.methods, learner=settings.learner, procedural=settings.procedural)
    names = lineup.names("select")
    if PAPER_MODEL not in names:
        raise ValueError(f"params.yaml: methods.{PAPER_MODEL}.experiments must include select: its C is also the "
                         "paper's ablations' (only_edge, only_clique) and the people stage's")
    lineup.mrf(names)
    output = options.output
    contexts, meta = read_features(options.world / "features")
    bench = load_benchmark(options.world / "processed")
    dev = DevData(contexts, meta, bench, folds, settings.max_steps)
    print(f"choosing C for {', '.join(names)} among {' '.join(f'{c:g}' for c in select.C)} (extended at "
          f"an edge, {select.max_extensions} times at most) on the development world (seed {dev_seed}, "
          f"{len(bench.scenarios)} scenarios), {folds.folds} folds, {n_jobs} jobs")
    rounds: list[float] = []  # each round's seconds
    # the rounds' fold models (2.6 MB each, about 100 in the first round) are read by this stage alone: not kept
    with tempfile.TemporaryDirectory(prefix="taskseq-select-") as scratch:

        def evaluate(pending: dict[str, tuple[float, ...]]) -> dict[str, dict[float, dict[str, float]]]:
            print(f"round {len(rounds)}: " + "; ".join(f"{m} C={' '.join(f'{c:g}' for c in v)}"
                                                      for m, v in pending.items()))
            start = time.perf_counter()
            out = cross_validate_settings(pending, lambda name, C: lineup.at_C(C).factory(name), dev,
                                          Path(scratch) / str(len(rounds)), n_jobs, verbose=5)
            rounds.append(time.perf_counter() - start)
            return out

        chosen = choose_C(names, select.C, evaluate, select.max_extensions)
    ranking = rank_methods(chosen)
    result = {"criterion": CRITERION, "dev_seed": dev_seed,
              "grid": list(select.C), "max_extensions": select.max_extensions, "settings": chosen,
              "method": ranking[0]["method"], "methods": ranking,
              # the order is now params.yaml's `methods` section's; the words stay, so the file stays the same bytes
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
    tracker.metrics({"seconds": sum(rounds),
                     **{f"C.{name}": choice["C"] for name, choice in chosen.items()}})
    for r in ranking:
        print(f"{r['method']:<10} C={r['C']:<8g} sequence arg {r['sequence_arg']:5.1f}  success "
              f"{r['success']:5.1f}  step arg {r['average_arg']:5.1f}")
    tracker.params({"method": result["method"]})
    print(f"{len(rounds)} rounds took {' + '.join(f'{s:.0f}' for s in rounds)} s; chose method "
          f"{result['method']} at C={ranking[0]['C']:g}; written to {output}")
    return result
