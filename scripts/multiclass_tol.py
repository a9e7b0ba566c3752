"""Choose the multiclass baseline's stopping tolerance (`crossval.multiclass_tol`) on the development world.

The multiclass baseline is scikit-learn's Crammer-Singer `LinearSVC`: what it
reports is the primitive each held-out step gets, not its weights. Its
coordinate descent stops when the dual's projected gradient falls below `tol`;
at scikit-learn's default (1e-4) its fits were a sixth of a cross-validation's
time, and some stopped at the iteration cap before they reached it. This
script runs the fits of the development world's cross-validation folds at each
tolerance of a grid and compares their held-out predictions with those of the
tightest: the loosest tolerance whose predictions are all the same is the
choice, which goes into params.yaml by hand. docs/evaluation.md shows the
table this writes.

    python scripts/multiclass_tol.py --world data/dev --output reports/multiclass_tol.json

Run it after `dvc repro` has run `dev_world` (it reads the world's features and processed tables).
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from taskseq.demonstrations.benchmark import load_benchmark  # noqa: E402
from taskseq.evaluate.methods import MulticlassMethod  # noqa: E402
from taskseq.experiments.crossval import scenario_folds, training_index  # noqa: E402
from taskseq.features.dataset import read_features  # noqa: E402
from taskseq.runtime.atomic import write_json_atomic  # noqa: E402
from taskseq.settings import Params  # noqa: E402


def held_out_primitives(tol: float, C: float, contexts, meta, folds: list[set[str]]) -> tuple[list[int], float]:
    """Every step's primitive as predicted by the fit of the fold that holds it out, and the CPU seconds of the fits."""
    predictions = [-1] * len(contexts)
    seconds = 0.0
    for test in folds:
        train = training_index(meta, test)
        held_out = [i for i, m in enumerate(meta) if m.scenario_id in test]
        start = time.process_time()
        method = MulticlassMethod(C=C, tol=tol).fit([contexts[i] for i in train], [meta[i] for i in train])
        seconds += time.process_time() - start
        for i, (prim, _, _) in zip(held_out, method.predict_steps([contexts[i] for i in held_out]), strict=True):
            predictions[i] = prim
    return predictions, seconds


def choose(rows: list[dict]) -> float:
    """The loosest tolerance whose predictions, and those of every tighter one, all equal the tightest's."""
    chosen = None
    for row in sorted(rows, key=lambda r: r["tol"]):
        if row["differ_from_tightest"]:
            break
        chosen = row["tol"]
    return chosen


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--world", type=Path, default=ROOT / "data" / "dev",
                        help="a world folder with features/ and processed/ (default: data/dev, the development world)")
    parser.add_argument("--tols", type=float, nargs="+", default=[1e-4, 1e-3, 1e-2, 1e-1],
                        help="tolerances to try, the tightest is the reference (default: 1e-4 1e-3 1e-2 1e-1)")
    parser.add_argument("--params", type=Path, default=ROOT / "params.yaml")
    parser.add_argument("--output", type=Path, help="also write the table as JSON here")
    args = parser.parse_args(argv)
    if not all(math.isfinite(t) and t > 0 for t in args.tols):
        parser.error("--tols: every tolerance must be a number above 0")
    for part in ("features", "processed"):
        if not (args.world / part).is_dir():
            parser.error(f"--world: {args.world / part} is not a folder (`dvc repro dev_world` writes data/dev)")
    c = Params.load(args.params).crossval
    contexts, meta = read_features(args.world / "features")
    folds = scenario_folds(load_benchmark(args.world / "processed").scenarios, c.folds, c.seed, c.group_by)
    gold = [x.gold[0] for x in contexts]
    rows, reference = [], None
    for tol in sorted(args.tols):
        predictions, seconds = held_out_primitives(tol, c.multiclass_C, contexts, meta, folds)
        if reference is None:
            reference = predictions
        rows.append({"tol": tol, "cpu_seconds": round(seconds, 2),
                     "avg_prim": round(100 * sum(p == g for p, g in zip(predictions, gold, strict=True)) / len(gold),
                                       2),
                     "differ_from_tightest": sum(p != r for p, r in zip(predictions, reference, strict=True))})
        print(f"tol {tol:g}: {seconds:6.2f} CPU-s, avg prim {rows[-1]['avg_prim']:.2f}, "
              f"{rows[-1]['differ_from_tightest']} of {len(gold)} held-out steps differ from the tightest")
    chosen = choose(rows)
    print(f"chosen: crossval.multiclass_tol = {chosen:g} (params.yaml has {c.multiclass_tol:g})")
    if args.output:
        world = args.world.resolve()
        shown = world.relative_to(ROOT) if world.is_relative_to(ROOT) else world
        write_json_atomic(args.output, {"world": str(shown), "C": c.multiclass_C, "steps": len(gold),
                                        "chosen": chosen, "rows": rows})
    return 0


if __name__ == "__main__":
    sys.exit(main())
