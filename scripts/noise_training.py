"""Choose the noisy-training settings of `ours + relations + noisy training` on the development world.

The method (`taskseq/methods/noise_trained.py`) adds copies of its training
steps with binary attributes flipped. How many copies and how often to flip
are its free settings; this script cross-validates every pair of a grid on
the development world that the `dev_world` stage draws (`data/dev`, never
reported), runs each fold's model under the `noise` stage's conditions (its
rates, draws and seed from params.yaml), and ranks the pairs by the mean
sequence arg over those rates (the area under the noise curve), then by the
mean success, then fewer copies, then the lower flip rate. The chosen pair
goes into params.yaml by hand (`methods.noise_trained`: `noise_rate`, `noise_copies`);
docs/model.md shows the table this prints.

    python scripts/noise_training.py --flip-rates 0.05 0.1 0.2 --copies 1 2 3

Run it after `dvc repro` has run `dev_world` and `select` (it reads data/dev and C from reports/selection.json).
"""

from __future__ import annotations

import argparse
import sys
from functools import partial
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from taskseq.demonstrations.benchmark import load_benchmark  # noqa: E402
from taskseq.evaluate.methods import ScorerMethod  # noqa: E402
from taskseq.experiments.robustness import NoiseCondition, evaluate_conditions, noise_curve, noise_runs  # noqa: E402
from taskseq.features.dataset import read_features  # noqa: E402
from taskseq.selection import read_selection  # noqa: E402
from taskseq.settings import Params  # noqa: E402


def rank(rows: list[dict[str, float]]) -> list[dict[str, float]]:
    """Best first: mean sequence arg over the noise rates, then mean success, then fewer copies, lower rate."""
    return sorted(rows, key=lambda r: (-round(r["mean_arg"], 9), -round(r["mean_success"], 9), r["copies"],
                                       r["flip_rate"]))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--flip-rates", type=float, nargs="+", default=[0.05, 0.1, 0.2],
                        help="training flip rates to try (default: 0.05 0.1 0.2)")
    parser.add_argument("--copies", type=int, nargs="+", default=[1, 2, 3],
                        help="numbers of noisy copies to try (default: 1 2 3)")
    parser.add_argument("--data", type=Path, default=ROOT / "data" / "dev",
                        help="the development world's folder as `select` writes it (default: data/dev)")
    parser.add_argument("--selection", type=Path, default=ROOT / "reports" / "selection.json",
                        help="C is the relations model's C there (default: reports/selection.json)")
    parser.add_argument("--params", type=Path, default=ROOT / "params.yaml")
    parser.add_argument("--n-jobs", type=int, default=2)
    args = parser.parse_args(argv)
    if any(not 0.0 < r <= 1.0 for r in args.flip_rates) or any(c < 1 for c in args.copies):
        parser.error("flip rates must be within (0, 1] and copies at least 1")
    params = Params.load(args.params)
    noise, crossval = params.noise, params.crossval
    C = read_selection(args.selection).of("relations")
    contexts, meta = read_features(args.data / "features")
    bench = load_benchmark(args.data / "processed")
    relations = partial(ScorerMethod, features="relations", C=C, tol=params.train.tol, max_iter=params.train.max_iter,
                        n_slacks=params.train.n_slacks)
    settings = {f"{r:g}x{c}": (r, c) for r in args.flip_rates for c in args.copies} | {"none": (0.0, 0)}
    makes = {name: partial(relations, noise_rate=r, noise_copies=c, name=name) for name, (r, c) in settings.items()}
    conditions = [NoiseCondition(r, d) for r in noise.rates for d in range(noise.draws)]
    print(f"{len(makes)} settings x {crossval.folds} folds on the development world ({len(bench.scenarios)} "
          f"scenarios), relations at C = {C:g}, noise rates {' '.join(f'{r:g}' for r in noise.rates)}, "
          f"{noise.draws} draws", file=sys.stderr)
    outcomes = evaluate_conditions(makes, contexts, meta, bench.scenarios, conditions, crossval.fold_settings,
                                   crossval.max_steps, noise.seed, args.n_jobs)
    rows = []
    for name, results in outcomes.items():
        curve = noise_curve(noise, noise_runs(noise, results))
        rate, copies = settings[name]
        rows.append({"flip_rate": rate, "copies": copies, **{f"arg@{p['rate']:g}": p["sequence_arg"] for p in curve},
                     "mean_arg": float(np.mean([p["sequence_arg"] for p in curve])),
                     "mean_success": float(np.mean([p["success"] for p in curve]))})
    ranked = rank([r for r in rows if r["copies"]])
    heads = [f"seq arg at {r:g}" for r in noise.rates]
    print("| flip rate | copies | " + " | ".join(heads) + " | mean | mean success |")
    print("|---:|---:|" + "---:|" * (len(heads) + 2))
    for r in [*ranked, *[r for r in rows if not r["copies"]]]:
        cells = " | ".join(f"{r[f'arg@{p:g}']:.1f}" for p in noise.rates)
        mark = " (chosen)" if r is ranked[0] else ""
        label = "none" if not r["copies"] else f"{r['flip_rate']:g}"
        print(f"| {label}{mark} | {r['copies']} | {cells} | {r['mean_arg']:.1f} | {r['mean_success']:.1f} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
