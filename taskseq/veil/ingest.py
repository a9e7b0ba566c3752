"""`taskseq veil import`: check a VEIL-500 release folder, replay its sequences and write Parquet tables.

Everything is checked before anything is written: every file read (`release.read_release`), every action line
grounded to a domain action (`grounding.ActionIndex.parse`), every instruction of `ControllerInstructions.xml` a
known verb. The first problem raises `VeilFormatError` naming the file, line and element. Then the sequences are
replayed (`replay`, its rule for noisy data) and the tables written at once (`taskseq.io.atomic_directory`),
their bytes depending only on the release.

Tables (one Parquet file each; docs/veil.md):
  sequences  one row per <point> of data.xml: environment, room, file number, objective, counts, status
  steps      one row per action line: raw text, learner step (verb, a1, a2), domain action, status, reason
  objects    one row per object of each environment: category, affordances, position, initial states
and `import.json`: counts of sequences by status and of skipped steps by reason.
"""

from __future__ import annotations

import json
from collections import Counter
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

import pyarrow as pa
import pyarrow.parquet as pq

from ..runtime.atomic import atomic_directory
from .grounding import ARITIES, ActionError, ActionIndex
from .release import Release, read_release
from .replay import KEPT, SEQUENCE_STATUSES, SKIPPED, Replay, replay_release
from .state import initial_state
from .xmltree import VeilFormatError

STR, F64, I32, BOOL = pa.string(), pa.float64(), pa.int32(), pa.bool_()
_NAME_VALUE = pa.struct([("name", STR), ("value", STR)])

SCHEMAS: dict[str, pa.Schema] = {
    "sequences": pa.schema(
        [("seq_id", STR), ("environment", STR), ("room", STR), ("env_number", I32), ("objective", STR),
         ("text", STR), ("n_segments", I32), ("n_steps", I32), ("n_kept", I32), ("n_skipped", I32),
         ("status", STR), ("line", I32)]
    ),
    "steps": pa.schema(
        [("seq_id", STR), ("t", I32), ("segment", I32), ("raw", STR), ("verb", STR), ("a1", STR), ("a2", STR),
         ("action", STR), ("status", STR), ("reason", STR), ("detail", STR), ("kept_index", I32), ("line", I32)]
    ),
    "objects": pa.schema(
        [("environment", STR), ("room", STR), ("env_number", I32), ("name", STR), ("category", STR),
         ("catalogued", BOOL), ("affordances", pa.list_(STR)), ("x", F64), ("y", F64), ("z", F64),
         ("rx", F64), ("ry", F64), ("rz", F64), ("true_states", pa.list_(STR)),
         ("other_states", pa.list_(_NAME_VALUE))]
    ),
}
TABLES = tuple(SCHEMAS)
SUMMARY = "import.json"


def validate(root: Path | str) -> Release:
    """Read the release and check every action line against the domain; the first problem raises
    `VeilFormatError`."""
    release = read_release(root)
    instructions = Path(root) / "ControllerInstructions.xml"
    for name in release.instructions:
        if name not in ARITIES:
            raise VeilFormatError(instructions, 0, "<Instruction>",
                                  f"instruction {name!r} is no verb the importer knows ({', '.join(ARITIES)})")
    index = ActionIndex(release.domain)
    arities = {k: tuple(len(p) for p in v) for k, v in release.instructions.items()}
    data = Path(root) / "data.xml"
    for p in release.points:
        for a in p.actions:
            try:
                index.parse(a.text, arities)
            except ActionError as err:
                raise VeilFormatError(data, a.line, "<action>", str(err)) from None
    return release


def _tables(release: Release, replays: list[Replay]) -> dict[str, pa.Table]:
    seqs, steps, objects = [], [], []
    for r in replays:
        p = r.point
        env = release.environments[p.env_id]
        seqs.append({"seq_id": p.seq_id, "environment": p.env_id, "room": env.room, "env_number": env.number,
                     "objective": p.objective, "text": p.text, "n_segments": p.n_segments,
                     "n_steps": len(r.records), "n_kept": len(r.kept), "n_skipped": len(r.records) - len(r.kept),
                     "status": r.status, "line": p.line})
        for rec in r.records:
            s = rec.step
            steps.append({"seq_id": p.seq_id, "t": rec.t, "segment": rec.segment, "raw": rec.raw,
                          "verb": s.verb if s else None, "a1": s.a1 if s else None, "a2": s.a2 if s else None,
                          "action": rec.action, "status": rec.status, "reason": rec.reason, "detail": rec.detail,
                          "kept_index": rec.kept_index, "line": rec.line})
    for env in release.environments.values():
        start = initial_state(env, release.catalog)
        for o in env.objects:
            info = start.world.objects[o.name]
            true_states = sorted(f[2] for f in start.facts if f[0] == "state" and f[1] == o.name)
            objects.append({"environment": env.env_id, "room": env.room, "env_number": env.number, "name": o.name,
                            "category": info.category, "catalogued": info.catalogued,
                            "affordances": sorted(info.affordances), "x": o.position[0], "y": o.position[1],
                            "z": o.position[2], "rx": o.rotation[0], "ry": o.rotation[1], "rz": o.rotation[2],
                            "true_states": true_states,
                            "other_states": [{"name": k, "value": v} for k, v in info.attributes]})
    rows = {"sequences": seqs, "steps": steps, "objects": objects}
    return {t: pa.Table.from_pylist(rows[t], schema=SCHEMAS[t]) for t in TABLES}


def summarize(release: Release, replays: list[Replay]) -> dict[str, Any]:
    """Counts of the import: sequences by status, steps kept and skipped by reason, by verb, and objects."""
    statuses = Counter(r.status for r in replays)
    records = [rec for r in replays for rec in r.records]
    skipped = Counter(rec.reason for rec in records if rec.status == SKIPPED)
    by_verb: dict[str, dict[str, int]] = {}
    for rec in records:
        verb = rec.step.verb if rec.step else rec.raw.split()[0].lower()
        entry = by_verb.setdefault(verb, {KEPT: 0, SKIPPED: 0})
        entry[rec.status] += 1
    objects = [o for env in release.environments.values() for o in env.objects]
    uncatalogued = sorted({release.catalog.category_of(o.name)[0] for o in objects
                           if release.catalog.category_of(o.name)[1] is None})
    return {
        "sequences": len(replays),
        "sequences_imported": sum(1 for r in replays if r.kept),
        "sequences_by_status": {s: statuses.get(s, 0) for s in SEQUENCE_STATUSES},
        "steps": len(records),
        "steps_kept": sum(len(r.kept) for r in replays),
        "steps_skipped": sum(skipped.values()),
        "skipped_by_reason": dict(sorted(skipped.items(), key=lambda kv: (-kv[1], kv[0]))),
        "steps_by_verb": dict(sorted(by_verb.items())),
        "environments": len(release.environments),
        "objects": len(objects),
        "categories_not_in_objects_xml": uncatalogued,
    }


NAMED_STATE = "a state the step needs"  # `not state S` and `state S` together: S is a name of the release's


def counts_without_names(summary: dict[str, Any]) -> dict[str, Any]:
    """The import's counts as a committed report may hold them: sequences by status and steps by reason, the reasons
    that name one of the release's states (`not state S`, `state S`) counted together, since the release's own names
    are never redistributed."""
    reasons: Counter[str] = Counter()
    for reason, n in summary["skipped_by_reason"].items():
        reasons[NAMED_STATE if reason.startswith(("state ", "not state ")) else reason] += n
    kept = ("sequences", "sequences_imported", "sequences_by_status", "steps", "steps_kept", "steps_skipped",
            "environments", "objects")
    return {**{k: summary[k] for k in kept},
            "skipped_by_reason": dict(sorted(reasons.items(), key=lambda kv: (-kv[1], kv[0])))}


def import_release(root: Path | str, output: Path | str,
                   progress: Callable[[Iterable[Any]], Iterable[Any]] | None = None) -> dict[str, Any]:
    """Validate, replay and write `output` (replaced whole, or left as it was when anything fails)."""
    release = validate(root)
    replays = replay_release(release, progress=progress)
    tables = _tables(release, replays)
    summary = summarize(release, replays)
    with atomic_directory(output) as tmp:
        for name, table in tables.items():
            pq.write_table(table, tmp / f"{name}.parquet", compression="zstd", write_statistics=False)
        (tmp / SUMMARY).write_text(json.dumps(summary, indent=2) + "\n", encoding="utf-8")
    return summary


def read_tables(directory: Path | str) -> dict[str, pa.Table]:
    return {t: pq.read_table(Path(directory) / f"{t}.parquet", schema=SCHEMAS[t]) for t in TABLES}


def format_summary(summary: dict[str, Any]) -> str:
    lines = [f"{summary['sequences_imported']} of {summary['sequences']} sequences imported "
             f"({', '.join(f'{k} {v}' for k, v in summary['sequences_by_status'].items())})",
             f"{summary['steps_kept']} of {summary['steps']} steps kept, {summary['steps_skipped']} skipped:"]
    lines += [f"  {n:5d}  {reason}" for reason, n in summary["skipped_by_reason"].items()]
    return "\n".join(lines)
