"""The benchmark as the evaluation reads it, decoded once from the Parquet tables.

The same `Scenario` type the simulator generates (`sim.scenarios`): where a
scenario starts, its task and its demonstrations; plus every demonstrated
world state, which teacher-forced baselines plan from.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..sim.primitives import Action
from ..sim.scenarios import Scenario
from ..sim.state import WorldState
from .ingest import TABLES, read_tables, records_from_tables
from .records import parse_record, state_from_dict


@dataclass(frozen=True)
class Benchmark:
    records: list[dict[str, Any]]  # the log records, in file and line order
    scenarios: dict[str, Scenario]  # by scenario id
    states: dict[tuple[str, int], WorldState]  # (sequence id, step) -> the state before that step; the last is final
    actions: dict[str, tuple[Action, ...]]  # sequence id -> its actions

    @classmethod
    def from_records(cls, records: list[dict[str, Any]]) -> Benchmark:
        first: dict[str, tuple[str, Any, WorldState]] = {}
        demos: dict[str, list[tuple[Action, ...]]] = {}
        states, actions = {}, {}
        for rec in records:
            specs, task, acts = parse_record(rec)
            sid = rec["scenario_id"]
            demos.setdefault(sid, []).append(tuple(acts))
            actions[rec["demo_id"]] = tuple(acts)
            for k, st in enumerate([s["state"] for s in rec["steps"]] + [rec["final_state"]]):
                states[(rec["demo_id"], k)] = state_from_dict(specs, st)
            if sid not in first:
                first[sid] = (rec["env_id"], task, states[(rec["demo_id"], 0)])
        scenarios = {sid: Scenario(env, task, initial, tuple(demos[sid]))
                     for sid, (env, task, initial) in first.items()}
        for sid, sc in scenarios.items():
            if sc.id != sid:
                raise ValueError(f"scenario {sid!r}: its environment and task name it {sc.id!r}")
        return cls(records, scenarios, states, actions)


def load_benchmark(processed: Path | str) -> Benchmark:
    """The benchmark from the Parquet tables that `taskseq ingest` wrote.

    Decoded once per process while the tables stay as they are (their names,
    sizes and modification times): a stage that runs several experiments on a
    world reads it for each, and decoding took about 0.2 s every time. Nothing
    changes a `Benchmark` once built, so the callers share it.
    """
    folder = Path(processed).resolve()
    try:
        key = (folder, tuple((t, s.st_size, s.st_mtime_ns) for t in TABLES
                             if (s := (folder / f"{t}.parquet").stat())))
    except OSError:  # a missing table: read_tables names it
        return Benchmark.from_records(records_from_tables(read_tables(processed)))
    if key not in _LOADED:
        if len(_LOADED) >= 4:  # a stage reads two worlds at most
            _LOADED.clear()
        _LOADED[key] = Benchmark.from_records(records_from_tables(read_tables(folder)))
    return _LOADED[key]


_LOADED: dict[tuple[Path, tuple[tuple[str, int, int], ...]], Benchmark] = {}
