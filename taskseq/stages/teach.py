"""Stage `teach`: what k demonstrations buy in environments the planner has never seen.

For each reported world, the environments of `teach.environments` are held
out of the benchmark's training steps. A scripted person (the demonstrator,
writing through the server's record writer, read back by the ingest
validator) demonstrates k tasks in each of them; the full model is trained
on the rest of the benchmark plus those k per environment and judged on the
same held-out tasks for every k: all the tasks of those environments the
demonstrator can do, except the first max(k) it demonstrates.
"""

from __future__ import annotations

import statistics
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..demonstrations.benchmark import load_benchmark
from ..demonstrations.ingest import load_logs
from ..experiments.teaching import fit, pooled, success_on, teaching_order
from ..features.dataset import build_steps
from ..report.csvs import csv_text
from ..report.figures import line_plot_png
from ..runtime.atomic import write_text_atomic
from ..selection import read_selection
from ..serve.environments import world_environment
from ..serve.writer import RecordWriter, person_record
from ..settings import Learner, Params, Teach, World
from ..sim.scenarios import doable_tasks
from ..sim.tasks import TASKS
from ..track.mlflow_runs import NO_RUN, Tracker
from .options import TeachOptions

SCRIPTED = "scripted"  # the participant id of the scripted person's records


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
    learner: Learner  # the full model's, as `train` sets it (its C from the selection file)
    max_steps: int  # step cap of closed-loop runs


def settings(params: Params, world_seed: int | None = None) -> Settings:
    t = params.train
    return Settings(params.world, params.teach, Learner(t.tol, t.max_iter, t.n_slacks),
                    params.crossval.max_steps)


def run(settings: Settings, options: TeachOptions, tracker: Tracker = NO_RUN) -> list[dict[str, Any]]:
    world, teach, learner, max_steps = settings.world, settings.teach, settings.learner, settings.max_steps
    worlds, output = options.worlds, options.output
    C = read_selection(options.selection).of("full")
    unknown = sorted(set(teach.environments) - {f"env{i:02d}" for i in range(1, 14)})
    if unknown:
        raise ValueError(f"teach.environments: unknown environments {unknown}")
    rows = []
    for seed in world.seeds:
        records = load_benchmark(Path(worlds) / str(seed) / "processed").records
        base, _ = build_steps([r for r in records if r["env_id"] not in teach.environments])
        rng = np.random.default_rng([teach.seed, seed])
        taught, tested = {}, {}
        for env_id in teach.environments:
            env = world_environment(seed, env_id)
            tasks = doable_tasks(env.state)
            order = teaching_order(tasks, rng)
            taught[env_id] = (env, [tasks[i] for i in order[: max(teach.k)]])
            tested[env_id] = [tasks[i][0] for i in order[max(teach.k) :]]
        for k in teach.k:
            people = written_and_read_back([person_record(env, task, actions, SCRIPTED)
                                            for env, shown in taught.values() for task, actions in shown[:k]])
            planner = fit(base + (build_steps(people)[0] if people else []), C, learner)
            outcomes = [success_on(planner, env.env_id, env.state, tested[e], max_steps)
                        for e, (env, _) in taught.items()]
            rows.append({"world_seed": seed, "k": k, "held_out_tasks": sum(o.n_tasks for o in outcomes),
                         "successes": sum(o.n_success for o in outcomes), "success": pooled(outcomes),
                         **{f"success_{t}": pooled(outcomes, t) for t in TASKS}})
            print(f"world {seed}, k = {k}: {rows[-1]['successes']}/{rows[-1]['held_out_tasks']} held-out tasks "
                  f"succeed ({rows[-1]['success']:.1f}%)")
    table = _over_seeds(rows, teach.k)
    out = Path(output)
    kinds = [f"success_{t}" for t in TASKS]
    write_text_atomic(out / "teach_seeds.csv", csv_text(["world_seed", "k", "held_out_tasks", "successes", "success",
                                                         *kinds], rows, dict.fromkeys(["success", *kinds], 2)))
    means = [f"{c}_mean" for c in ["success", *kinds]]
    write_text_atomic(out / "teach.csv", csv_text(["k", *means, "success_sd", "n_seeds"], table,
                                                  dict.fromkeys([*means, "success_sd"], 2)))
    write_text_atomic(out / "teach.md", _markdown(table, teach))
    out.mkdir(parents=True, exist_ok=True)
    line_plot_png({"full model": ([r["k"] for r in table], [r["success_mean"] for r in table],
                                  [r["success_sd"] for r in table])},
                  str(out / "teach.png"), f"unseen environments {', '.join(teach.environments)}: "
                  f"mean ± sd over worlds {', '.join(map(str, world.seeds))}",
                  "tasks demonstrated per environment (k)", "success on the other tasks (%)",
                  xticks=list(teach.k), xticklabels=[str(k) for k in teach.k])
    for r in table:
        tracker.metrics({f"success_k{r['k']}": r["success_mean"]})
    return table


def _over_seeds(rows: list[dict[str, Any]], ks: tuple[int, ...]) -> list[dict[str, Any]]:
    out = []
    for k in ks:
        mine = [r for r in rows if r["k"] == k]
        values = [r["success"] for r in mine]
        kinds = {f"success_{t}_mean": statistics.fmean(r[f"success_{t}"] for r in mine) for t in TASKS}
        out.append({"k": k, "success_mean": statistics.fmean(values), **kinds,
                    "success_sd": statistics.stdev(values) if len(values) > 1 else 0.0, "n_seeds": len(values)})
    return out


def _markdown(table: list[dict[str, Any]], teach: Teach) -> str:
    lines = ["# Teaching unseen environments", "",
             f"Environments {', '.join(teach.environments)}, held out of the training data; a scripted person "
             "demonstrates k tasks in each; success of the full model on the other tasks there "
             "(mean ± sd over world seeds).", "",
             "| k | success (%) | " + " | ".join(TASKS) + " | world seeds |", "|---:|---:|" + "---:|" * len(TASKS)
             + "---:|"]
    lines += [f"| {r['k']} | {r['success_mean']:.1f} ± {r['success_sd']:.1f} | "
              + " | ".join(f"{r[f'success_{t}_mean']:.1f}" for t in TASKS) + f" | {r['n_seeds']} |" for r in table]
    lines += ["", "Task kinds: mean over world seeds of the success on the held-out tasks of that kind."]
    return "\n".join(lines) + "\n"
