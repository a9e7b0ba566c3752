"""The commands that are not pipeline stages: replay logs, plan a program for one task."""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

from .learn.persist import load_model
from .logs.records import spec_from_dict, state_from_dict
from .logs.validate import LogError, check_record, check_references, check_schema, log_files, read_records
from .plan.planner import Program, plan
from .sim.tasks import Task


def replay(input_dir: Path) -> tuple[int, list[str]]:
    """Re-execute every logged sequence: (records that replay exactly, problems found)."""
    n_ok, problems = 0, []
    for path in log_files(Path(input_dir)):
        try:
            for item in read_records(path):
                try:
                    check_record(item)
                    n_ok += 1
                except LogError as err:
                    problems.append(str(err))
        except LogError as err:  # unreadable line: the rest of that file cannot be trusted
            problems.append(str(err))
    return n_ok, problems


def load_environment(path: Path, record: int) -> tuple[list[dict[str, Any]], dict[str, Any]]:
    """(objects, state) from a JSON environment file or a record of a JSON Lines log."""
    if path.suffix == ".jsonl":
        items = list(read_records(path))
        if not 1 <= record <= len(items):
            raise ValueError(f"{path}: has {len(items)} records, no record {record}")
        item = items[record - 1]
        check_schema(item)
        check_references(item)
        return item.record["objects"], item.record["steps"][0]["state"]
    try:
        env = json.loads(path.read_text())
    except (OSError, ValueError) as err:
        raise ValueError(f"{path}: cannot read the environment: {err}") from None
    for key in ("objects", "state"):
        if key not in env:
            raise LogError(path, 1, key, "an environment file needs 'objects' and 'state' (as in the log format)")
    return env["objects"], env["state"]


def plan_task(model_path: Path, env: Path, record: int, task_text: str, max_steps: int,
              top_k: int) -> tuple[Program, dict[str, str]]:
    """The program the model plans for the task in that environment, and the objects' names."""
    model, w, _ = load_model(model_path)
    objects, state_dict = load_environment(env, record)
    specs = {o["id"]: spec_from_dict(o) for o in objects}
    state = state_from_dict(specs, state_dict)
    task = Task.parse(task_text)
    task.check_objects(state)
    return plan(model, w, state, task, max_steps=max_steps, top_k=top_k), {o: s.name for o, s in specs.items()}


def program_json(program: Program) -> str:
    return json.dumps({
        "task": str(program.task), "status": program.status, "goal_reached": program.goal_reached,
        "steps": [{"action": str(s.action), "score": s.score, "unsafe": s.unsafe,
                   "alternatives": [[str(a), sc] for a, sc in s.alternatives]} for s in program.steps],
        "error": program.error,
    }, indent=2)


def print_program(program: Program, names: dict[str, str], out=None) -> None:
    out = out or sys.stdout

    def label(action) -> str:
        return f"{action}  [{', '.join(names[a] for a in action.args)}]" if action.args else str(action)

    print(f"program for {program.task}:", file=out)
    for k, s in enumerate(program.steps, start=1):
        alts = "; ".join(f"{a} {sc:.2f}" for a, sc in s.alternatives)
        warn = f"  UNSAFE: {', '.join(s.unsafe)}" if s.unsafe else ""
        print(f"{k:3d}. {label(s.action):55s} score {s.score:8.2f}   next best: {alts}{warn}", file=out)
    print(f"status: {program.status}; goal {'reached' if program.goal_reached else 'not reached'}"
          + (f"; {program.error}" if program.error else ""), file=out)
