"""`taskseq scaling`: how the cost of every per-world stage grows with the size of the world.

For each size (rooms of a procedural world, seed 0 by default) the world is
drawn and taken through the per-world stages exactly as `dvc.yaml` runs them,
each stage a `taskseq` process of its own whose wall time, CPU time and peak
resident memory are measured (`getrusage(RUSAGE_CHILDREN)` of a small
launcher: the largest process of the stage's tree, its loky workers included
once reaped). After `features`, the full model is fitted alone in a process of
its own (`python -m taskseq.bench.scaling`), to time training to the set gap, count
its iterations, read that process's peak resident memory
(`getrusage(RUSAGE_SELF).ru_maxrss`) after reading the features and after the
fit, and time inference on the world's own steps.

Timings are measurements, not results: they go to the JSON this command is
told to write (reports/scaling.json, docs/scaling-benchmark.md), never into
the pipeline.
"""

from __future__ import annotations

import json
import math
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from .machine import machine

PREPARE = ("generate", "ingest", "features")  # always run: the timed fit reads the features
EVALUATE = ("fold_models", "crossval", "noise", "feedback")  # the per-world stages after them, in dvc.yaml's order
NEEDS_FOLDS = ("crossval", "noise", "feedback")  # they read the fold models' store
WARM_UP_STEPS = 30  # steps of the untimed fit that loads the compiled code before the timed one
INFERENCE_STEPS = 400  # steps of the world whose inference is timed (spread evenly over it)


@dataclass(frozen=True)
class Plan:
    """What one scaling run measures: sizes, stages and the settings of the timed fit."""

    rooms: tuple[int, ...]
    stages: tuple[str, ...]  # of EVALUATE, run in EVALUATE's order; PREPARE always runs
    C: float
    tol: float
    max_iter: int
    n_slacks: int
    world_seed: int = 0
    n_jobs: int = 1
    methods: tuple[str, ...] | None = None  # crossval's --methods (default: every method of Table I)
    params: Path | None = None  # settings file of every stage (default: params.yaml, else the defaults)
    overrides: tuple[str, ...] = ()  # --set of every stage
    selection: Path | None = None  # the stages' --selection (C of the fold models)

    def check(self) -> None:
        """Refuse a plan that cannot run, naming what is wrong."""
        if not self.rooms:
            raise ValueError("scaling: give at least one size (--rooms)")
        if any(n < 1 for n in self.rooms):
            raise ValueError(f"scaling: rooms must be positive whole numbers, got {list(self.rooms)}")
        if len(set(self.rooms)) != len(self.rooms):
            raise ValueError(f"scaling: each size once, got {list(self.rooms)}")
        unknown = [s for s in self.stages if s not in EVALUATE]
        if unknown:
            raise ValueError(f"scaling: unknown stage(s) {unknown}; choose among {list(EVALUATE)} "
                             f"({', '.join(PREPARE)} always run)")
        if "fold_models" not in self.stages and any(s in NEEDS_FOLDS for s in self.stages):
            raise ValueError(f"scaling: {', '.join(s for s in self.stages if s in NEEDS_FOLDS)} read the fold models: "
                             f"add fold_models to --stages")
        if not self.C > 0 or not self.tol > 0 or self.max_iter < 1 or self.n_slacks < 0:
            raise ValueError(f"scaling: C and tol must be positive, max_iter at least 1, n_slacks at least 0; got "
                             f"C={self.C}, tol={self.tol}, max_iter={self.max_iter}, n_slacks={self.n_slacks}")
        if self.methods is not None and "crossval" not in self.stages:
            raise ValueError("scaling: --methods chooses crossval's methods: add crossval to --stages")


@dataclass(frozen=True)
class Measured:
    """One command: its wall time, the CPU time of its processes (on a shared machine wall time follows the
    load, CPU time much less) and the peak resident memory of its largest process."""

    seconds: float
    cpu_seconds: float
    peak_rss_mib: float


def stage_commands(plan: Plan, rooms: int, world: Path) -> dict[str, list[str]]:
    """Each stage's `taskseq` arguments on the world in `world`, as `dvc.yaml` writes them."""
    data = {"features": str(world / "features"), "processed": str(world / "processed")}
    common = ([] if plan.params is None else ["--params", str(plan.params)]) + [
        a for o in plan.overrides for a in ("--set", o)]
    picked = [] if plan.selection is None else ["--selection", str(plan.selection)]
    jobs = ["--n-jobs", str(plan.n_jobs)]
    seed = ["--world-seed", str(plan.world_seed)]
    store = ["--model-store", str(world / "folds")]
    world_data = ["--features", data["features"], "--processed", data["processed"], *picked]
    methods = [] if plan.methods is None else ["--methods", *plan.methods]
    commands = {
        "generate": ["generate", *seed, "--set", "world.family=procedural", "--set",
                     f"procedural.environments={rooms}", "--output", str(world / "raw"),
                     "--metrics", str(world / "world.json")],
        "ingest": ["ingest", *seed, "--input", str(world / "raw"), "--output", data["processed"],
                   "--metrics", str(world / "dataset.json")],
        "features": ["features", *seed, "--input", data["processed"], "--output", data["features"]],
        "fold_models": ["fold_models", *seed, *world_data, *jobs, "--output", str(world / "folds"),
                        "--metrics", str(world / "folds.json")],
        "crossval": ["crossval", *seed, *world_data, *jobs, *store, "--output", str(world / "crossval"),
                     "--recordings-dir", str(world / "recordings"), *methods],
        "noise": ["noise", *seed, *world_data, *jobs, *store, "--output", str(world / "noise")],
        "feedback": ["feedback", *seed, *world_data, *jobs, *store, "--output", str(world / "feedback")],
    }
    return {name: [*argv, *common] for name, argv in commands.items()}


# A lean launcher between this process and each measured one: a process's peak resident memory counts the
# memory of the process it was started from (Linux carries it over at exec), so the measured command is
# started from this small one, which reports its children's peak (`RUSAGE_CHILDREN`) to the file argv[1].
_LAUNCHER = ("import resource, subprocess, sys; code = subprocess.call(sys.argv[2:]); "
             "r = resource.getrusage(resource.RUSAGE_CHILDREN); "
             "open(sys.argv[1], 'w').write(f'{r.ru_maxrss} {r.ru_utime + r.ru_stime}'); sys.exit(code)")


def measured(label: str, argv: list[str], log: Path) -> Measured:
    """Run `argv` to its end (its output to `log`): wall time and peak memory; raise with the log's tail if it
    fails."""
    peak = log.with_suffix(".rusage")
    start = time.perf_counter()
    with open(log, "w", encoding="utf-8") as out:
        code = subprocess.call([sys.executable, "-c", _LAUNCHER, str(peak), *argv], stdout=out,
                               stderr=subprocess.STDOUT)
    seconds = time.perf_counter() - start
    if code != 0:
        tail = "".join(log.read_text(encoding="utf-8", errors="replace").splitlines(keepends=True)[-15:])
        raise RuntimeError(f"scaling: {label} exited with {code}; its log {log} ends:\n{tail}")
    maxrss, cpu = peak.read_text().split()
    return Measured(seconds, float(cpu), int(maxrss) / 1024)  # KiB on Linux


def _rss_mib() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def fit_and_infer(features: str, C: float, tol: float, max_iter: int, n_slacks: int) -> dict[str, Any]:
    """Read the features, fit the full model, time inference on the world's steps (run in a process of its own,
    so that its peak memory is the fit's)."""
    from ..features.context import candidate_index
    from ..features.dataset import read_features
    from ..learn.estimator import StepScorer
    from .speed import fit_summary

    contexts, _ = read_features(features)
    loaded = _rss_mib()
    # an untimed fit on a few steps first: the first fit of a process loads the compiled code (about 0.3 s)
    StepScorer("full", C=C, tol=tol, max_iter=max_iter, n_slacks=n_slacks).fit(contexts[:WARM_UP_STEPS])
    cpu = time.process_time()
    planner = StepScorer("full", C=C, tol=tol, max_iter=max_iter, n_slacks=n_slacks).fit(contexts)
    cpu = time.process_time() - cpu
    fitted = _rss_mib()
    every = max(1, len(contexts) // INFERENCE_STEPS)
    sample = contexts[::every]
    planner.model_.inference(sample[0], planner.w_)  # compiled code loaded before timing
    times, candidates = [], []  # a step's candidates grow with the square of its objects
    for ctx in sample:
        t0 = time.perf_counter()
        planner.model_.inference(ctx, planner.w_)
        times.append(time.perf_counter() - t0)
        candidates.append(len(candidate_index(ctx.n)[0]))
    return {
        "steps": len(contexts),
        **fit_summary(planner),
        "cpu_seconds": cpu,
        "loaded_rss_mib": loaded,
        "peak_rss_mib": fitted,
        "inference": {"steps_timed": len(sample), "median_ms": 1000 * statistics.median(times),
                      "candidates_median": statistics.median(candidates), "candidates_max": max(candidates)},
    }


def time_fit(world: Path, plan: Plan) -> dict[str, Any]:
    """`fit_and_infer` on a world's features in a process of its own (`python -m taskseq.bench.scaling`)."""
    out = world / "fit.json"
    argv = [str(world / "features"), repr(plan.C), repr(plan.tol), str(plan.max_iter), str(plan.n_slacks), str(out)]
    process = measured("the timed fit", [sys.executable, "-m", "taskseq.bench.scaling", *argv],
                       world / "logs" / "fit.log")
    result = json.loads(out.read_text(encoding="utf-8"))
    result["process_seconds"] = process.seconds
    result["ms_per_step"] = 1000 * result["seconds"] / result["steps"]
    result["cpu_ms_per_step"] = 1000 * result["cpu_seconds"] / result["steps"]
    return result


def _scenarios(world: Path) -> int:
    """Scenarios of the world, from the counts `taskseq ingest` wrote (this process loads no table)."""
    return json.loads((world / "dataset.json").read_text(encoding="utf-8"))["scenarios"]


def measure_size(plan: Plan, rooms: int, world: Path, say: Callable[[str], None],
                 done: Callable[[dict[str, Any]], None]) -> dict[str, Any]:
    """Draw a world of `rooms` rooms into `world`, time the fit on its features, then every stage of the plan.

    `done` gets the size's entry after each measurement (`complete` false until the last), so a long run
    stopped part way keeps what it measured.
    """
    commands = stage_commands(plan, rooms, world)
    logs = world / "logs"
    logs.mkdir(parents=True, exist_ok=True)
    entry: dict[str, Any] = {"rooms": rooms, "stages": {}, "complete": False,
                             "load_average": {"before": list(os.getloadavg())}}

    def stage(name: str) -> None:
        say(f"[{rooms} rooms] {name} ...")
        m = measured(f"taskseq {name}", [sys.executable, "-m", "taskseq.cli", "--no-mlflow", *commands[name]],
                     logs / f"{name}.log")
        entry["stages"][name] = asdict(m)
        say(f"[{rooms} rooms] {name}: {m.seconds:.1f} s ({m.cpu_seconds:.1f} s CPU), peak {m.peak_rss_mib:.0f} MiB")

    for name in PREPARE:
        stage(name)
    say(f"[{rooms} rooms] timed fit of the full model (C={plan.C:g}, gap {plan.tol:g}) ...")
    train = time_fit(world, plan)
    inference = train.pop("inference")
    say(f"[{rooms} rooms] {train['steps']} steps: fit {train['seconds']:.2f} s, {train['iterations']} iterations, "
        f"{train['ms_per_step']:.3f} ms a step, peak {train['peak_rss_mib']:.0f} MiB; "
        f"inference {inference['median_ms']:.3f} ms a step")
    entry.update(scenarios=_scenarios(world), steps=train["steps"], train=train, inference=inference)
    done(entry)
    for name in (s for s in EVALUATE if s in plan.stages):
        stage(name)
        done(entry)
    entry["load_average"]["after"] = list(os.getloadavg())
    entry["complete"] = True
    done(entry)
    return entry


def growth(sizes: list[dict[str, Any]]) -> dict[str, Any]:
    """Log-log slopes against steps between consecutive sizes and from the smallest to the largest: 1 is
    linear, above 1 grows faster than the steps."""
    if len(sizes) < 2:
        return {}
    sizes = sorted(sizes, key=lambda s: s["steps"])

    def slope(a: dict[str, Any], b: dict[str, Any], get: Callable[[dict[str, Any]], float]) -> float | None:
        if a["steps"] == b["steps"] or get(a) <= 0 or get(b) <= 0:
            return None
        return math.log(get(b) / get(a)) / math.log(b["steps"] / a["steps"])

    series: dict[str, Callable[[dict[str, Any]], float]] = {
        "train_seconds": lambda s: s["train"]["seconds"],
        "train_cpu_seconds": lambda s: s["train"]["cpu_seconds"],
        "train_iterations": lambda s: s["train"]["iterations"],
        "train_peak_rss_mib": lambda s: s["train"]["peak_rss_mib"],
        "inference_ms": lambda s: s["inference"]["median_ms"],
    }
    measured_at = {key: sizes for key in series}
    for name in dict.fromkeys(n for s in sizes for n in s["stages"]):
        series[f"stage.{name}"] = lambda s, n=name: s["stages"][n]["seconds"]
        series[f"stage.{name}.cpu"] = lambda s, n=name: s["stages"][n]["cpu_seconds"]
        measured_at[f"stage.{name}"] = measured_at[f"stage.{name}.cpu"] = [
            s for s in sizes if name in s["stages"]]  # a run stopped part way
    out = {}
    for key, get in series.items():
        have = measured_at[key]
        if len(have) < 2:
            continue
        pairs = list(zip(have, have[1:], strict=False))
        out[key] = {"overall": slope(have[0], have[-1], get),
                    "between": [{"steps": [a["steps"], b["steps"]], "slope": slope(a, b, get)} for a, b in pairs]}
    return out


def run_scaling(plan: Plan, keep: Path | None = None, say: Callable[[str], None] = print,
                update: Callable[[dict[str, Any]], None] = lambda result: None) -> dict[str, Any]:
    """Every size of the plan, smallest first; each world in a temporary folder, or kept under `keep`.

    `update` gets the result so far after every measurement (the command writes it out each time).
    """
    from ..runtime.cache import disabled  # here: the command line is built without the learner

    with disabled():  # a fit read from the cache would time nothing, here or in the stages' processes
        return _measured(plan, keep, say, update)


def _measured(plan: Plan, keep: Path | None, say: Callable[[str], None],
              update: Callable[[dict[str, Any]], None]) -> dict[str, Any]:
    plan.check()
    settings = asdict(plan)
    for key in ("params", "selection"):
        settings[key] = None if settings[key] is None else str(settings[key])
    result: dict[str, Any] = {"machine": machine(), "settings": settings, "sizes": [], "growth": {}}

    def done(entry: dict[str, Any]) -> None:
        sizes = [s for s in result["sizes"] if s["rooms"] != entry["rooms"]] + [entry]
        result["sizes"] = sizes
        result["growth"] = growth(sizes)
        update(result)

    for rooms in sorted(plan.rooms):
        if keep is None:
            with tempfile.TemporaryDirectory(prefix=f"taskseq-scaling-{rooms}-") as tmp:
                measure_size(plan, rooms, Path(tmp), say, done)
        else:
            world = keep / f"rooms-{rooms}"
            shutil.rmtree(world, ignore_errors=True)  # a world of this size from an earlier run: replaced
            measure_size(plan, rooms, world, say, done)
    return result


def stage_order(result: dict[str, Any]) -> list[str]:
    """The measured stages in the order they ran (the JSON sorts its keys)."""
    return [*PREPARE, *(s for s in EVALUATE if s in result["settings"]["stages"])]


def format_scaling(result: dict[str, Any]) -> str:
    """The table of the docs: one row per size, then the log-log slopes from the smallest size to the largest."""
    sizes = result["sizes"]
    names = stage_order(result)
    head = (f"{'rooms':>5} {'scen.':>6} {'steps':>6} {'fit s':>7} {'iters':>5} {'ms/step':>7} {'peak MiB':>8} "
            f"{'infer ms':>8} " + " ".join(f"{n:>9}" for n in names))
    lines = [head]
    for s in sizes:
        t = s["train"]
        lines.append(f"{s['rooms']:>5} {s['scenarios']:>6} {s['steps']:>6} {t['seconds']:>7.2f} {t['iterations']:>5} "
                     f"{t['ms_per_step']:>7.3f} {t['peak_rss_mib']:>8.0f} {s['inference']['median_ms']:>8.3f} "
                     + " ".join(f"{s['stages'][n]['seconds']:>9.1f}" if n in s["stages"] else f"{'-':>9}"
                                for n in names))
    slopes = result["growth"]
    if slopes:
        shown = ", ".join(f"{k} {v['overall']:.2f}" for k, v in slopes.items() if v["overall"] is not None)
        lines.append(f"log-log slope against steps, smallest to largest size (1 = linear): {shown}")
    return "\n".join(lines)


def plot_scaling(result: dict[str, Any], path: Path | str) -> None:
    """Two panels against steps: each stage's wall time (log-log, with a linear guide) and training time per step."""
    from ..report.figures import scaling_png

    sizes = sorted(result["sizes"], key=lambda s: s["steps"])
    steps = [s["steps"] for s in sizes]
    stages = {}
    for name in stage_order(result):
        have = [s for s in sizes if name in s["stages"]]
        stages[name] = ([s["steps"] for s in have], [s["stages"][name]["seconds"] for s in have])
    stages["fit (full model)"] = (steps, [s["train"]["seconds"] for s in sizes])
    per_step = {"wall time": [s["train"]["ms_per_step"] for s in sizes],
                "CPU time": [s["train"]["cpu_ms_per_step"] for s in sizes]}
    scaling_png(steps, stages, per_step, result["settings"]["tol"], str(path))


def parse_rooms(values: Sequence[str]) -> tuple[int, ...]:
    """Sizes from the command line, each a positive whole number."""
    out = []
    for v in values:
        if not v.isdigit() or int(v) < 1:
            raise ValueError(f"scaling: rooms must be positive whole numbers, got {v!r}")
        out.append(int(v))
    return tuple(out)


if __name__ == "__main__":  # the timed fit's own process: FEATURES C TOL MAX_ITER N_SLACKS OUTPUT.json
    _features, _C, _tol, _max_iter, _n_slacks, _out = sys.argv[1:]
    from ..runtime.atomic import write_json_atomic

    write_json_atomic(_out, fit_and_infer(_features, float(_C), float(_tol), int(_max_iter), int(_n_slacks)))
