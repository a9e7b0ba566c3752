"""Validated logs to Parquet tables with explicit schemas, and back.

Tables (one Parquet file each):
  objects       one row per distinct object: size, levels, the 14 attributes
  environments  which objects each environment holds, in log order
  scenarios     environment + task + task arguments, with its number of sequences
  sequences     one row per demonstration, with the file and line it came from
  steps         one row per primitive executed
  states        the world before every step and after the last, one row per object
"""

from __future__ import annotations

from collections import Counter
from pathlib import Path
from typing import Any

import pyarrow as pa
import pyarrow.parquet as pq

from ..io import atomic_directory
from ..sim.objects import ATTRIBUTE_NAMES, BINARY_ATTRIBUTES
from .records import FORMAT
from .validate import LogError, LoggedRecord, check_record, log_files, read_records

STR, F64, I32 = pa.string(), pa.float64(), pa.int32()

SCHEMAS: dict[str, pa.Schema] = {
    "objects": pa.schema(
        [("object_id", STR), ("name", STR), ("category", STR), ("w", F64), ("l", F64), ("h", F64),
         ("levels", pa.list_(F64))] + [(a, F64) for a in ATTRIBUTE_NAMES]
    ),
    "environments": pa.schema([("env_id", STR), ("position", I32), ("object_id", STR)]),
    "scenarios": pa.schema(
        [("scenario_id", STR), ("env_id", STR), ("task", STR), ("arg1", STR), ("arg2", STR), ("n_sequences", I32)]
    ),
    "sequences": pa.schema(
        [("sequence_id", STR), ("scenario_id", STR), ("source", STR), ("line", I32), ("n_steps", I32)]
    ),
    "steps": pa.schema([("sequence_id", STR), ("step", I32), ("primitive", STR), ("arg1", STR), ("arg2", STR)]),
    "states": pa.schema(
        [("sequence_id", STR), ("step", I32), ("object_id", STR), ("x", F64), ("y", F64), ("z", F64),
         ("support", STR), ("relation", STR), ("stirred", pa.bool_()), ("robot_x", F64), ("robot_y", F64),
         ("held", STR), ("held_above", STR)]
    ),
}
TABLES = tuple(SCHEMAS)


def _arg(args: list[str], i: int) -> str | None:
    return args[i] if len(args) > i else None


class _Collector:
    """Accumulates rows and checks what only shows across records."""

    def __init__(self) -> None:
        self.rows: dict[str, list[dict[str, Any]]] = {t: [] for t in TABLES}
        self.objects: dict[str, tuple[dict[str, Any], str]] = {}
        self.envs: dict[str, tuple[list[str], str]] = {}
        self.scenarios: dict[str, dict[str, Any]] = {}
        self.sequence_ids: dict[str, str] = {}

    def add(self, item: LoggedRecord) -> None:
        rec = item.record
        where = f"{item.path.name}:{item.line}"

        def fail(field: str, message: str) -> None:
            raise LogError(item.path, item.line, field, message)

        if rec["demo_id"] in self.sequence_ids:
            fail("demo_id", f"{rec['demo_id']!r} already used at {self.sequence_ids[rec['demo_id']]}")
        self.sequence_ids[rec["demo_id"]] = where
        for i, obj in enumerate(rec["objects"]):
            seen = self.objects.get(obj["id"])
            if seen is None:
                self.objects[obj["id"]] = (obj, where)
            elif seen[0] != obj:
                fail(f"objects[{i}]", f"object {obj['id']} differs from its description at {seen[1]}")
        ids = [o["id"] for o in rec["objects"]]
        env = self.envs.get(rec["env_id"])
        if env is None:
            self.envs[rec["env_id"]] = (ids, where)
        elif env[0] != ids:
            fail("objects", f"environment {rec['env_id']} holds other objects at {env[1]}")
        task = rec["task"]
        scenario = self.scenarios.get(rec["scenario_id"])
        key = {"env_id": rec["env_id"], "task": task["name"], "arg1": task["args"][0], "arg2": _arg(task["args"], 1)}
        if scenario is None:
            self.scenarios[rec["scenario_id"]] = {**key, "n_sequences": 1, "where": where}
        elif {k: scenario[k] for k in key} != key:
            fail("scenario_id", f"scenario {rec['scenario_id']} has another environment or task at {scenario['where']}")
        else:
            scenario["n_sequences"] += 1
        sid = rec["demo_id"]
        self.rows["sequences"].append(
            {"sequence_id": sid, "scenario_id": rec["scenario_id"], "source": item.path.name, "line": item.line,
             "n_steps": len(rec["steps"])}
        )
        for k, step in enumerate(rec["steps"]):
            self.rows["steps"].append(
                {"sequence_id": sid, "step": k, "primitive": step["primitive"], "arg1": _arg(step["args"], 0),
                 "arg2": _arg(step["args"], 1)}
            )
        for k, state in enumerate([s["state"] for s in rec["steps"]] + [rec["final_state"]]):
            stirred = set(state["stirred"])
            for obj in ids:
                entry = state["objects"][obj]
                x, y, z = entry["pose"]
                self.rows["states"].append(
                    {"sequence_id": sid, "step": k, "object_id": obj, "x": x, "y": y, "z": z,
                     "support": entry["support"], "relation": entry["relation"], "stirred": obj in stirred,
                     "robot_x": state["robot"][0], "robot_y": state["robot"][1], "held": state["held"],
                     "held_above": state["held_above"]}
                )

    def tables(self) -> dict[str, pa.Table]:
        for oid in sorted(self.objects):
            obj = self.objects[oid][0]
            w, l, h = obj["size"]  # noqa: E741
            self.rows["objects"].append(
                {"object_id": oid, "name": obj["name"], "category": obj["category"], "w": w, "l": l, "h": h,
                 "levels": obj["levels"], **{a: float(obj["attributes"][a]) for a in ATTRIBUTE_NAMES}}
            )
        for env_id in sorted(self.envs):
            for pos, oid in enumerate(self.envs[env_id][0]):
                self.rows["environments"].append({"env_id": env_id, "position": pos, "object_id": oid})
        for scen_id in sorted(self.scenarios):
            s = self.scenarios[scen_id]
            self.rows["scenarios"].append(
                {"scenario_id": scen_id, **{k: s[k] for k in ("env_id", "task", "arg1", "arg2", "n_sequences")}}
            )
        return {t: pa.Table.from_pylist(self.rows[t], schema=SCHEMAS[t]) for t in TABLES}


def load_logs(input_dir: Path | str) -> tuple[dict[str, pa.Table], list[LoggedRecord]]:
    """Validate every record of every log file; the first problem raises `LogError`."""
    collector = _Collector()
    records = []
    for path in log_files(Path(input_dir)):
        for item in read_records(path):
            check_record(item)
            collector.add(item)
            records.append(item)
    if not records:
        raise LogError(input_dir, 0, "(file)", "the logs hold no records")
    return collector.tables(), records


def dataset_summary(tables: dict[str, pa.Table]) -> dict[str, Any]:
    steps = tables["steps"].to_pylist()
    seqs = tables["sequences"].to_pylist()
    scen = {s["scenario_id"]: s["task"] for s in tables["scenarios"].to_pylist()}
    seq_task = {s["sequence_id"]: scen[s["scenario_id"]] for s in seqs}
    lengths = [s["n_steps"] for s in seqs]
    return {
        "environments": len(set(tables["environments"].column("env_id").to_pylist())),
        "objects": tables["objects"].num_rows,
        "tasks": len(set(scen.values())),
        "scenarios": tables["scenarios"].num_rows,
        "sequences": len(seqs),
        "steps": len(steps),
        "min_steps": min(lengths),
        "max_steps": max(lengths),
        "steps_per_primitive": dict(sorted(Counter(s["primitive"] for s in steps).items())),
        "steps_per_task": dict(sorted(Counter(seq_task[s["sequence_id"]] for s in steps).items())),
        "sequences_per_task": dict(sorted(Counter(seq_task[s["sequence_id"]] for s in seqs).items())),
    }


def write_tables(tables: dict[str, pa.Table], output: Path | str) -> None:
    """Replace `output` with one Parquet file per table; bytes depend only on the data."""
    with atomic_directory(output) as tmp:
        for name, table in tables.items():
            pq.write_table(table, tmp / f"{name}.parquet", compression="zstd", write_statistics=False)


def read_tables(directory: Path | str) -> dict[str, pa.Table]:
    return {t: pq.read_table(Path(directory) / f"{t}.parquet", schema=SCHEMAS[t]) for t in TABLES}


def records_from_tables(tables: dict[str, pa.Table]) -> list[dict[str, Any]]:
    """Rebuild the log records from the tables, in their original file and line order."""
    objects = {o["object_id"]: o for o in tables["objects"].to_pylist()}
    env_objects: dict[str, list[str]] = {}
    for row in sorted(tables["environments"].to_pylist(), key=lambda r: (r["env_id"], r["position"])):
        env_objects.setdefault(row["env_id"], []).append(row["object_id"])
    scenarios = {s["scenario_id"]: s for s in tables["scenarios"].to_pylist()}
    steps: dict[str, list[dict[str, Any]]] = {}
    for row in tables["steps"].to_pylist():
        steps.setdefault(row["sequence_id"], []).append(row)
    states: dict[tuple[str, int], list[dict[str, Any]]] = {}
    for row in tables["states"].to_pylist():
        states.setdefault((row["sequence_id"], row["step"]), []).append(row)

    def state(sid: str, k: int) -> dict[str, Any]:
        rows = states[(sid, k)]
        first = rows[0]
        return {
            "robot": [first["robot_x"], first["robot_y"]],
            "held": first["held"],
            "held_above": first["held_above"],
            "stirred": sorted(r["object_id"] for r in rows if r["stirred"]),
            "objects": {
                r["object_id"]: {"pose": [r["x"], r["y"], r["z"]], "support": r["support"], "relation": r["relation"]}
                for r in rows
            },
        }

    def obj_record(oid: str) -> dict[str, Any]:
        o = objects[oid]
        return {
            "id": oid, "name": o["name"], "category": o["category"], "size": [o["w"], o["l"], o["h"]],
            "levels": list(o["levels"]),
            "attributes": {a: (int(o[a]) if a in BINARY_ATTRIBUTES else o[a]) for a in ATTRIBUTE_NAMES},
        }

    out = []
    for seq in sorted(tables["sequences"].to_pylist(), key=lambda s: (s["source"], s["line"])):
        sid, scen = seq["sequence_id"], scenarios[seq["scenario_id"]]
        rows = sorted(steps.get(sid, []), key=lambda r: r["step"])
        out.append({
            "format": FORMAT,
            "demo_id": sid,
            "scenario_id": seq["scenario_id"],
            "env_id": scen["env_id"],
            "task": {"name": scen["task"], "args": [a for a in (scen["arg1"], scen["arg2"]) if a is not None]},
            "objects": [obj_record(o) for o in env_objects[scen["env_id"]]],
            "steps": [
                {"primitive": r["primitive"], "args": [a for a in (r["arg1"], r["arg2"]) if a is not None],
                 "state": state(sid, r["step"])}
                for r in rows
            ],
            "final_state": state(sid, seq["n_steps"]),
        })
    return out
