"""Validated logs to Parquet tables with explicit schemas, and back.

Tables (one Parquet file each):
  objects       one row per distinct object: size, levels, the 14 attributes; where environments of a folder
                describe one object id differently (two versions of a room in people's demonstrations), one row
                per object of each environment, with its `env_id` first
  environments  which objects each environment holds, in log order
  scenarios     environment + task + task arguments, with its number of sequences
  sequences     one row per demonstration, with the file and line it came from; with `participant` and
                `corrected` columns only where a record carries these fields (people's demonstrations)
  steps         one row per primitive executed
  states        the world before every step and after the last, one row per object
"""

from __future__ import annotations

import json
import re
from collections import Counter
from pathlib import Path
from typing import Any

import pyarrow as pa
import pyarrow.parquet as pq

from ..runtime.atomic import atomic_directory
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
# the optional fields a record of `taskseq serve` may carry, as columns of the sequences table: each column is written
# only where some record of the input carries its field (null where a record does not), so the tables of the
# benchmark's logs, which carry neither, keep their schema and bytes
PERSON_COLUMNS: dict[str, pa.DataType] = {"participant": STR, "corrected": pa.list_(I32)}
# the objects table where an object id means different objects in different environments
OBJECTS_BY_ENVIRONMENT = pa.schema([("env_id", STR), *SCHEMAS["objects"]])


def sequences_schema(columns: list[str] | tuple[str, ...]) -> pa.Schema:
    """The sequences table's schema with those of `PERSON_COLUMNS` named in `columns`, in their fixed order."""
    return pa.schema([*SCHEMAS["sequences"], *((c, t) for c, t in PERSON_COLUMNS.items() if c in columns)])


def _arg(args: list[str], i: int) -> str | None:
    return args[i] if len(args) > i else None


class _Collector:
    """Accumulates rows and checks what only shows across records.

    An environment always describes its objects alike, in every record of it. `one_catalog` asks more, as the
    benchmark's logs promise: an object id names one object in every environment (its objects come from one
    catalog, so a difference is a bug of the generator). People's rooms promise less: a person saves a room file
    again with a mug made larger, and its records go to a new environment (the id carries the file's hash) in
    which the same id describes another object.
    """

    def __init__(self, one_catalog: bool = True) -> None:
        self.one_catalog = one_catalog
        self.rows: dict[str, list[dict[str, Any]]] = {t: [] for t in TABLES}
        self.objects: dict[str, tuple[dict[str, Any], str]] = {}
        self.envs: dict[str, tuple[list[dict[str, Any]], str]] = {}  # its objects' descriptions, first seen where
        self.scenarios: dict[str, dict[str, Any]] = {}
        self.sequence_ids: dict[str, str] = {}

    def checkpoint(self) -> tuple[Any, ...]:
        """What `restore` needs to undo every record added after this call."""
        return ({t: len(r) for t, r in self.rows.items()}, dict(self.objects), dict(self.envs),
                {k: dict(v) for k, v in self.scenarios.items()}, dict(self.sequence_ids))

    def restore(self, checkpoint: tuple[Any, ...]) -> None:
        lengths, self.objects, self.envs, self.scenarios, self.sequence_ids = checkpoint
        for t, n in lengths.items():
            del self.rows[t][n:]

    def add(self, item: LoggedRecord) -> None:
        rec = item.record
        where = f"{item.path.name}:{item.line}"

        def fail(field: str, message: str) -> None:
            raise LogError(item.path, item.line, field, message)

        if rec["demo_id"] in self.sequence_ids:
            fail("demo_id", f"{rec['demo_id']!r} already used at {self.sequence_ids[rec['demo_id']]}")
        self.sequence_ids[rec["demo_id"]] = where
        ids = [o["id"] for o in rec["objects"]]
        env = self.envs.get(rec["env_id"])
        if env is None:
            self.envs[rec["env_id"]] = (rec["objects"], where)
        elif [o["id"] for o in env[0]] != ids:
            fail("objects", f"environment {rec['env_id']} holds other objects at {env[1]}")
        else:
            for i, (obj, seen) in enumerate(zip(rec["objects"], env[0], strict=True)):
                if obj != seen:
                    fail(f"objects[{i}]", f"object {obj['id']} differs from its description in environment "
                                          f"{rec['env_id']} at {env[1]}")
        for i, obj in enumerate(rec["objects"]):
            first = self.objects.setdefault(obj["id"], (obj, where))
            if self.one_catalog and first[0] != obj:
                fail(f"objects[{i}]", f"object {obj['id']} differs from its description at {first[1]} (in the "
                                      "benchmark's logs an object id names one object in every environment; a folder "
                                      "of people's demonstrations, where two versions of a room may describe it "
                                      "differently, ingests with --people)")
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
             "n_steps": len(rec["steps"]), **{c: rec[c] for c in PERSON_COLUMNS if c in rec}}
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
        """The tables; the objects table per environment only where an object id means different objects."""
        one_each = all(obj == self.objects[obj["id"]][0] for objects, _ in self.envs.values() for obj in objects)
        if one_each:
            described = [(None, self.objects[oid][0]) for oid in sorted(self.objects)]
        else:
            described = [(env_id, obj) for env_id in sorted(self.envs)
                         for obj in sorted(self.envs[env_id][0], key=lambda o: o["id"])]
        for env_id, obj in described:
            w, l, h = obj["size"]  # noqa: E741
            self.rows["objects"].append(
                {**({} if env_id is None else {"env_id": env_id}), "object_id": obj["id"], "name": obj["name"],
                 "category": obj["category"], "w": w, "l": l, "h": h, "levels": obj["levels"],
                 **{a: float(obj["attributes"][a]) for a in ATTRIBUTE_NAMES}}
            )
        for env_id in sorted(self.envs):
            for pos, obj in enumerate(self.envs[env_id][0]):
                self.rows["environments"].append({"env_id": env_id, "position": pos, "object_id": obj["id"]})
        for scen_id in sorted(self.scenarios):
            s = self.scenarios[scen_id]
            self.rows["scenarios"].append(
                {"scenario_id": scen_id, **{k: s[k] for k in ("env_id", "task", "arg1", "arg2", "n_sequences")}}
            )
        carried = [c for c in PERSON_COLUMNS if any(c in row for row in self.rows["sequences"])]
        schemas = {**SCHEMAS, "objects": SCHEMAS["objects"] if one_each else OBJECTS_BY_ENVIRONMENT,
                   "sequences": sequences_schema(carried)}
        return {t: pa.Table.from_pylist(self.rows[t], schema=schemas[t]) for t in TABLES}


def load_logs(input_dir: Path | str) -> tuple[dict[str, pa.Table], list[LoggedRecord]]:
    """Validate every record of every log file; the first problem raises `LogError`.

    For the pipeline's own logs (the generated worlds): any problem in them is a bug to see at once."""
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


def load_people_logs(folder: Path | str) -> tuple[dict[str, pa.Table], list[LoggedRecord], list[LogError]]:
    """The records of a folder of people's demonstrations, and the problem of each file left out.

    A file with a problem (not JSON, a record failing the schema or the replay, a record at odds with an earlier
    file) is left out whole, where it is, and the others are used: one bad file, a log edited by hand or cut
    short by a full disk, must not strand every other person's work. Each environment describes its objects
    alike, but one object id may mean different objects in different environments (two versions of a room)."""
    collector = _Collector(one_catalog=False)
    records: list[LoggedRecord] = []
    skipped: list[LogError] = []
    for path in log_files(Path(folder)):
        checkpoint, kept = collector.checkpoint(), len(records)
        try:
            for item in read_records(path):
                check_record(item)
                collector.add(item)
                records.append(item)
        except LogError as err:
            collector.restore(checkpoint)
            del records[kept:]
            skipped.append(err)
    return collector.tables(), records, skipped


# the demo_id `taskseq serve` gives a record (`serve.writer.person_record`): the scenario, then the participant (or
# "person") and 12 random hex digits, where the scripted demonstrator's is the scenario and a sequence number
PERSON_DEMO_ID = re.compile(r"/[A-Za-z0-9][A-Za-z0-9_-]{0,63}-[0-9a-f]{12}$")


def is_person_record(record: dict[str, Any]) -> bool:
    """Whether a record was written by `taskseq serve` (or the teaching script through its writer): it carries a
    participant, the corrections of assist mode, or the writer's demo_id; the scripted demonstrator's never does."""
    demo_id = record.get("demo_id")
    return ("participant" in record or "corrected" in record
            or (isinstance(demo_id, str) and PERSON_DEMO_ID.search(demo_id) is not None))


def people_folder(folder: Path | str) -> bool:
    """Whether `folder` is a folder of people's demonstrations: at least one record was written by `taskseq serve`
    and none by the scripted demonstrator.

    `taskseq ingest` reads such a folder the people's way (a file with a problem is left out) without `--people`,
    while the benchmark's generated logs, and any folder mixing both, keep failing at their first problem. Lines
    that do not parse say nothing either way (the loader names them); the first benchmark record decides at once,
    so a benchmark folder costs one line to recognise."""
    person = False
    for path in sorted(Path(folder).glob("*.jsonl")):
        with open(path, encoding="utf-8", errors="replace") as fh:
            for text in fh:
                try:
                    record = json.loads(text)
                except ValueError:
                    continue
                if not isinstance(record, dict) or "demo_id" not in record:
                    continue
                if not is_person_record(record):
                    return False
                person = True
    return person


def dataset_summary(tables: dict[str, pa.Table]) -> dict[str, Any]:
    steps = tables["steps"].to_pylist()
    seqs = tables["sequences"].to_pylist()
    scen = {s["scenario_id"]: s["task"] for s in tables["scenarios"].to_pylist()}
    seq_task = {s["sequence_id"]: scen[s["scenario_id"]] for s in seqs}
    lengths = [s["n_steps"] for s in seqs]
    return {
        "environments": len(set(tables["environments"].column("env_id").to_pylist())),
        "objects": _distinct_objects(tables["objects"]),
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


def _distinct_objects(objects: pa.Table) -> int:
    """How many different objects the objects table describes (one row each, unless it is per environment)."""
    if "env_id" not in objects.column_names:
        return objects.num_rows
    return len({json.dumps(row, sort_keys=True) for row in objects.drop_columns(["env_id"]).to_pylist()})


def write_tables(tables: dict[str, pa.Table], output: Path | str) -> None:
    """Replace `output` with one Parquet file per table; bytes depend only on the data."""
    with atomic_directory(output) as tmp:
        for name, table in tables.items():
            pq.write_table(table, tmp / f"{name}.parquet", compression="zstd", write_statistics=False)


def read_tables(directory: Path | str) -> dict[str, pa.Table]:
    """The tables `write_tables` wrote; the objects table as it was written, per environment or not, and the
    sequences table with the person's columns it was written with."""
    directory = Path(directory)
    per_env = pq.read_schema(directory / "objects.parquet").names[0] == "env_id"
    sequences = sequences_schema(pq.read_schema(directory / "sequences.parquet").names)
    schemas = {**SCHEMAS, "objects": OBJECTS_BY_ENVIRONMENT if per_env else SCHEMAS["objects"], "sequences": sequences}
    return {t: pq.read_table(directory / f"{t}.parquet", schema=schemas[t]) for t in TABLES}


def records_from_tables(tables: dict[str, pa.Table]) -> list[dict[str, Any]]:
    """Rebuild the log records from the tables, in their original file and line order, with the `participant` and
    `corrected` of the records that carried them."""
    objects = {(o.get("env_id"), o["object_id"]): o for o in tables["objects"].to_pylist()}
    per_env = "env_id" in tables["objects"].column_names
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

    def obj_record(env_id: str, oid: str) -> dict[str, Any]:
        o = objects[env_id if per_env else None, oid]
        return {
            "id": oid, "name": o["name"], "category": o["category"], "size": [o["w"], o["l"], o["h"]],
            "levels": list(o["levels"]),
            "attributes": {a: (int(o[a]) if a in BINARY_ATTRIBUTES else o[a]) for a in ATTRIBUTE_NAMES},
        }

    out = []
    for seq in sorted(tables["sequences"].to_pylist(), key=lambda s: (s["source"], s["line"])):
        sid, scen = seq["sequence_id"], scenarios[seq["scenario_id"]]
        rows = sorted(steps.get(sid, []), key=lambda r: r["step"])
        record = {
            "format": FORMAT,
            "demo_id": sid,
            "scenario_id": seq["scenario_id"],
            "env_id": scen["env_id"],
            "task": {"name": scen["task"], "args": [a for a in (scen["arg1"], scen["arg2"]) if a is not None]},
            "objects": [obj_record(scen["env_id"], o) for o in env_objects[scen["env_id"]]],
            "steps": [
                {"primitive": r["primitive"], "args": [a for a in (r["arg1"], r["arg2"]) if a is not None],
                 "state": state(sid, r["step"])}
                for r in rows
            ],
            "final_state": state(sid, seq["n_steps"]),
        }
        for column in PERSON_COLUMNS:
            if seq.get(column) is not None:
                record[column] = seq[column]
        out.append(record)
    return out
