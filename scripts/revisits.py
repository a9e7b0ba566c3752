"""Check on the development world what the lookahead's rule against loops changes.

The `lookahead` policy ranks again when its first proposal would close a
loop, leading back to a world the program was in with the same two steps
remembered (`without_revisits`, which `taskseq.plan.planner.run_loop`
calls): it takes the first of its best runnable candidates that leads out of
the loop and whose imagined steps break no rule. Without it, such a program
repeats itself until the step cap. This script
draws the development world (`world.dev_seed`, never reported) as a world
of drawn rooms with `--rooms` rooms, cross-validates every method whose
policy is `lookahead` with whole rooms held out (C from the selection file),
and runs each fold's programs twice, with the rule and
without, from the same fitted models. It prints the figures of both and every
program that differs; docs/model.md shows the table this writes.

    python scripts/revisits.py --rooms 52 --output reports/revisits.json

Run it after `dvc repro` has run `select` (C is read from reports/selection.json).
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from taskseq.demonstrations.benchmark import Benchmark  # noqa: E402
from taskseq.demonstrations.records import scenario_records  # noqa: E402
from taskseq.experiments.crossval import judge, scenario_folds, training_index  # noqa: E402
from taskseq.features.dataset import build_steps  # noqa: E402
from taskseq.methods import Lineup, specs  # noqa: E402
from taskseq.plan.planner import learned_policy, run_loop  # noqa: E402
from taskseq.runtime.atomic import write_json_atomic  # noqa: E402
from taskseq.runtime.jobs import run_jobs  # noqa: E402
from taskseq.selection import read_selection  # noqa: E402
from taskseq.settings import Generate, Params  # noqa: E402
from taskseq.sim.scenarios import world_scenarios  # noqa: E402

RULES = ("with", "without")  # the rule against revisits: as the policy declares it, and taken away


def _fold(make, contexts, meta, bench, test, max_steps) -> list[dict]:
    """One fold's model, fitted once; each test scenario's program with the rule and without."""
    index = training_index(meta, test)
    method = make().fit([contexts[i] for i in index], [meta[i] for i in index], bench.scenarios)
    rows = []
    for sid in sorted(test):
        scenario = bench.scenarios[sid]
        row = {"scenario": sid}
        for rule in RULES:
            policy = learned_policy(method.policy, method.planner_, scenario.task, scenario.initial)
            if rule == "without":
                policy = (lambda p: lambda ctx, state: p(ctx, state))(policy)  # the same ranking, no second ranking
            outcome = judge(scenario, run_loop(policy, scenario.initial, scenario.task, max_steps))
            row[rule] = {"arg": outcome.arg_correct, "success": outcome.success, "safe": outcome.safe,
                         "status": outcome.status, "actions": list(outcome.actions)}
        rows.append(row)
    return rows


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--rooms", type=int, default=52, help="rooms of the drawn development world (default: 52)")
    parser.add_argument("--selection", type=Path, default=ROOT / "reports" / "selection.json",
                        help="each method's C (default: reports/selection.json)")
    parser.add_argument("--params", type=Path, default=ROOT / "params.yaml")
    parser.add_argument("--output", type=Path, help="also write the table as JSON here")
    parser.add_argument("--n-jobs", type=int, default=2)
    args = parser.parse_args(argv)
    params = Params.load(args.params)
    c = params.crossval
    if args.rooms < c.folds:
        parser.error(f"--rooms: at least crossval.folds ({c.folds}), so that every fold holds out a room")
    lineup = Lineup(params.methods, read_selection(args.selection), params.train.learner,
                    procedural=params.procedural)
    methods = [name for name, _ in params.methods.entries if specs()[name].policy == "lookahead"]
    scenarios, _ = world_scenarios(Generate(params.world.dev_seed, "procedural",
                                            replace(params.procedural, environments=args.rooms)))
    records = scenario_records(scenarios)
    contexts, meta = build_steps(records)
    bench = Benchmark.from_records(records)
    folds = scenario_folds(bench.scenarios, c.folds, c.seed, "environment")
    print(f"{', '.join(methods)}: {c.folds} folds, rooms held out, on the development world {params.world.dev_seed} "
          f"drawn with {args.rooms} rooms ({len(bench.scenarios)} scenarios)", file=sys.stderr)
    parts = run_jobs([(_fold, (lineup.factory(name), contexts, meta, bench, test, c.max_steps))
                      for name in methods for test in folds], args.n_jobs)
    table, changed = [], []
    for k, name in enumerate(methods):
        rows = [row for part in parts[k * len(folds):(k + 1) * len(folds)] for row in part]
        for rule in RULES:
            table.append({"method": name, "rule": rule, "programs": len(rows),
                          "sequence_arg": round(100 * sum(r[rule]["arg"] for r in rows) / len(rows), 2),
                          "success": round(100 * sum(r[rule]["success"] for r in rows) / len(rows), 2),
                          "step_cap": sum(r[rule]["status"] == "step_cap" for r in rows),
                          "unsafe": sum(not r[rule]["safe"] for r in rows)})
        changed += [{"method": name, **r} for r in rows if r["with"]["actions"] != r["without"]["actions"]]
    print("| method | rule | sequence arg | success | programs at the step cap | unsafe programs |")
    print("|---|---|---:|---:|---:|---:|")
    for row in table:
        print(f"| {row['method']} | {row['rule']} | {row['sequence_arg']:.1f} | {row['success']:.1f} | "
              f"{row['step_cap']} | {row['unsafe']} |")
    for r in changed:
        print(f"{r['method']} {r['scenario']}: without {r['without']['status']} (success {r['without']['success']}),"
              f" with {r['with']['status']} (success {r['with']['success']})")
    print(f"{len(changed)} programs differ")
    if args.output:
        write_json_atomic(args.output, {"dev_seed": params.world.dev_seed, "rooms": args.rooms, "folds": c.folds,
                                        "table": table,
                                        "changed": changed})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
