"""Stage `teach`: what k demonstrations buy the shipped planner in drawn rooms it has never seen.

For each reported world, the `scenes` stage's drawn world of that seed is
read, and the rooms of `teach.environments` are held out of its training
steps. A scripted person (the demonstrator, writing through the server's
record writer, read back by the ingest validator) shows k tasks in each of
them; the shipped planner (the method `select` ranks first, at its C) is
trained on the rest of the drawn world plus those k per room, each taught
step counted `teach.weight` times, and judged on the same other tasks of
those rooms for every k: every task the demonstrator can do there
(`sim.scenarios.room_scenarios`) except the first max(k) it shows. A program
counts for sequence arg when it is one of the task's demonstrations, for
success when it stopped by choice with the goal reached and no safety rule
broken; k against 0 is paired task by task (exact McNemar test).
"""

from __future__ import annotations

import statistics
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..demonstrations.benchmark import Benchmark, load_benchmark
from ..demonstrations.ingest import load_logs
from ..experiments.teaching import judged, rooms_to_teach, weighted
from ..features.dataset import build_steps
from ..methods import Lineup, method_spec
from ..report.csvs import csv_text
from ..report.figures import line_plot_png
from ..report.seeds import mean_sd
from ..report.stats import mcnemar_exact
from ..report.stats_tables import p_text
from ..runtime.atomic import write_text_atomic
from ..runtime.jobs import Job, run_jobs
from ..selection import read_selection
from ..serve.environments import Environment
from ..serve.writer import RecordWriter, person_record
from ..settings import Learner, Methods, Params, Procedural, Teach, World
from ..track.mlflow_runs import NO_RUN, Tracker
from .options import TeachOptions

SCRIPTED = "scripted"  # the participant id of the scripted person's records
FIGURES = ("sequence_arg", "success")


def written_and_read_back(records: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """The records as the server writes them (`RecordWriter`) and `taskseq ingest` reads them back."""
    if not records:
        return []
    with tempfile.TemporaryDirectory(prefix="taskseq-teach-") as tmp:
        writer = RecordWriter(Path(tmp))
        for record in records:
            writer.append(record)
        return [item.record for item in load_logs(tmp)[1]]


@dataclass(frozen=True)
class Settings:
    world: World
    teach: Teach
    learner: Learner  # as `train` sets it (the shipped method's C from the selection file)
    max_steps: int  # step cap of closed-loop runs
    methods: Methods  # the shipped method's own settings
    procedural: Procedural = Procedural()  # where a method that trains on drawn rooms draws them


def settings(params: Params, world_seed: int | None = None) -> Settings:
    t = params.train
    return Settings(params.world, params.teach, Learner(t.tol, t.max_iter, t.n_slacks), params.crossval.max_steps,
                    params.methods, params.procedural)


def run(settings: Settings, options: TeachOptions, tracker: Tracker = NO_RUN, n_jobs: int = 1) -> list[dict[str, Any]]:
    world, teach, max_steps = settings.world, settings.teach, settings.max_steps
    selection = read_selection(options.selection)
    shipped = selection.method
    if shipped is None:
        raise ValueError(f"{options.selection}: names no method ranked first (the shipped planner); run "
                         "`taskseq select` again")
    make = Lineup(settings.methods, selection, settings.learner, procedural=settings.procedural).mrf([shipped])[shipped]
    # one job per world and k: a fit on thousands of steps each, so the jobs share the cores
    jobs = [job for seed in world.seeds
            for job in teach_jobs(seed, load_benchmark(Path(options.worlds) / str(seed) / "processed"), teach, make,
                                  max_steps)]
    programs = [row for rows in run_jobs(jobs, n_jobs) for row in rows]
    table, per_seed = _over_seeds(programs, teach.k, world.seeds)
    out, label = Path(options.output), method_spec(shipped).label
    write_text_atomic(out / "teach_programs.csv", csv_text(list(programs[0]), programs) if programs else "")
    write_text_atomic(out / "teach_seeds.csv", csv_text(["world_seed", "k", "held_out_tasks", *FIGURES], per_seed,
                                                        dict.fromkeys(FIGURES, 2)))
    columns = ["k", *(f"{f}_{s}" for f in FIGURES for s in ("mean", "sd")), "arg_misses", "misses_removed",
               "better", "worse", "p", "n_seeds"]
    write_text_atomic(out / "teach.csv", csv_text(columns, table, {c: 2 for c in columns[1:5]} | {"p": 4}))
    write_text_atomic(out / "teach.md", _markdown(table, teach, label, shipped))
    out.mkdir(parents=True, exist_ok=True)
    ks = [r["k"] for r in table]
    title = (f"the shipped planner ({shipped}) in drawn rooms held out:\n{', '.join(teach.environments)}; "
             f"mean ± sd over worlds {', '.join(map(str, world.seeds))}")
    line_plot_png({name: (ks, [r[f"{f}_mean"] for r in table], [r[f"{f}_sd"] for r in table])
                   for name, f in (("sequence arg", "sequence_arg"), ("success", "success"))},
                  str(out / "teach.png"), title, "tasks demonstrated per room (k)", "% of the other tasks there",
                  xticks=ks, xticklabels=[str(k) for k in ks])
    for r in table:
        tracker.metrics({f"sequence_arg_k{r['k']}": r["sequence_arg_mean"], f"success_k{r['k']}": r["success_mean"]})
    return table


def teach_world(seed: int, bench: Benchmark, teach: Teach, make: Any, max_steps: int) -> list[dict[str, Any]]:
    """Every program the planner (`make()`, unfitted) runs in the held-out rooms of world `seed` (its benchmark
    `bench`), for every k: one row each."""
    return [row for job, args in teach_jobs(seed, bench, teach, make, max_steps) for row in job(*args)]


def teach_jobs(seed: int, bench: Benchmark, teach: Teach, make: Any, max_steps: int) -> list[Job]:
    """`teach_world`'s work as one job per k, each giving its rows."""
    rooms: dict[str, Any] = {}
    for scenario in bench.scenarios.values():
        rooms.setdefault(scenario.env_id, scenario.initial)
    unknown = sorted(set(teach.environments) - set(rooms))
    if unknown:
        raise ValueError(f"teach.environments: {', '.join(unknown)} not among world {seed}'s rooms "
                         f"({', '.join(sorted(rooms))})")
    base = build_steps([r for r in bench.records if r["env_id"] not in teach.environments])
    taught = rooms_to_teach({e: rooms[e] for e in teach.environments}, max(teach.k),
                            np.random.default_rng([teach.seed, seed]))
    return [(_taught, (seed, k, base, taught, bench.scenarios, teach.weight, make, max_steps)) for k in teach.k]


def taught_method(k: int, base: tuple[list, list], taught: list[Any], scenarios: dict[str, Any], weight: int,
                  make: Any) -> Any:
    """The planner (`make()`) fitted on `base` plus the first k tasks shown in each room of `taught`, as a person's
    records are written and read back, each taught step counted `weight` times."""
    people = written_and_read_back([person_record(Environment(room.env_id, room.env_id, room.state), task,
                                                  list(actions), SCRIPTED)
                                    for room in taught for task, actions in room.shown[:k]])
    steps, meta = weighted(*base, *build_steps(people), weight) if people else base
    # a shipped method that rolls out its training scenarios (chained starts, DAgger) finds them here
    return make().fit(steps, meta, {**scenarios, **Benchmark.from_records(people).scenarios})


def _taught(seed: int, k: int, base: tuple[list, list], taught: list[Any], scenarios: dict[str, Any], weight: int,
            make: Any, max_steps: int) -> list[dict[str, Any]]:
    """The rows of one k: the planner trained on `base` plus the first k tasks shown in each room of `taught`."""
    method = taught_method(k, base, taught, scenarios, weight, make)
    rows = []
    for room in taught:
        for outcome in judged(make, method, room.tested, max_steps):
            rows.append({"world_seed": seed, "k": k, "room": room.env_id, "scenario": outcome.scenario_id,
                         "task": outcome.task, "sequence_arg": int(outcome.arg_correct),
                         "success": int(outcome.success), "failure": outcome.failure})
    print(f"world {seed}, k = {k}: {sum(r['sequence_arg'] for r in rows)} of {len(rows)} held-out tasks as "
          f"demonstrated, {sum(r['success'] for r in rows)} succeed")
    return rows


def _over_seeds(programs: list[dict[str, Any]], ks: tuple[int, ...],
                seeds: tuple[int, ...]) -> tuple[list[dict[str, Any]], list[dict[str, Any]]]:
    """Per k: each figure's mean and sd over worlds, and the programs paired with k = 0's (misses of sequence arg
    removed, McNemar's discordant pairs and p); and per world and k, the counts behind them."""
    per_seed = []
    for seed in seeds:
        for k in ks:
            mine = [r for r in programs if r["world_seed"] == seed and r["k"] == k]
            per_seed.append({"world_seed": seed, "k": k, "held_out_tasks": len(mine),
                             **{f: 100.0 * statistics.fmean(r[f] for r in mine) if mine else float("nan")
                                for f in FIGURES}})
    first = {(r["world_seed"], r["scenario"]): r["sequence_arg"] for r in programs if r["k"] == ks[0]}
    table = []
    for k in ks:
        mine = [r for r in per_seed if r["k"] == k]
        paired = [r for r in programs if r["k"] == k]
        now = np.array([r["sequence_arg"] for r in paired], dtype=bool)
        before = np.array([first[(r["world_seed"], r["scenario"])] for r in paired], dtype=bool)
        better, worse, p = mcnemar_exact(now, before)
        misses = int((~before).sum())
        spread = {f: mean_sd([r[f] for r in mine]) for f in FIGURES}
        table.append({"k": k, **{f"{f}_{s}": spread[f][i] for f in FIGURES for i, s in enumerate(("mean", "sd"))},
                      "arg_misses": int((~now).sum()),
                      "misses_removed": 100.0 * (misses - int((~now).sum())) / misses if misses else 0.0,
                      "better": better, "worse": worse, "p": p, "n_seeds": len(mine)})
    return table, per_seed


def _markdown(table: list[dict[str, Any]], teach: Teach, label: str, shipped: str) -> str:
    k0 = table[0]["k"]
    lines = ["# Teaching rooms never seen", "",
             f"Drawn rooms {', '.join(teach.environments)} of each world's drawn world, held out of its training "
             f"data; a scripted person shows k tasks in each (each taught step counted {teach.weight} times); "
             f"the shipped planner, {label} (`{shipped}`), on the other tasks there: % of programs as "
             "demonstrated (sequence arg) and successful, mean ± sd over world seeds. Against "
             f"k = {k0}, task by task: the misses of sequence arg removed (share of k = {k0}'s misses), the "
             f"programs right only with k (better) and only with k = {k0} (worse), and the exact McNemar p.", "",
             "| k | sequence arg | success | misses | misses removed | better | worse | p | world seeds |",
             "|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    lines += [f"| {r['k']} | {r['sequence_arg_mean']:.1f} ± {r['sequence_arg_sd']:.1f} | "
              f"{r['success_mean']:.1f} ± {r['success_sd']:.1f} | {r['arg_misses']} | {r['misses_removed']:.0f}% | "
              f"{r['better']} | {r['worse']} | {p_text(r['p'])} | {r['n_seeds']} |" for r in table]
    return "\n".join(lines) + "\n"

