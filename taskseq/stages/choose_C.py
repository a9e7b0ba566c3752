"""Stage `choose_C`: choose one MRF method's C on the development world by cross-validation.

`dvc.yaml` runs it once per method whose entry of params.yaml's `methods`
names select (`choose_C@NAME`), each depending on its own method's module
only, so a change to one method re-does that method's choice alone; the
`select` stage then ranks the choices. The development world is drawn by the
`dev_world` stage into its own folder; this stage reads its features and
tables, and only the method's choice file leaves it.
"""

from __future__ import annotations

import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..demonstrations.benchmark import load_benchmark
from ..experiments.selection import CRITERION, DevData, choose_method_C
from ..features.dataset import read_features
from ..methods import Lineup
from ..runtime.atomic import write_json_atomic
from ..settings import Folds, Learner, Methods, Params, Procedural, Select
from ..track.mlflow_runs import NO_RUN, Tracker
from .generate import read_manifest
from .options import ChooseCOptions


@dataclass(frozen=True)
class Settings:
    seeds: tuple[int, ...]  # the reported world seeds, which the development world's may not be
    procedural: Procedural  # the rooms' distribution (a method trained also on drawn rooms draws them from it)
    select: Select
    learner: Learner  # the structural SVM's settings as `train` sets them; C is the value tried
    folds: Folds
    max_steps: int  # step cap of closed-loop runs
    methods: Methods  # params.yaml's methods; a run reads its own method's entry alone (`own_entry`)


def settings(params: Params, world_seed: int | None = None) -> Settings:
    c = params.crossval
    return Settings(params.world.seeds, params.procedural, params.select, params.train.learner, c.fold_settings,
                    c.max_steps, params.methods)


def run(settings: Settings, options: ChooseCOptions, tracker: Tracker = NO_RUN, n_jobs: int = 1) -> dict[str, Any]:
    select, folds, name = settings.select, settings.folds, options.method
    dev_seed = read_manifest(options.world)["seed"]
    if dev_seed in settings.seeds:
        raise ValueError(f"{options.world}: the development world's seed {dev_seed} is also a reported seed; "
                         "settings must be chosen on a world that is never reported")
    # a wrong name or entry stops here, before minutes of work
    lineup = Lineup(own_entry(settings.methods, name), learner=settings.learner, procedural=settings.procedural)
    lineup.mrf([name])
    contexts, meta = read_features(options.world / "features")
    bench = load_benchmark(options.world / "processed")
    dev = DevData(contexts, meta, bench, folds, settings.max_steps)
    print(f"choosing C for {name} among {' '.join(f'{c:g}' for c in select.C)} (extended at an edge, "
          f"{select.max_extensions} times at most) on the development world (seed {dev_seed}, "
          f"{len(bench.scenarios)} scenarios), {folds.folds} folds, {n_jobs} jobs")
    # the rounds' fold models (2.6 MB each) are read by this stage alone: not kept
    with tempfile.TemporaryDirectory(prefix="taskseq-choose-C-") as scratch:
        choice, rounds = choose_method_C(name, lambda method, C: lineup.at_C(C).factory(method), dev, select.C,
                                         select.max_extensions, Path(scratch), n_jobs, verbose=5)
    result = {"method": name, "criterion": CRITERION, "dev_seed": dev_seed, "grid": list(select.C),
              "max_extensions": select.max_extensions, "choice": choice}
    write_json_atomic(options.output, result)
    for c in choice["candidates"]:
        with tracker.child(f"{name} C={c['C']:g}", {"method": name, "C": c["C"]}) as child:
            child.metrics({k: v for k, v in c.items() if k != "C"})
        print(f"{name:<10} C={c['C']:<8g} sequence arg {c['sequence_arg']:5.1f}  success {c['success']:5.1f}  "
              f"step arg {c['average_arg']:5.1f}")
    tracker.params({"method": name})
    tracker.metrics({"seconds": sum(rounds), "C": choice["C"]})
    capped = " (the cap stopped it at an edge)" if choice["capped"] else ""
    print(f"{name} chose C={choice['C']:g} after {choice['extensions']} extensions{capped}; {len(rounds)} rounds "
          f"took {' + '.join(f'{s:.0f}' for s in rounds)} s; written to {options.output}")
    return result


def own_entry(methods: Methods, name: str) -> Methods:
    """`methods` with method `name`'s entry alone: a run's choice then cannot depend on another method's entry,
    which is why dvc.yaml's runs list `methods.NAME` among their params, not the whole section (an edit of one
    method's entry re-does that method's choice alone)."""
    return Methods(tuple(entry for entry in methods.entries if entry[0] == name))
