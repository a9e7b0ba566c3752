"""Choose how many drawn rooms `ours + ... + drawn rooms` trains on, on the development world's drawn rooms.

The method (`taskseq/methods/drawn_rooms.py`) adds to every fit the
demonstrated steps of `rooms` rooms drawn from params.yaml's `procedural`
distribution with their own seed. This script draws the development world
as a world of drawn rooms (`world.dev_seed`, `procedural.environments`
rooms: never reported), cross-validates with whole rooms held out (the
`scenes` stage's folds), once per number of rooms in the grid and once
without drawn rooms (the choice-cue planner, `choice_lookahead`), all at
that planner's C from reports/selection.json, and ranks the numbers by
sequence arg, then success, then fewer rooms. The first goes into
params.yaml by hand (`methods.drawn_rooms.rooms`); docs/model.md shows the
table this prints.

    python scripts/drawn_rooms.py --rooms 13 26 52 104 --output reports/drawn_rooms_choice.json

Run it after `dvc repro` has run `select` (it reads C from reports/selection.json).
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from dataclasses import replace
from functools import partial
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from taskseq.demonstrations.benchmark import Benchmark  # noqa: E402
from taskseq.demonstrations.records import scenario_records  # noqa: E402
from taskseq.evaluate.methods import ScorerMethod  # noqa: E402
from taskseq.evaluate.metrics import summarize  # noqa: E402
from taskseq.experiments.crossval import cross_validate  # noqa: E402
from taskseq.features.dataset import build_steps  # noqa: E402
from taskseq.methods import Lineup  # noqa: E402
from taskseq.runtime.atomic import write_json_atomic  # noqa: E402
from taskseq.selection import Selection, read_selection  # noqa: E402
from taskseq.settings import Generate, Params  # noqa: E402
from taskseq.sim.scenarios import world_scenarios  # noqa: E402


def _renamed(make: Callable[[], ScorerMethod], name: str) -> ScorerMethod:
    """A method as `make` builds it, under its row's name in this script's table."""
    return replace(make(), name=name)


def rank(rows: list[dict[str, float]]) -> list[dict[str, float]]:
    """Best first: sequence arg, then success, then fewer rooms."""
    return sorted(rows, key=lambda r: (-round(r["sequence_arg"], 9), -round(r["success"], 9), r["rooms"]))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--rooms", type=int, nargs="+", default=[13, 26, 52, 104],
                        help="numbers of drawn rooms to try (default: 13 26 52 104)")
    parser.add_argument("--selection", type=Path, default=ROOT / "reports" / "selection.json",
                        help="C is the choice-cue planner's C there (default: reports/selection.json)")
    parser.add_argument("--params", type=Path, default=ROOT / "params.yaml")
    parser.add_argument("--output", type=Path, help="also write the ranked table as JSON here")
    parser.add_argument("--n-jobs", type=int, default=2)
    args = parser.parse_args(argv)
    if any(n < 1 for n in args.rooms):
        parser.error("--rooms: every number of rooms must be at least 1")
    params = Params.load(args.params)
    world, crossval, learner = params.world, params.crossval, params.train.learner
    seed = Lineup(params.methods).settings_of("drawn_rooms").rooms_seed
    if seed in (*world.seeds, world.dev_seed):
        parser.error(f"methods.drawn_rooms.rooms_seed {seed} is a world's seed: its rooms would be that world's")
    C = read_selection(args.selection).of("choice_lookahead")
    dev = Generate(world.dev_seed, "procedural", params.procedural)
    scenarios, _ = world_scenarios(dev)
    records = scenario_records(scenarios)
    contexts, meta = build_steps(records)
    bench = Benchmark.from_records(records)
    # both methods as their specs build them (taskseq/methods), at the choice-cue planner's C, one per room count
    at_C = Selection(dict.fromkeys(("choice_lookahead", "drawn_rooms"), C), source=str(args.selection))
    makes = {"none": partial(_renamed, Lineup(params.methods, at_C, learner).factory("choice_lookahead"), "none")}
    for n in args.rooms:
        rooms = Params.load(args.params, [f"methods.drawn_rooms.rooms={n}"]).methods
        makes[f"rooms{n}"] = partial(_renamed, Lineup(rooms, at_C, learner, procedural=params.procedural)
                                     .factory("drawn_rooms"), f"rooms{n}")
    print(f"{len(makes)} settings x {crossval.folds} folds, rooms held out, on the drawn development world "
          f"{world.dev_seed} ({params.procedural.environments} rooms, {len(bench.scenarios)} scenarios), "
          f"C = {C:g}, drawn rooms' seed {seed}", file=sys.stderr)
    results = cross_validate(makes, contexts, meta, bench, n_folds=crossval.folds, seed=crossval.seed,
                             group_by="environment", max_steps=crossval.max_steps, n_jobs=args.n_jobs)
    summary = summarize(results, contexts, dict.fromkeys(makes, True))
    rows = [{"rooms": 0 if name == "none" else int(name[5:]), "sequence_arg": s["sequence/arg"],
             "success": s["success"]} for name, s in summary.items()]
    ranked = rank([r for r in rows if r["rooms"]])
    print("| drawn rooms added | sequence arg | success |")
    print("|---:|---:|---:|")
    for r in [*ranked, *[r for r in rows if not r["rooms"]]]:
        mark = " (chosen)" if r is ranked[0] else ""
        print(f"| {r['rooms'] or 'none'}{mark} | {r['sequence_arg']:.1f} | {r['success']:.1f} |")
    if args.output:
        write_json_atomic(args.output, {"dev_seed": world.dev_seed, "rooms_seed": seed, "C": C,
                                        "chosen": ranked[0]["rooms"], "ranked": ranked,
                                        "without": [r for r in rows if not r["rooms"]]})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
