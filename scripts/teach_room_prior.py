"""Measure a room prior for teaching on drawn development worlds: does favouring the taught objects pay?

The `teach` stage lets a room's k demonstrations weigh by counting each taught
step `teach.weight` times in a refit. A person teaches their room's ways
(which bin, which cup, which spoon), so another way to let them weigh is a
prior: in a taught room, every candidate step that uses an object in the
position a taught step used it (`grasp` of this mug, `place_above` onto this
table) gets `beta` added to its score for each such use, for every task of the room, with or
without the refit. This script measures that on the teach protocol
(`taskseq.stages.teach`: the rooms `teach.environments` held out, the first
max(`teach.k`) tasks of each taught, every other task judged) for each beta of a grid,
on development draws only (`world.dev_seed` by default; `--dev-seeds` adds
others, never a reported one), and prints the sequence-arg misses and the
successes pooled over the draws, against the planner without the prior.
docs/teach.md shows the table this writes:

    python scripts/teach_room_prior.py --betas 0.25 0.5 1 2 --dev-seeds 100 101 102 103 104 \
        --output reports/teach_room_prior.json

Run it after `dvc repro` has run `select` (the shipped planner and its C are read from reports/selection.json).
"""

from __future__ import annotations

import argparse
import itertools
import sys
from collections.abc import Iterator
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "scripts"))  # the teach protocol's options and checks, as teach_weight.py has them

from teach_weight import add_dev_options, dev_setting  # noqa: E402

from taskseq.demonstrations.benchmark import Benchmark  # noqa: E402
from taskseq.demonstrations.records import scenario_records  # noqa: E402
from taskseq.experiments.crossval import judge  # noqa: E402
from taskseq.experiments.teaching import Taught  # noqa: E402
from taskseq.features.context import StepContext  # noqa: E402
from taskseq.learn.estimator import StepScorer  # noqa: E402
from taskseq.runtime.atomic import write_json_atomic  # noqa: E402
from taskseq.settings import Generate  # noqa: E402
from taskseq.sim.primitives import ALL_PRIMITIVES  # noqa: E402
from taskseq.sim.scenarios import world_scenarios  # noqa: E402
from taskseq.stages.teach import taught_method, teach_jobs  # noqa: E402

Use = tuple[str, int, str]  # (primitive, argument position, object id) of a taught step


class RoomPrior:
    """A fitted scorer whose candidates that use an object as a taught step did score `beta` more per such use;
    it ranks as `StepScorer.ranked` does (ties: the earlier candidate first), which is all a policy asks of it."""

    def __init__(self, scorer: StepScorer, uses: set[Use], beta: float) -> None:
        self.scorer, self.uses, self.beta = scorer, uses, beta

    def scores(self, x: StepContext) -> tuple[tuple[np.ndarray, np.ndarray, np.ndarray], np.ndarray]:
        (cp, ca1, ca2), s = self.scorer.model_.scores(x, self.scorer.w_)
        position = {o: i for i, o in enumerate(x.object_ids)}
        bonus = np.zeros(len(s))
        for primitive, k, obj in self.uses:
            if obj in position:
                bonus += (cp == ALL_PRIMITIVES.index(primitive)) & ((ca1, ca2)[k] == position[obj])
        return (cp, ca1, ca2), s + self.beta * bonus

    def ranked(self, x: StepContext) -> Iterator[tuple[tuple[int, int, int], float]]:
        (cp, ca1, ca2), s = self.scores(x)
        for i in np.argsort(-s, kind="stable"):
            yield (int(cp[i]), int(ca1[i]), int(ca2[i])), float(s[i])

    def top_k(self, x: StepContext, k: int) -> list[tuple[tuple[int, int, int], float]]:
        return list(itertools.islice(self.ranked(x), k))


def taught_uses(room: Taught, k: int) -> set[Use]:
    """Every (primitive, position, object) of the first k tasks a person shows in `room`."""
    return {(a.primitive, i, obj) for _, actions in room.shown[:k] for a in actions for i, obj in enumerate(a.args)}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--betas", type=float, nargs="+", default=[0.25, 0.5, 1.0, 2.0],
                        help="score added per taught use, to try (default: 0.25 0.5 1 2); 0, no prior, is always "
                             "run too, as what the others are compared with")
    add_dev_options(parser)
    args = parser.parse_args(argv)
    if any(b < 0 for b in args.betas):
        parser.error("--betas: a prior favours the taught objects, so every beta must be at least 0")
    betas = sorted({0.0, *args.betas})
    dev = dev_setting(parser, args)
    params, make, teach = dev.params, dev.make, dev.params.teach
    most = max(teach.k)
    print(f"the shipped planner ({dev.shipped}, C = {dev.C:g}) on the drawn development worlds "
          f"{' '.join(map(str, dev.seeds))}: rooms {' '.join(teach.environments)} held out, the first {most} tasks "
          f"of each taught", file=sys.stderr)
    counts: dict[tuple[int, float], list[int]] = {}  # (k of the refit, beta) -> [programs, as demonstrated, success]
    for seed in dev.seeds:
        scenarios, _ = world_scenarios(Generate(seed, "procedural", params.procedural))
        bench = Benchmark.from_records(scenario_records(scenarios))
        _, (_, _, base, rooms, known, weight, _, max_steps) = teach_jobs(seed, bench, teach, make,
                                                                        params.crossval.max_steps)[0]
        for k in (0, most):  # the planner without the refit, and refitted with the taught steps as `teach` does
            method = taught_method(k, base, rooms, known, weight, make)
            fitted = method.planner_
            for beta in betas:
                tally = counts.setdefault((k, beta), [0, 0, 0])
                for room in rooms:
                    method.planner_ = RoomPrior(fitted, taught_uses(room, most), beta)
                    for scenario in room.tested:
                        outcome = judge(scenario, method.run(scenario, max_steps))
                        tally[0] += 1
                        tally[1] += int(outcome.arg_correct)
                        tally[2] += int(outcome.success)
                print(f"world {seed}, refit with k = {k}, beta = {beta:g}: done", file=sys.stderr)
            method.planner_ = fitted
    rows = [{"refit_k": k, "beta": beta, "programs": n, "misses": n - arg, "successes": ok}
            for (k, beta), (n, arg, ok) in sorted(counts.items())]
    print("| refit with | beta | sequence-arg misses | successes | of programs |")
    print("|---|---:|---:|---:|---:|")
    for r in rows:
        refit = ("nothing (k = 0)" if r["refit_k"] == 0
                 else f"the first {r['refit_k']} tasks (teach.weight {teach.weight})")
        print(f"| {refit} | {r['beta']:g} | {r['misses']} | {r['successes']} | {r['programs']} |")
    if args.output:
        write_json_atomic(args.output, {"dev_seeds": dev.seeds, "method": dev.shipped, "C": dev.C,
                                        "environments": list(teach.environments), "taught": most,
                                        "weight": teach.weight, "rows": rows})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
