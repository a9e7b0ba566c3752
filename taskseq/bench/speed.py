"""`taskseq bench`: how long training and planning take on this machine.

Timings are measurements, not tests: they go to reports/bench.json and docs/speed.md.
"""

from __future__ import annotations

import resource
import statistics
import tempfile
import time
import tracemalloc
from pathlib import Path
from typing import Any

import numpy as np

from ..features.context import step_context
from ..features.dataset import build_steps, write_features
from ..learn.estimator import StepScorer
from ..runtime.cache import disabled
from ..sim.catalog import OBJECTS
from ..sim.objects import ObjectSpec
from ..sim.state import ON, WorldState
from ..sim.tasks import Task
from .machine import machine

SIZES = (10, 15, 25, 50, 100)


def synthetic_world(n: int, seed: int = 0) -> tuple[WorldState, Task]:
    """A floor, a long table and n-2 catalog items with fresh ids, for timing only."""
    rng = np.random.default_rng(seed)
    floor, table = OBJECTS[0], OBJECTS[5]
    specs = {floor.id: floor, table.id: table}
    poses = {floor.id: (0.0, 0.0, -floor.h), table.id: (0.0, table.l / 2, 0.0)}
    support = {table.id: (floor.id, ON)}
    movable = [o for o in OBJECTS if o.has("movable") and not o.has("liquid")]
    for k in range(n - 2):
        base = movable[int(rng.integers(len(movable)))]
        spec = ObjectSpec(f"x{k:03d}", base.name, base.category, base.size, base.flags, base.levels)
        specs[spec.id] = spec
        poses[spec.id] = (float(rng.uniform(-4, 4)), float(rng.uniform(-3, -0.5)), 0.0)
        support[spec.id] = (floor.id, ON)
    state = WorldState(specs, poses, support, robot=(0.0, -1.5))
    return state, Task("pick_and_place", ("x000", table.id))


def _train_row(contexts: list, features: str, C: float, tol: float, max_iter: int, n_slacks: int,
               progress: bool) -> tuple[dict[str, Any], StepScorer]:
    planner = StepScorer(features, C=C, tol=tol, max_iter=max_iter, n_slacks=n_slacks).fit(contexts, progress=progress)
    return {"features": features, "tol": tol, "n_slacks": n_slacks, **fit_summary(planner),
            "qp_steps": planner.ssvm_.n_qp_steps_}, planner


def fit_summary(planner: StepScorer) -> dict[str, Any]:
    """What a timed fit reports: its time, iterations, where the time went and the bounds it stopped at."""
    ssvm = planner.ssvm_
    return {
        "seconds": planner.fit_seconds_,
        "iterations": ssvm.n_iter_,
        "converged": bool(ssvm.converged_),
        "oracle_share": ssvm.seconds_oracle_ / planner.fit_seconds_,
        "qp_share": ssvm.seconds_qp_ / planner.fit_seconds_,
        "primal_objective": ssvm.primal_objective_,
        "dual_objective": ssvm.dual_objective_,
    }


@disabled()  # a fit read from the cache would time nothing
def run_bench(records: list[dict[str, Any]], C: float, tol: float, max_iter: int, n_slacks: int = 0,
              repeats: int = 50, progress: bool = True, gaps: tuple[float, ...] = (1e-3, 1e-4),
              reference_gap: float = 1e-5, relations: bool = True) -> dict[str, Any]:
    """Training to each relative gap in `gaps` (with `n_slacks` and the classic 1-slack), per-step latency.

    The full model's objectives are set against a reference solve of the same
    problem to `reference_gap`: its dual objective is a certified lower bound
    on the optimum, and `excess`, how far an objective lies above it
    (relative), bounds that run's distance to the optimum from above. With
    `relations`, the relations model (the pipeline's heaviest fit) is timed
    at the configured gap too.
    """
    tracemalloc.start()
    with tempfile.TemporaryDirectory() as tmp:
        contexts, meta = build_steps(records)
        write_features(contexts, meta, Path(tmp) / "features")
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()

    rows, planner = [], None
    for gap in gaps:
        for slacks in dict.fromkeys((n_slacks, 1)):
            row, f = _train_row(contexts, "full", C, gap, max_iter, slacks, progress)
            rows.append(row)
            if gap == tol and slacks == n_slacks:
                planner = f
    if planner is None:  # the configured tolerance is none of `gaps`: train once more with it
        row, planner = _train_row(contexts, "full", C, tol, max_iter, n_slacks, progress)
        rows.append(row)
    reference, _ = _train_row(contexts, "full", C, reference_gap, max_iter, n_slacks, progress)
    bound = max([reference["dual_objective"]] + [r["dual_objective"] for r in rows])
    for r in rows:
        r["excess"] = (r["primal_objective"] - bound) / max(1.0, abs(bound))
    if relations:
        rows.append(_train_row(contexts, "relations", C, tol, max_iter, n_slacks, progress)[0])
    peak_rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024  # KiB on Linux
    latency = {}
    for n in SIZES:
        state, task = synthetic_world(n)
        ctx = step_context(state, task, [])
        planner.model_.inference(ctx, planner.w_)  # warm caches
        infer, step = [], []
        for _ in range(repeats):
            t0 = time.perf_counter()
            planner.model_.inference(ctx, planner.w_)
            t1 = time.perf_counter()
            planner.model_.inference(step_context(state, task, []), planner.w_)
            t2 = time.perf_counter()
            infer.append(t1 - t0)
            step.append(t2 - t1)
        latency[str(n)] = {
            "candidates": int(len(planner.model_.scores(ctx, planner.w_)[1])),
            "inference_ms": 1000 * statistics.median(infer),
            "step_ms": 1000 * statistics.median(step),
        }
    return {
        "machine": machine(),
        "train": {"steps": len(contexts), "C": C, "runs": rows, "lower_bound": bound,
                  "reference": {k: reference[k] for k in ("tol", "n_slacks", "seconds", "iterations",
                                                          "primal_objective", "dual_objective")},
                  "peak_rss_mib": peak_rss},
        "latency": latency,
        "features_peak_mib": peak / 2**20,
    }


def format_bench(b: dict[str, Any]) -> str:
    t = b["train"]
    ref = t["reference"]
    lines = [
        f"training on {t['steps']} steps, C={t['C']} (peak resident memory {t['peak_rss_mib']:.0f} MiB)",
        f"{'model':>9} {'gap':>7} {'slacks':>7} {'seconds':>8} {'iterations':>11} {'oracle':>7} {'QP':>5} "
        f"{'objective':>11} {'excess':>9}",
    ]
    for r in t["runs"]:
        excess = f"{r['excess']:>9.1e}" if "excess" in r else f"{'':>9}"
        slacks = "n" if r["n_slacks"] == 0 else r["n_slacks"]  # n: one per step
        lines.append(f"{r['features']:>9} {r['tol']:>7.0e} {slacks:>7} {r['seconds']:>8.2f} "
                     f"{r['iterations']:>11} {r['oracle_share']:>7.0%} {r['qp_share']:>5.0%} "
                     f"{r['primal_objective']:>11.3f} {excess}" + ("" if r["converged"] else "  (not converged)"))
    lines += [
        f"reference: full model to a gap of {ref['tol']:.0e} in {ref['seconds']:.1f} s; certified lower bound on the "
        f"optimum {t['lower_bound']:.3f}",
        f"features stage, peak memory: {b['features_peak_mib']:.1f} MiB",
        "",
        f"{'objects':>8} {'candidates':>11} {'inference ms':>13} {'planner step ms':>16}",
    ]
    for n, row in sorted(b["latency"].items(), key=lambda item: int(item[0])):
        lines.append(f"{n:>8} {row['candidates']:>11} {row['inference_ms']:>13.3f} {row['step_ms']:>16.3f}")
    return "\n".join(lines)
