"""`taskseq bench`: how long training and planning take on this machine.

Timings are measurements, not tests: they go to reports/bench.json and the README.
"""

from __future__ import annotations

import os
import platform
import statistics
import tempfile
import time
import tracemalloc
from pathlib import Path
from typing import Any

import numpy as np

from .features.context import step_context
from .features.dataset import build_steps, write_features
from .learn.train import fit_mrf
from .sim.catalog import OBJECTS
from .sim.objects import ObjectSpec
from .sim.state import ON, WorldState
from .sim.tasks import Task

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


def run_bench(records: list[dict[str, Any]], C: float, tol: float, max_iter: int, repeats: int = 50,
              progress: bool = True) -> dict[str, Any]:
    tracemalloc.start()
    with tempfile.TemporaryDirectory() as tmp:
        contexts, meta = build_steps(records)
        write_features(contexts, meta, Path(tmp) / "features")
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()

    fit = fit_mrf(contexts, "full", C=C, tol=tol, max_iter=max_iter, progress=progress)
    last = fit.ssvm.history_[-1]
    latency = {}
    for n in SIZES:
        state, task = synthetic_world(n)
        ctx = step_context(state, task, [])
        fit.model.inference(ctx, fit.w)  # warm caches
        infer, step = [], []
        for _ in range(repeats):
            t0 = time.perf_counter()
            fit.model.inference(ctx, fit.w)
            t1 = time.perf_counter()
            fit.model.inference(step_context(state, task, []), fit.w)
            t2 = time.perf_counter()
            infer.append(t1 - t0)
            step.append(t2 - t1)
        latency[str(n)] = {
            "candidates": int(len(fit.model.scores(ctx, fit.w)[1])),
            "inference_ms": 1000 * statistics.median(infer),
            "step_ms": 1000 * statistics.median(step),
        }
    return {
        "machine": {"python": platform.python_version(), "processor": platform.machine(), "cpus": _cpus()},
        "train": {
            "steps": len(contexts),
            "seconds": fit.seconds,
            "iterations": fit.ssvm.n_iter_,
            "converged": bool(fit.ssvm.converged_),
            "relative_gap": last.gap / max(1.0, abs(last.best_primal)),
            "C": C,
            "tol": tol,
        },
        "latency": latency,
        "features_peak_mib": peak / 2**20,
    }


def _cpus() -> int:
    return os.cpu_count() or 1


def format_bench(b: dict[str, Any]) -> str:
    t = b["train"]
    lines = [
        f"training, full model: {t['seconds']:.1f} s, {t['iterations']} iterations, "
        f"relative gap {t['relative_gap']:.2g} ({'converged' if t['converged'] else 'not converged'}), "
        f"{t['steps']} steps, C={t['C']}, tol={t['tol']}",
        f"features stage, peak memory: {b['features_peak_mib']:.1f} MiB",
        "",
        f"{'objects':>8} {'candidates':>11} {'inference ms':>13} {'planner step ms':>16}",
    ]
    for n, row in b["latency"].items():
        lines.append(f"{n:>8} {row['candidates']:>11} {row['inference_ms']:>13.3f} {row['step_ms']:>16.3f}")
    return "\n".join(lines)
