"""Stage `people`: people's demonstrations, their dataset counts, and the planner's success with and without them.

Before: the full model trained on the first reported world's steps (what
`train` fits). After: the same with people's demonstrations added. Both are
judged in each environment people demonstrated, on the tasks they did not
demonstrate there (`experiments.teaching`). No demonstrations, no training: the
report says so.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from ..demonstrations.people import people_records
from ..demonstrations.records import parse_record, state_from_dict
from ..experiments.teaching import fit, pooled, success_on
from ..features.dataset import build_steps, read_features
from ..runtime.atomic import write_json_atomic, write_text_atomic
from ..selection import read_selection
from ..settings import Learner, Params, People
from ..sim.scenarios import doable_tasks
from ..track.mlflow_runs import NO_RUN, Tracker
from ..words import counted
from .options import PeopleOptions


@dataclass(frozen=True)
class Settings:
    people: People
    learner: Learner  # the full model's, as `train` sets it (its C from the selection file)
    max_steps: int  # step cap of closed-loop runs


def settings(params: Params, world_seed: int | None = None) -> Settings:
    t = params.train
    return Settings(People(logs=params.people.logs), Learner(t.tol, t.max_iter, t.n_slacks),
                    params.crossval.max_steps)


def run(settings: Settings, options: PeopleOptions, tracker: Tracker = NO_RUN) -> dict[str, Any]:
    learner, max_steps, output = settings.learner, settings.max_steps, options.output
    records, summary = people_records(settings.people.logs)
    result: dict[str, Any] = {"environments": [], "success_before": None, "success_after": None}
    if records:
        base, _ = read_features(options.features)
        C = read_selection(options.selection).of("full")
        before = fit(base, C, learner)
        after = fit(base + build_steps(records)[0], C, learner)
        rows, outcomes = [], {"before": [], "after": []}
        for env_id in sorted({r["env_id"] for r in records}):
            mine = [r for r in records if r["env_id"] == env_id]
            specs, _, _ = parse_record(mine[0])
            state = state_from_dict(specs, mine[0]["steps"][0]["state"])
            taught = {f"{r['task']['name']}({','.join(r['task']['args'])})" for r in mine}
            held_out = [t for t, _ in doable_tasks(state) if str(t) not in taught]
            row = {"env_id": env_id, "demonstrations": len(mine), "held_out_tasks": len(held_out)}
            for name, planner in (("before", before), ("after", after)):
                outcome = success_on(planner, env_id, state, held_out, max_steps)
                outcomes[name].append(outcome)
                row[f"success_{name}"] = outcome.success
            rows.append(row)
        result = {"environments": rows, "success_before": pooled(outcomes["before"]),
                  "success_after": pooled(outcomes["after"])}
    out = output
    write_json_atomic(out / "dataset.json", summary)
    write_json_atomic(out / "before_after.json", result)
    write_text_atomic(out / "before_after.md", _markdown(result))
    tracker.metrics({k: float(v) for k, v in summary.items() if isinstance(v, int)})
    n, rooms = summary["sequences"], summary["environments"]
    print(f"people's demonstrations: {counted(n, 'sequence')} in {counted(rooms, 'environment')}"
          + (f"; success on their held-out tasks {result['success_before']:.1f}% before, "
             f"{result['success_after']:.1f}% after" if records else ""))
    return result


def _markdown(result: dict[str, Any]) -> str:
    head = "# People's demonstrations: the planner's success on the tasks they did not demonstrate\n\n"
    if not result["environments"]:
        return head + "No people's demonstrations yet (`taskseq serve` writes them).\n"
    lines = ["| environment | demonstrations | held-out tasks | success before (%) | success after (%) |",
             "|---|---:|---:|---:|---:|"]
    lines += [f"| {r['env_id']} | {r['demonstrations']} | {r['held_out_tasks']} | {r['success_before']:.1f} | "
              f"{r['success_after']:.1f} |" for r in result["environments"]]
    lines.append(f"| all | | | {result['success_before']:.1f} | {result['success_after']:.1f} |")
    return head + "\n".join(lines) + "\n"
