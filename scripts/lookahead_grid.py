"""Choose the safety lookahead's depth and width on the development world.

The `lookahead` policy (`taskseq.plan.planner.lookahead`) takes, of the
`width` best runnable steps, the first whose next `depth` imagined steps
break no safety rule. Both are free settings; this script cross-validates the
choice-cue models (`ours + relations + choice cues`, C from the selection
file) on the development world that the `dev_world` stage draws (`data/dev`,
never reported), runs every fold's programs with each (depth, width) of the
grid, and ranks them by sequence arg, then success, then the shorter depth,
then the smaller width. The chosen pair is written into
`taskseq/plan/planner.py` by hand (`LOOKAHEAD_DEPTH`, `LOOKAHEAD_WIDTH`);
docs/model.md shows the table this prints.

    python scripts/lookahead_grid.py --depths 2 4 6 8 12 --widths 2 3 5

Run it after `dvc repro` has run `dev_world` and `select` (it reads data/dev and C from reports/selection.json).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from dataclasses import dataclass
from functools import partial
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from taskseq.demonstrations.benchmark import load_benchmark  # noqa: E402
from taskseq.evaluate.methods import ScorerMethod  # noqa: E402
from taskseq.evaluate.metrics import summarize  # noqa: E402
from taskseq.experiments.crossval import cross_validate  # noqa: E402
from taskseq.features.dataset import read_features  # noqa: E402
from taskseq.plan.planner import Policy, lookahead  # noqa: E402
from taskseq.selection import read_selection  # noqa: E402
from taskseq.settings import Params  # noqa: E402
from taskseq.sim.scenarios import Scenario  # noqa: E402


@dataclass
class LookaheadAt(ScorerMethod):
    """The choice-cue method with the lookahead at a depth and width of the grid (the stored models are shared:
    neither changes a weight)."""

    depth: int = 4
    width: int = 3

    def policy_for(self, scenario: Scenario) -> Policy:
        return lookahead(self.planner_, scenario.task, scenario.initial, depth=self.depth, width=self.width)


def rank(rows: list[dict[str, float]]) -> list[dict[str, float]]:
    """Best first: sequence arg, then success, then the shorter depth, then the smaller width."""
    return sorted(rows, key=lambda r: (-round(r["sequence_arg"], 9), -round(r["success"], 9), r["depth"], r["width"]))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--depths", type=int, nargs="+", default=[2, 4, 6, 8, 12],
                        help="imagined steps after a candidate to try (default: 2 4 6 8 12)")
    parser.add_argument("--widths", type=int, nargs="+", default=[2, 3, 5],
                        help="best runnable candidates to check (default: 2 3 5)")
    parser.add_argument("--data", type=Path, default=ROOT / "data" / "dev",
                        help="the development world's folder as `select` writes it (default: data/dev)")
    parser.add_argument("--selection", type=Path, default=ROOT / "reports" / "selection.json",
                        help="C is the lookahead method's C there (default: reports/selection.json)")
    parser.add_argument("--params", type=Path, default=ROOT / "params.yaml")
    parser.add_argument("--n-jobs", type=int, default=2)
    args = parser.parse_args(argv)
    if any(d < 1 for d in args.depths) or any(w < 1 for w in args.widths):
        parser.error("depths and widths must be at least 1")
    params = Params.load(args.params)
    crossval = params.crossval
    C = read_selection(args.selection).of("choice_lookahead")
    learner = {"tol": params.train.tol, "max_iter": params.train.max_iter, "n_slacks": params.train.n_slacks}
    contexts, meta = read_features(args.data / "features")
    bench = load_benchmark(args.data / "processed")
    grid = {f"{d}x{w}": (d, w) for d in args.depths for w in args.widths}
    with tempfile.TemporaryDirectory() as store:  # the six fold models, fitted once for every pair
        base = partial(LookaheadAt, features="choice", policy="lookahead", store=store,
                       C=C, **learner)
        makes = {"feasible": partial(ScorerMethod, features="choice", policy="feasible", store=store, name="feasible",
                                     C=C, **learner)}
        makes |= {name: partial(base, depth=d, width=w, name=name) for name, (d, w) in grid.items()}
        print(f"{len(grid)} (depth, width) pairs x {crossval.folds} folds on the development world "
              f"({len(bench.scenarios)} scenarios), choice cues at C = {C:g}", file=sys.stderr)
        fold = (crossval.folds, crossval.seed, crossval.group_by, crossval.max_steps, args.n_jobs)
        # the feasible steps first: their fits fill the store before the pairs share it
        results = cross_validate({"feasible": makes.pop("feasible")}, contexts, meta, bench, *fold)
        results += cross_validate(makes, contexts, meta, bench, *fold)
    summary = summarize(results, contexts, dict.fromkeys(["feasible", *makes], True))
    rows = [{"depth": d, "width": w, "sequence_arg": summary[name]["sequence/arg"],
             "success": summary[name]["success"]} for name, (d, w) in grid.items()]
    ranked = rank(rows)
    print("| depth | width | sequence arg | success |")
    print("|---:|---:|---:|---:|")
    for r in ranked:
        mark = " (chosen)" if r is ranked[0] else ""
        print(f"| {r['depth']}{mark} | {r['width']} | {r['sequence_arg']:.1f} | {r['success']:.1f} |")
    base_row = summary["feasible"]
    print(f"| no lookahead (feasible steps) | - | {base_row['sequence/arg']:.1f} | {base_row['success']:.1f} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
