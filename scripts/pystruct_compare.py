"""Time this project's learner against pystruct's `OneSlackSSVM` on the same model, data and objective.

pystruct is not a dependency (it does not install with NumPy 2), so this
script runs it from its source: a checkout of https://github.com/pystruct/pystruct
with `np.float`, `np.int` and `np.bool` replaced by the builtins (the only change
it needs; none of its compiled parts are used), and cvxopt installed in the
environment. Both learners fit the full `StepMRF` model on all 886 steps of world 0
(`data/worlds/0/processed`, written by `dvc repro`) at C = 3, the objective
`0.5 ||w||^2 + C sum_i xi_i`:

- pystruct: `OneSlackSSVM(model, C=3, tol, inference_cache=0, n_jobs=1)`, timed
  to its own stop, at each of `--tols`;
- this learner: `StepScorer("full", C=3, tol=1e-4, max_iter=2000, n_slacks=0)`, timed to the first
  iteration whose objective is as low as pystruct's final one at that tolerance
  (`history_[k].seconds`).

Both final weights are scored by one function, `0.5 w.w + C * sum_i max_y [loss +
w.psi(x_i, y) - w.psi(x_i, y_i)]`, with the project's exact oracle. Every fit is
one fresh process (BLAS at one thread, the fit cache off, each learner run once
on a few steps before its clock starts, so Numba's kernels and cvxopt are
loaded); the learners alternate, `--per-run` fits of this learner after each
of pystruct's. `--before DIR` times another checkout of this project beside
(its learner on the same data, labelled `before`; `git worktree add
../taskseq-before <commit>` makes one). Every measurement is appended to
`--output` (JSON lines, each with the run's id, so runs into one file stay
apart); the table printed at the end is the one docs/speed.md shows:

    python -m venv /tmp/pystruct-env && /tmp/pystruct-env/bin/pip install -c requirements.lock -e . cvxopt
    /tmp/pystruct-env/bin/python scripts/pystruct_compare.py --pystruct ~/src/pystruct --rounds 9 \\
        --before ../taskseq-before --output /tmp/pystruct.jsonl
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
C = 3.0
WARM_STEPS = 30  # the fit each process makes before its clock starts
THIS = "taskseq"


class StepMRFModel:
    """pystruct's model protocol over `StepMRF`, as much of it as `OneSlackSSVM` calls (no inference cache, one job):
    labellings are handed to pystruct as int arrays, since its final objective takes another path for tuples."""

    def __init__(self) -> None:
        from taskseq.learn.mrf import StepMRF

        self.mrf = StepMRF("full")
        self.size_joint_feature = self.mrf.size_joint_feature

    def initialize(self, X, Y) -> None:
        pass

    def joint_feature(self, x, y):
        return self.mrf.joint_feature(x, tuple(int(v) for v in y))

    def batch_joint_feature(self, X, Y, Y_true=None):
        import numpy as np

        return np.asarray(self.mrf.batch_joint_feature_rows(X, Y).sum(axis=0)).ravel()  # pystruct sums them

    def loss(self, y, y_hat) -> float:
        return self.mrf.loss(tuple(int(v) for v in y), tuple(int(v) for v in y_hat))

    def batch_loss(self, Y, Y_hat):
        return self.mrf.batch_loss(Y, Y_hat)

    def max_loss(self, y) -> float:
        return 3.0

    def inference(self, x, w, relaxed=None, constraints=None):
        import numpy as np

        return np.array(self.mrf.inference(x, w), dtype=np.int64)

    def batch_inference(self, X, w, relaxed=None, constraints=None):
        import numpy as np

        return np.asarray(self.mrf.batch_inference(X, w), dtype=np.int64)

    def loss_augmented_inference(self, x, y, w, relaxed=None):
        import numpy as np

        return np.array(self.mrf.loss_augmented_inference(x, tuple(int(v) for v in y), w), dtype=np.int64)

    def batch_loss_augmented_inference(self, X, Y, w, relaxed=None):
        return self.mrf.batch_loss_augmented_inference(X, Y, w)


def objective(X, Y, w) -> float:
    """The SSVM objective at `w`, the max over labellings by the project's exact oracle: one scorer for both."""
    import numpy as np

    from taskseq.learn.mrf import StepMRF

    mrf, Y = StepMRF("full"), np.asarray(Y, dtype=np.int64)
    Y_hat = mrf.batch_loss_augmented_inference(X, Y, w)
    slack = mrf.batch_loss(Y, Y_hat) - (mrf.batch_joint_feature_rows(X, Y) - mrf.batch_joint_feature_rows(X, Y_hat)) @ w
    return float(0.5 * np.dot(w, w) + C * np.maximum(slack, 0.0).sum())


def one_fit(learner: str, tol: float, target: float | None) -> dict:
    """One timed fit in this process (the child's work)."""
    from threadpoolctl import threadpool_limits

    from taskseq.demonstrations.benchmark import load_benchmark
    from taskseq.features.dataset import build_steps
    from taskseq.learn.estimator import StepScorer
    from taskseq.runtime.cache import disabled

    X = build_steps(load_benchmark(ROOT / "data/worlds/0/processed").records)[0]
    Y = [x.gold for x in X]

    def fit(X, Y):
        if learner == "pystruct":
            from pystruct.learners.one_slack_ssvm import OneSlackSSVM

            return OneSlackSSVM(StepMRFModel(), C=C, tol=tol, inference_cache=0, n_jobs=1, verbose=0).fit(X, Y)
        return StepScorer("full", C=C, tol=1e-4, max_iter=2000, n_slacks=0).fit(X, Y)

    with threadpool_limits(limits=1), disabled():
        fit(X[:WARM_STEPS], Y[:WARM_STEPS])
        start = time.perf_counter()
        fitted = fit(X, Y)
        seconds = time.perf_counter() - start
        w = fitted.w if learner == "pystruct" else fitted.w_
        row = {"tol": tol, "seconds": seconds, "objective": objective(X, Y, w)}
    if learner == "pystruct":
        row["iterations"] = len(fitted.objective_curve_) - 1  # the curve ends with the objective after its loop
    else:
        reached = next((h for h in fitted.ssvm_.history_ if target is not None and h.best_primal <= target), None)
        row.update(reach_seconds=None if reached is None else reached.seconds,
                   reach_iteration=None if reached is None else reached.iteration, iterations=fitted.ssvm_.n_iter_)
    return row


def _positive(text: str) -> int:
    value = int(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be at least 1, got {value}")
    return value


def _measure(learner: str, label: str, tol: float, target: float | None, pythonpath: list[str]) -> dict:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(pythonpath), "OMP_NUM_THREADS": "1",
           "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
    env.pop("TASKSEQ_CACHE", None)
    args = [sys.executable, __file__, "--one", learner, "--tol", repr(tol)]
    if target is not None:
        args += ["--target", repr(target)]
    out = subprocess.run(args, env=env, capture_output=True, text=True, cwd=ROOT)
    if out.returncode:
        raise SystemExit(f"a {label} fit failed:\n{out.stderr}")
    return {"learner": label, **json.loads(out.stdout.strip().splitlines()[-1])}


def summary(rows: list[dict]) -> str:
    """Per tolerance: pystruct's iterations, objective and time to its stop; each learner's time to reach that
    objective; the ratio of the medians and its range over the runs."""
    lines = ["| pystruct tolerance | its iterations | its objective | learner | runs | seconds, min to max | median "
             "| pystruct's median over it | min to max |", "|---|---:|---:|---|---:|---|---:|---:|---|"]
    for tol in sorted({r["tol"] for r in rows}):
        theirs = [r for r in rows if r["tol"] == tol and r["learner"] == "pystruct"]
        if not theirs:
            continue
        p = [r["seconds"] for r in theirs]
        its = "/".join(sorted({str(r["iterations"]) for r in theirs}))
        obj = "/".join(sorted({f"{r['objective']:.4f}" for r in theirs}))
        lines.append(f"| {tol:.0e} | {its} | {obj} | pystruct | {len(p)} | {min(p):.2f} to {max(p):.2f} | "
                     f"{statistics.median(p):.2f} | | |")
        for label in sorted({r["learner"] for r in rows} - {"pystruct"}):
            q = [r["reach_seconds"] for r in rows if r["tol"] == tol and r["learner"] == label
                 and r["reach_seconds"] is not None]
            if q:
                lines.append(f"| | | | {label} | {len(q)} | {min(q):.2f} to {max(q):.2f} | {statistics.median(q):.2f} "
                             f"| {statistics.median(p) / statistics.median(q):.1f} | {min(p) / max(q):.1f} to "
                             f"{max(p) / min(q):.1f} |")
    return "\n".join(lines)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--pystruct", type=Path, help="folder of pystruct's source (holding the `pystruct` package)")
    parser.add_argument("--tols", type=float, nargs="+", default=[1e-4, 1e-3],
                        help="pystruct's tolerances (default 1e-4 1e-3)")
    parser.add_argument("--rounds", type=_positive, default=3, help="rounds: each tolerance once per round (default 3)")
    parser.add_argument("--per-run", type=_positive, default=2,
                        help="this learner's fits after each of pystruct's (default 2)")
    parser.add_argument("--before", type=Path, help="another checkout of this project, timed beside as `before`")
    parser.add_argument("--output", type=Path, help="JSON lines, one per fit, appended to (required)")
    parser.add_argument("--one", choices=("pystruct", THIS), help=argparse.SUPPRESS)  # a child's single fit
    parser.add_argument("--tol", type=float, help=argparse.SUPPRESS)
    parser.add_argument("--target", type=float, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.one:
        print(json.dumps(one_fit(args.one, args.tol, args.target)))
        return 0
    if args.output is None:
        parser.error("--output is required: the file the measurements are appended to")
    if args.pystruct is None or not (args.pystruct / "pystruct" / "learners" / "one_slack_ssvm.py").is_file():
        parser.error("--pystruct must name a folder holding pystruct's source (pystruct/learners/one_slack_ssvm.py)")
    if args.before is not None and not (args.before / "taskseq" / "__init__.py").is_file():
        parser.error(f"--before {args.before}: holds no `taskseq` package (a checkout of this project: "
                     "`git worktree add ../taskseq-before <commit>`)")
    if not (ROOT / "data/worlds/0/processed").is_dir():
        parser.error("data/worlds/0/processed is missing: run `dvc repro` first")
    if not args.output.parent.is_dir():
        parser.error(f"--output {args.output}: its folder does not exist")
    run = time.strftime("%Y%m%dT%H%M%S")  # the id of this run's rows in --output
    ours = [str(ROOT), str(args.pystruct.resolve())]
    rows = []
    for r in range(args.rounds):
        for tol in args.tols:
            theirs = _measure("pystruct", "pystruct", tol, None, ours)
            batch = [theirs]
            for _ in range(args.per_run):
                batch.append(_measure(THIS, "this learner", tol, theirs["objective"], ours))
                if args.before:
                    batch.append(_measure(THIS, "before", tol, theirs["objective"],
                                          [str(args.before.resolve()), str(args.pystruct.resolve())]))
            with args.output.open("a") as f:
                f.writelines(json.dumps({"run": run, "round": r, **row}) + "\n" for row in batch)
            rows += batch
            print(f"round {r + 1}/{args.rounds}, pystruct at {tol:g}: {theirs['seconds']:.2f} s", flush=True)
    print(summary(rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
