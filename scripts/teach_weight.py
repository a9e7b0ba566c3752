"""Choose how much a taught step counts (`teach.weight`) on the development world's drawn rooms.

The `teach` stage trains the shipped planner on a drawn world's steps outside
the held-out rooms plus the k tasks a scripted person shows in each, every
taught step counted `teach.weight` times, so that a room's own ways can
weigh against the many steps of other rooms. This script runs the stage's
protocol (`taskseq.stages.teach.teach_world`) on the development world drawn
as a world of drawn rooms (`world.dev_seed`, never reported), once per weight
of the grid, and ranks the weights by sequence arg over every k above 0
pooled, then success, then the smaller weight. The first goes into
params.yaml by hand; docs/teach.md shows the table this writes.

    python scripts/teach_weight.py --weights 1 3 10 30 100 300 --output reports/teach_weight.json

Run it after `dvc repro` has run `select` (the shipped planner and its C are read from reports/selection.json).
"""

from __future__ import annotations

import argparse
import statistics
import sys
from dataclasses import replace
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from taskseq.demonstrations.benchmark import Benchmark  # noqa: E402
from taskseq.demonstrations.records import scenario_records  # noqa: E402
from taskseq.methods import Lineup  # noqa: E402
from taskseq.runtime.atomic import write_json_atomic  # noqa: E402
from taskseq.selection import read_selection  # noqa: E402
from taskseq.settings import Generate, Params  # noqa: E402
from taskseq.sim.scenarios import world_scenarios  # noqa: E402
from taskseq.stages.teach import teach_world  # noqa: E402


def rank(rows: list[dict[str, float]]) -> list[dict[str, float]]:
    """Best first: sequence arg over k > 0, then success, then the smaller weight."""
    return sorted(rows, key=lambda r: (-round(r["sequence_arg"], 9), -round(r["success"], 9), r["weight"]))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--weights", type=int, nargs="+", default=[1, 3, 10, 30, 100, 300],
                        help="times a taught step counts, to try (default: 1 3 10 30 100 300)")
    parser.add_argument("--selection", type=Path, default=ROOT / "reports" / "selection.json",
                        help="the shipped planner and its C (default: reports/selection.json)")
    parser.add_argument("--params", type=Path, default=ROOT / "params.yaml")
    parser.add_argument("--output", type=Path, help="also write the ranked table as JSON here")
    args = parser.parse_args(argv)
    if any(w < 1 for w in args.weights):
        parser.error("--weights: every weight must be at least 1")
    params = Params.load(args.params)
    teach, world = params.teach, params.world
    if max(teach.k) < 1:
        parser.error("teach.k has no k above 0: nothing is taught, so no weight can matter")
    selection = read_selection(args.selection)
    shipped = selection.method
    if shipped is None:
        parser.error(f"{args.selection}: names no method ranked first; run `taskseq select` again")
    make = Lineup(params.methods, selection, params.train.learner, procedural=params.procedural).mrf([shipped])[shipped]
    scenarios, _ = world_scenarios(Generate(world.dev_seed, "procedural", params.procedural))
    bench = Benchmark.from_records(scenario_records(scenarios))
    print(f"the shipped planner ({shipped}, C = {selection.of(shipped):g}) on the drawn development world "
          f"{world.dev_seed}: rooms {' '.join(teach.environments)} held out, k = {' '.join(map(str, teach.k))}",
          file=sys.stderr)
    rows, untaught = [], None
    for weight in args.weights:
        programs = teach_world(world.dev_seed, bench, replace(teach, weight=weight), make, params.crossval.max_steps)
        taught = [p for p in programs if p["k"] > 0]
        untaught = [p for p in programs if p["k"] == 0]
        rows.append({"weight": weight, **{f: 100.0 * statistics.fmean(p[f] for p in taught)
                                          for f in ("sequence_arg", "success")}})
    ranked = rank(rows)
    zero = {f: 100.0 * statistics.fmean(p[f] for p in untaught) for f in ("sequence_arg", "success")}
    print("| weight | sequence arg, k > 0 | success, k > 0 |")
    print("|---:|---:|---:|")
    for r in ranked:
        mark = " (chosen)" if r is ranked[0] else ""
        print(f"| {r['weight']}{mark} | {r['sequence_arg']:.1f} | {r['success']:.1f} |")
    print(f"| nothing taught (k = 0) | {zero['sequence_arg']:.1f} | {zero['success']:.1f} |")
    if args.output:
        write_json_atomic(args.output, {"dev_seed": world.dev_seed, "method": shipped, "C": selection.of(shipped),
                                        "environments": list(teach.environments), "k": list(teach.k),
                                        "chosen": ranked[0]["weight"], "ranked": ranked, "untaught": zero})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
