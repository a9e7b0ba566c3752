"""Check on the development world what the lookahead's stop at the goal changes.

The `lookahead` policy proposes `done` first once the task's goal holds, and
its imagined steps end there (`plan.planner.lookahead`, `stop_at_goal`). This
script runs the `teach` stage's protocol (`taskseq.stages.teach.teach_jobs`)
on the development world drawn as a world of drawn rooms (`world.dev_seed`,
never reported): the shipped planner, trained on the other rooms plus k
tasks a scripted person shows in each of `teach.environments`, judged on the
other tasks there. Each k's model is fitted once and its programs run with
the rule and without. It prints sequence arg, success and the misses of
sequence arg per k and rule, and the share of k = 0's misses that k removes;
docs/model.md shows the table this writes.

    python scripts/goal_stop.py --output reports/goal_stop.json

Run it after `dvc repro` has run `select` (the shipped planner and its C are read from reports/selection.json).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from taskseq.demonstrations.benchmark import Benchmark  # noqa: E402
from taskseq.demonstrations.records import scenario_records  # noqa: E402
from taskseq.experiments.crossval import judge  # noqa: E402
from taskseq.methods import Lineup  # noqa: E402
from taskseq.plan.planner import Memo, lookahead, run_loop  # noqa: E402
from taskseq.runtime.atomic import write_json_atomic  # noqa: E402
from taskseq.selection import read_selection  # noqa: E402
from taskseq.settings import Generate, Params  # noqa: E402
from taskseq.sim.scenarios import world_scenarios  # noqa: E402
from taskseq.stages import teach as stage  # noqa: E402

RULES = {"with": True, "without": False}  # the stop at the goal: as the policy has it, and taken away


def _both(seed, k, base, taught, scenarios, weight, make, max_steps) -> list[dict]:  # noqa: ARG001 (a job's args)
    """The `teach` stage's model for one k (`stage.taught_method`), its held-out programs run with the rule and
    without."""
    planner = stage.taught_method(k, base, taught, scenarios, weight, make).planner_
    rows = []
    for room in taught:
        for scenario in room.tested:
            row = {"k": k, "scenario": scenario.id}
            for rule, stops in RULES.items():
                policy = lookahead(planner, scenario.task, scenario.initial, stop_at_goal=stops)
                outcome = judge(scenario, run_loop(policy, scenario.initial, scenario.task, max_steps, memo=Memo()))
                row[rule] = {"arg": outcome.arg_correct, "success": outcome.success, "status": outcome.status,
                             "actions": list(outcome.actions)}
            rows.append(row)
    return rows


def summary(rows: list[dict], ks: list[int]) -> list[dict]:
    """Per rule and k: % sequence arg and success, the misses of sequence arg, the share of the first k's
    (`teach.k`'s first, 0 in params.yaml) that k removes."""
    out = []
    for rule in RULES:
        zero = sum(not r[rule]["arg"] for r in rows if r["k"] == ks[0])
        for k in ks:
            mine = [r[rule] for r in rows if r["k"] == k]
            misses = sum(not o["arg"] for o in mine)
            out.append({"rule": rule, "k": k, "programs": len(mine),
                        "sequence_arg": 100.0 * sum(o["arg"] for o in mine) / len(mine),
                        "success": 100.0 * sum(o["success"] for o in mine) / len(mine), "misses": misses,
                        "misses_removed": 100.0 * (zero - misses) / zero if zero else 0.0, "against_k": ks[0]})
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--selection", type=Path, default=ROOT / "reports" / "selection.json",
                        help="the shipped planner and its C (default: reports/selection.json)")
    parser.add_argument("--params", type=Path, default=ROOT / "params.yaml")
    parser.add_argument("--output", type=Path, help="also write the table and every program that differs as JSON")
    args = parser.parse_args(argv)
    params = Params.load(args.params)
    teach, world = params.teach, params.world
    selection = read_selection(args.selection)
    shipped = selection.method
    if shipped is None:
        parser.error(f"{args.selection}: names no method ranked first; run `taskseq select` again")
    make = Lineup(params.methods, selection, params.train.learner, procedural=params.procedural).mrf([shipped])[shipped]
    if make().policy != "lookahead":
        parser.error(f"the shipped planner {shipped} does not use the lookahead policy: the rule does not apply")
    scenarios, _ = world_scenarios(Generate(world.dev_seed, "procedural", params.procedural))
    bench = Benchmark.from_records(scenario_records(scenarios))
    print(f"the shipped planner ({shipped}, C = {selection.of(shipped):g}) on the drawn development world "
          f"{world.dev_seed}: rooms {' '.join(teach.environments)} held out, k = {' '.join(map(str, teach.k))}, "
          f"each taught step counted {teach.weight} times", file=sys.stderr)
    rows = [row for job, job_args in stage.teach_jobs(world.dev_seed, bench, teach, make, params.crossval.max_steps)
            for row in _both(*job_args)]
    table = summary(rows, list(teach.k))
    print(f"| rule | k | sequence arg | success | misses | k = {teach.k[0]}'s misses removed |")
    print("|---|---:|---:|---:|---:|---:|")
    for r in table:
        print(f"| {r['rule']} | {r['k']} | {r['sequence_arg']:.1f} | {r['success']:.1f} | {r['misses']} | "
              f"{r['misses_removed']:.0f}% |")
    changed = [r for r in rows if r["with"]["actions"] != r["without"]["actions"]]
    print(f"{len(changed)} of {len(rows)} programs differ", file=sys.stderr)
    if args.output:
        write_json_atomic(args.output, {"dev_seed": world.dev_seed, "method": shipped, "C": selection.of(shipped),
                                        "environments": list(teach.environments), "k": list(teach.k),
                                        "weight": teach.weight, "table": table, "changed": changed})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
