"""Choose how much a taught step counts (`teach.weight`) on drawn development worlds.

The `teach` stage trains the shipped planner on a drawn world's steps outside
the held-out rooms plus the k tasks a scripted person shows in each, every
taught step counted `teach.weight` times, so that a room's own ways can
weigh against the many steps of other rooms. This script runs the stage's
protocol (`taskseq.stages.teach.teach_world`) on development worlds drawn as
worlds of drawn rooms (`world.dev_seed` by default; `--dev-seeds` adds other
draws, each one that no stage reports), once per weight of the grid, and
ranks the weights by sequence arg over every k above 0 and every draw
pooled, then success, then the smaller weight. The first goes into
params.yaml by hand; docs/teach.md shows the table this writes, with the
share of k = 0's misses of sequence arg that the largest k removes, per draw.

    python scripts/teach_weight.py --weights 1 3 10 30 100 300 --dev-seeds 100 101 102 103 104 \
        --output reports/teach_weight.json

Run it after `dvc repro` has run `select` (the shipped planner and its C are read from reports/selection.json).
"""

from __future__ import annotations

import argparse
import statistics
import sys
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from taskseq.demonstrations.benchmark import Benchmark  # noqa: E402
from taskseq.demonstrations.records import scenario_records  # noqa: E402
from taskseq.experiments.crossval import judge  # noqa: E402
from taskseq.methods import Lineup  # noqa: E402
from taskseq.runtime.atomic import write_json_atomic  # noqa: E402
from taskseq.selection import read_selection  # noqa: E402
from taskseq.settings import Generate, Params  # noqa: E402
from taskseq.sim.scenarios import world_scenarios  # noqa: E402
from taskseq.stages.teach import taught_method, teach_jobs, teach_world  # noqa: E402


def rank(rows: list[dict[str, float]]) -> list[dict[str, float]]:
    """Best first: sequence arg over k > 0, then success, then the smaller weight."""
    return sorted(rows, key=lambda r: (-round(r["sequence_arg"], 9), -round(r["success"], 9), r["weight"]))


@dataclass(frozen=True)
class DevSetting:
    """What a measurement of the teach protocol on development draws runs with, checked."""

    params: Params
    seeds: list[int]  # the drawn development worlds, never a reported one
    shipped: str  # the method `select` ranked first
    C: float  # its C
    make: Any  # its factory of unfitted methods


def add_dev_options(parser: argparse.ArgumentParser) -> None:
    """The options every teach-protocol measurement takes: the selection, params, output and development draws."""
    parser.add_argument("--selection", type=Path, default=ROOT / "reports" / "selection.json",
                        help="the shipped planner and its C (default: reports/selection.json)")
    parser.add_argument("--params", type=Path, default=ROOT / "params.yaml")
    parser.add_argument("--output", type=Path, help="also write the table as JSON here")
    parser.add_argument("--dev-seeds", type=int, nargs="+",
                        help="seeds of the drawn development worlds (default: world.dev_seed); never a reported one")


def dev_setting(parser: argparse.ArgumentParser, args: argparse.Namespace) -> DevSetting:
    """The checked setting of `add_dev_options`' options: a reported world seed, a `teach.k` without a k above 0
    or a selection that names no shipped planner stops the script with one line."""
    params = Params.load(args.params)
    teach, world = params.teach, params.world
    seeds = args.dev_seeds or [world.dev_seed]
    reported = sorted(set(seeds) & set(world.seeds))
    if reported:
        parser.error(f"--dev-seeds: {', '.join(map(str, reported))} is a reported world seed (world.seeds); "
                     "settings are chosen on development draws only")
    if max(teach.k) < 1:
        parser.error("teach.k has no k above 0: nothing is taught, so there is nothing to measure")
    selection = read_selection(args.selection)
    shipped = selection.method
    if shipped is None:
        parser.error(f"{args.selection}: names no method ranked first; run `taskseq select` again")
    make = Lineup(params.methods, selection, params.train.learner, procedural=params.procedural).mrf([shipped])[shipped]
    return DevSetting(params, seeds, shipped, selection.of(shipped), make)


def room_variants(dev: DevSetting, settings: list[float], planner_for: Callable[[Any, Any, float], Any],
                  what: str) -> list[dict[str, Any]]:
    """The teach protocol on each development draw with the planner changed per taught room: for the planner
    without the taught steps (k = 0) and the one refitted with the first max(`teach.k`) tasks of each room as
    `teach` does, every setting s of `settings` runs `planner_for(fitted, room, s)` (a planner, or `fitted`
    itself) on that room's judged tasks. One row per (k of the refit, setting): the programs, the misses of
    sequence arg in all and per draw, and the successes. `what` names the setting in the progress lines."""
    params, make, teach = dev.params, dev.make, dev.params.teach
    most = max(teach.k)
    print(f"the shipped planner ({dev.shipped}, C = {dev.C:g}) on the drawn development worlds "
          f"{' '.join(map(str, dev.seeds))}: rooms {' '.join(teach.environments)} held out, the first {most} tasks "
          f"of each taught", file=sys.stderr)
    counts: dict[tuple[int, float], dict[str, Any]] = {}
    for seed in dev.seeds:
        scenarios, _ = world_scenarios(Generate(seed, "procedural", params.procedural))
        bench = Benchmark.from_records(scenario_records(scenarios))
        _, (_, _, base, rooms, known, weight, _, max_steps) = teach_jobs(seed, bench, teach, make,
                                                                        params.crossval.max_steps)[0]
        for k in (0, most):
            method = taught_method(k, base, rooms, known, weight, make)
            fitted = method.planner_
            for setting in settings:
                tally = counts.setdefault((k, setting), {"programs": 0, "misses": 0, "successes": 0,
                                                         "misses_by_world": {}})
                missed = 0
                for room in rooms:
                    method.planner_ = planner_for(fitted, room, setting)
                    for scenario in room.tested:
                        outcome = judge(scenario, method.run(scenario, max_steps))
                        tally["programs"] += 1
                        tally["successes"] += int(outcome.success)
                        missed += int(not outcome.arg_correct)
                tally["misses"] += missed
                tally["misses_by_world"][str(seed)] = missed
                print(f"world {seed}, refit with k = {k}, {what} {setting:g}: {missed} misses", file=sys.stderr)
            method.planner_ = fitted
    return [{"refit_k": k, what: setting, **tally} for (k, setting), tally in sorted(counts.items())]


def show_variants(dev: DevSetting, rows: list[dict[str, Any]], what: str, output: Path | None) -> None:
    """Print `room_variants`' rows as a table (setting `what`, none where 0) and write them as JSON to `output`."""
    teach = dev.params.teach
    print(f"| refit with | {what} | sequence-arg misses | successes | of programs |")
    print("|---|---:|---:|---:|---:|")
    for r in rows:
        refit = ("nothing (k = 0)" if r["refit_k"] == 0
                 else f"the first {r['refit_k']} tasks (teach.weight {teach.weight})")
        print(f"| {refit} | {'none' if r[what] == 0 else format(r[what], 'g')} | {r['misses']} | {r['successes']} | "
              f"{r['programs']} |")
    if output:
        write_json_atomic(output, {"dev_seeds": dev.seeds, "method": dev.shipped, "C": dev.C,
                                   "environments": list(teach.environments), "taught": max(teach.k),
                                   "weight": teach.weight, "rows": rows})


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--weights", type=int, nargs="+", default=[1, 3, 10, 30, 100, 300],
                        help="times a taught step counts, to try (default: 1 3 10 30 100 300)")
    add_dev_options(parser)
    args = parser.parse_args(argv)
    if any(w < 1 for w in args.weights):
        parser.error("--weights: every weight must be at least 1")
    dev = dev_setting(parser, args)
    params, seeds, shipped, make = dev.params, dev.seeds, dev.shipped, dev.make
    teach = params.teach
    benches = {}
    for seed in seeds:
        scenarios, _ = world_scenarios(Generate(seed, "procedural", params.procedural))
        benches[seed] = Benchmark.from_records(scenario_records(scenarios))
    print(f"the shipped planner ({shipped}, C = {dev.C:g}) on the drawn development worlds "
          f"{' '.join(map(str, seeds))}: rooms {' '.join(teach.environments)} held out, "
          f"k = {' '.join(map(str, teach.k))}", file=sys.stderr)
    rows, untaught = [], []
    for weight in args.weights:
        programs = [p for seed in seeds for p in teach_world(seed, benches[seed], replace(teach, weight=weight), make,
                                                             params.crossval.max_steps)]
        taught = [p for p in programs if p["k"] > 0]
        untaught = [p for p in programs if p["k"] == 0]
        rows.append({"weight": weight, **{f: 100.0 * statistics.fmean(p[f] for p in taught)
                                          for f in ("sequence_arg", "success")},
                     "misses": {str(seed): misses(programs, seed, teach.k) for seed in seeds}})
    ranked = rank(rows)
    zero = {f: 100.0 * statistics.fmean(p[f] for p in untaught) for f in ("sequence_arg", "success")}
    most = max(teach.k)
    print(f"| weight | sequence arg, k > 0 | success, k > 0 | misses at k = 0 -> k = {most} |")
    print("|---:|---:|---:|---:|")
    for r in ranked:
        mark = " (chosen)" if r is ranked[0] else ""
        before, after = (sum(m[i] for m in r["misses"].values()) for i in (0, 1))
        print(f"| {r['weight']}{mark} | {r['sequence_arg']:.1f} | {r['success']:.1f} | {before} -> {after} |")
    print(f"| nothing taught (k = 0) | {zero['sequence_arg']:.1f} | {zero['success']:.1f} | |")
    if args.output:
        write_json_atomic(args.output, {"dev_seeds": seeds, "method": shipped, "C": dev.C,
                                        "environments": list(teach.environments), "k": list(teach.k),
                                        "chosen": ranked[0]["weight"], "ranked": ranked, "untaught": zero})
    return 0


def misses(programs: list[dict], seed: int, ks: tuple[int, ...]) -> tuple[int, int]:
    """World `seed`'s programs not as demonstrated at k = the smallest and at k = the largest of `ks`."""
    return tuple(sum(1 - p["sequence_arg"] for p in programs if p["world_seed"] == seed and p["k"] == k)
                 for k in (min(ks), max(ks)))


if __name__ == "__main__":
    raise SystemExit(main())
