"""Reading logs strictly: every problem names the file, the line and the field.

A record passes when it matches the JSON Schema, refers only to objects of its
environment, carries attributes consistent with its boxes, and replays in the
simulator: every step is feasible, every logged state is the one the
simulator produces, and the task's goal holds at the end.
"""

from __future__ import annotations

import functools
import json
import math
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import fastjsonschema
from jsonschema import Draft202012Validator

from ..sim.primitives import ARITY, PreconditionError, execute
from ..sim.state import WorldState
from ..sim.tasks import TASK_ARITY, goal_reached
from ..words import counted
from .records import expected_attributes, load_schema, parse_record, state_from_dict, state_to_dict

TOLERANCE = 1e-6


class LogError(ValueError):
    """One problem in one record of a log file."""

    def __init__(self, path: Path | str, line: int, field: str, message: str) -> None:
        super().__init__(f"{path}:{line}: {field}: {message}")
        self.path, self.line, self.field, self.message = str(path), line, field, message


@dataclass(frozen=True)
class LoggedRecord:
    path: Path
    line: int
    record: dict[str, Any]


_VALIDATOR = Draft202012Validator(load_schema())
# Draft 7 keywords whose meaning is the same in draft 2020-12, which the schema is written in (a `$ref` with no
# sibling, `items` as one schema, numeric `exclusiveMinimum`); tests/test_ingest.py holds the schema to that list
SAME_IN_DRAFT_7 = frozenset({
    "$schema", "$id", "$defs", "$ref", "title", "description", "type", "const", "enum", "properties", "required",
    "additionalProperties", "items", "minItems", "maxItems", "uniqueItems", "minLength", "pattern", "minimum",
    "exclusiveMinimum", "oneOf"})


@functools.cache
def _accepts() -> Callable[[Any], Any]:
    """The schema compiled to Python by fastjsonschema (as draft 7, whose meaning of its keywords is the same):
    a valid record checks in under a millisecond where jsonschema takes about fourteen, most of a large ingest.
    It only accepts; a record it refuses is read again by jsonschema, whose message names the field (and which
    accepts a string ending in a newline where the pattern ends in `$`, as before; the compiled one does not)."""
    schema = {k: v for k, v in load_schema().items() if k != "$id"}  # its resolver would read the id as a URL
    return fastjsonschema.compile({**schema, "$schema": "http://json-schema.org/draft-07/schema#"})


def _nonfinite(value: Any, path: str) -> str | None:
    """Path of the first NaN or infinity in a parsed record, if any."""
    if isinstance(value, float) and not math.isfinite(value):
        return path
    items = value.items() if isinstance(value, dict) else enumerate(value) if isinstance(value, list) else ()
    for key, child in items:
        found = _nonfinite(child, f"{path}[{key}]" if isinstance(key, int) else f"{path}.{key}" if path else key)
        if found:
            return found
    return None


def log_files(directory: Path) -> list[Path]:
    """The *.jsonl logs of a folder, by name; a missing folder, a file or a folder without logs is an error that
    says which."""
    directory = Path(directory)
    if not directory.is_dir():
        what = "is a file; give the folder that holds it" if directory.exists() else "no such folder"
        raise FileNotFoundError(f"{directory}: {what}")
    files = sorted(directory.glob("*.jsonl"))
    if not files:
        raise FileNotFoundError(f"{directory}: no *.jsonl log files")
    return files


def read_records(path: Path) -> Iterator[LoggedRecord]:
    """Parse a JSON Lines file; NaN and infinity are refused by field, blank lines skipped."""
    with open(path, encoding="utf-8") as fh:
        for number, text in enumerate(fh, start=1):
            if not text.strip():
                continue
            try:
                record = json.loads(text)
            except ValueError as err:
                raise LogError(path, number, "(line)", f"not valid JSON: {err}") from None
            if not isinstance(record, dict):
                raise LogError(path, number, "(line)", "a record must be a JSON object")
            bad = _nonfinite(record, "")
            if bad:
                raise LogError(path, number, bad, "NaN and infinity are not allowed; every number must be finite")
            yield LoggedRecord(Path(path), number, record)


def _field(path: Any) -> str:
    out = ""
    for part in path:
        out += f"[{part}]" if isinstance(part, int) else (f".{part}" if out else str(part))
    return out or "(record)"


def check_schema(item: LoggedRecord) -> None:
    try:
        _accepts()(item.record)
        return
    except (fastjsonschema.JsonSchemaValueException, RecursionError):  # arrays nested hundreds deep: it recurses
        pass  # the reference validator below decides, and names the field
    errors = sorted(_VALIDATOR.iter_errors(item.record), key=lambda e: list(e.absolute_path))
    if errors:
        err = errors[0]
        raise LogError(item.path, item.line, _field(err.absolute_path), err.message)


def check_references(item: LoggedRecord) -> None:
    """Ids, arities, attribute consistency and referential integrity."""
    rec = item.record

    def fail(field: str, message: str) -> None:
        raise LogError(item.path, item.line, field, message)

    ids: list[str] = [o["id"] for o in rec["objects"]]
    known = set(ids)
    for i, obj in enumerate(rec["objects"]):
        if ids.index(obj["id"]) != i:
            fail(f"objects[{i}].id", f"object {obj['id']} is listed twice")
        for name, want in expected_attributes(obj).items():
            got = obj["attributes"][name]
            if not math.isclose(got, want, rel_tol=1e-6, abs_tol=1e-9):
                fail(f"objects[{i}].attributes.{name}", f"{got} does not match the size {obj['size']} ({want:.6g})")
    task = rec["task"]
    if len(task["args"]) != TASK_ARITY[task["name"]]:
        fail("task.args", f"{task['name']} takes {counted(TASK_ARITY[task['name']], 'argument', spelled=True)}, "
                           f"got {len(task['args'])}")
    for j, arg in enumerate(task["args"]):
        if arg not in known:
            fail(f"task.args[{j}]", f"unknown object {arg!r}")
    states = [(f"steps[{k}].state", s["state"]) for k, s in enumerate(rec["steps"])]
    states.append(("final_state", rec["final_state"]))
    for k, step in enumerate(rec["steps"]):
        prim = step["primitive"]
        if len(step["args"]) != ARITY[prim]:
            fail(f"steps[{k}].args", f"{prim} takes {counted(ARITY[prim], 'argument', spelled=True)}, "
                                        f"got {len(step['args'])}")
        for j, arg in enumerate(step["args"]):
            if arg not in known:
                fail(f"steps[{k}].args[{j}]", f"unknown object {arg!r}")
        if len(step["args"]) == 2 and step["args"][0] == step["args"][1]:
            fail(f"steps[{k}].args", f"{prim} needs two different objects")
    for where, state in states:
        missing = known - set(state["objects"])
        extra = set(state["objects"]) - known
        if missing:
            fail(f"{where}.objects", f"missing objects {sorted(missing)}")
        if extra:
            fail(f"{where}.objects", f"unknown objects {sorted(extra)}")
        for key in ("held", "held_above"):
            if state[key] is not None and state[key] not in known:
                fail(f"{where}.{key}", f"unknown object {state[key]!r}")
        for j, liquid in enumerate(state["stirred"]):
            if liquid not in known:
                fail(f"{where}.stirred[{j}]", f"unknown object {liquid!r}")
        for obj, entry in state["objects"].items():
            if entry["support"] is not None and entry["support"] not in known:
                fail(f"{where}.objects.{obj}.support", f"unknown object {entry['support']!r}")
            if (entry["support"] is None) != (entry["relation"] is None):
                fail(f"{where}.objects.{obj}.relation", "support and relation must both be set or both be null")


def _first_difference(logged: dict[str, Any], simulated: dict[str, Any]) -> tuple[str, Any, Any] | None:
    for key in ("robot", "held", "held_above", "stirred"):
        if not _same(logged[key], simulated[key]):
            return key, logged[key], simulated[key]
    for obj in simulated["objects"]:
        for key in ("pose", "support", "relation"):
            a, b = logged["objects"][obj][key], simulated["objects"][obj][key]
            if not _same(a, b):
                return f"objects.{obj}.{key}", a, b
    return None


def _same(a: Any, b: Any) -> bool:
    if isinstance(a, list) and isinstance(b, list):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b, strict=True))
    if isinstance(a, (int, float)) and isinstance(b, (int, float)):
        return abs(a - b) <= TOLERANCE
    return a == b


def check_replay(item: LoggedRecord) -> None:
    """Re-execute the steps from the first logged state and compare every state."""
    rec = item.record
    specs, task, actions = parse_record(rec)
    initial: WorldState = state_from_dict(specs, rec["steps"][0]["state"])
    state = initial
    for k, action in enumerate(actions):
        try:
            state = execute(state, action)
        except PreconditionError as err:
            raise LogError(item.path, item.line, f"steps[{k}]", f"infeasible: {err}") from None
        where = f"steps[{k + 1}].state" if k + 1 < len(actions) else "final_state"
        logged = rec["steps"][k + 1]["state"] if k + 1 < len(actions) else rec["final_state"]
        diff = _first_difference(logged, state_to_dict(state))
        if diff is not None:
            field, got, want = diff
            raise LogError(
                item.path, item.line, f"{where}.{field}", f"logged {got!r} but replaying {action} gives {want!r}"
            )
    if not goal_reached(task, initial, state):
        raise LogError(item.path, item.line, "final_state", f"the goal of {task} is not reached")


def check_record(item: LoggedRecord) -> None:
    check_schema(item)
    check_references(item)
    check_replay(item)
