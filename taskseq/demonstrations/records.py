"""Demonstration records: the JSON Lines log format, to and from simulator objects.

One line is one demonstration: the environment's objects (size, attributes),
the task, every step with the full world state before it, and the final
state. `demonstration.schema.json` beside this file is the formal schema.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from ..runtime.cache import Digests
from ..sim.objects import BINARY_ATTRIBUTES, ObjectSpec, attributes_of_box
from ..sim.primitives import Action, execute
from ..sim.scenarios import Scenario
from ..sim.state import WorldState
from ..sim.tasks import Task

FORMAT = "taskseq.demonstration/1"
SCHEMA_PATH = Path(__file__).with_name("demonstration.schema.json")


def load_schema() -> dict[str, Any]:
    return json.loads(SCHEMA_PATH.read_text())


def state_to_dict(state: WorldState) -> dict[str, Any]:
    return {
        "robot": list(state.robot),
        "held": state.held,
        "held_above": state.held_above,
        "stirred": sorted(state.stirred),
        "objects": {
            o: {
                "pose": list(state.poses[o]),
                "support": state.support[o][0] if o in state.support else None,
                "relation": state.support[o][1] if o in state.support else None,
            }
            for o in state.specs
        },
    }


def state_from_dict(specs: dict[str, ObjectSpec], d: dict[str, Any]) -> WorldState:
    objects = d["objects"]
    return WorldState(
        specs=specs,
        poses={o: tuple(float(v) for v in objects[o]["pose"]) for o in specs},
        support={
            o: (objects[o]["support"], objects[o]["relation"]) for o in specs if objects[o]["support"] is not None
        },
        robot=(float(d["robot"][0]), float(d["robot"][1])),
        held=d["held"],
        held_above=d["held_above"],
        stirred=set(d["stirred"]),
    )


def spec_to_dict(spec: ObjectSpec) -> dict[str, Any]:
    return {
        "id": spec.id,
        "name": spec.name,
        "category": spec.category,
        "size": list(spec.size),
        "levels": list(spec.levels),
        "attributes": {k: (int(v) if k in BINARY_ATTRIBUTES else v) for k, v in spec.attributes().items()},
    }


def spec_from_dict(d: dict[str, Any]) -> ObjectSpec:
    flags = frozenset(f for f in BINARY_ATTRIBUTES if d["attributes"][f] == 1)
    return ObjectSpec(d["id"], d["name"], d["category"], tuple(float(v) for v in d["size"]), flags, tuple(d["levels"]))


def expected_attributes(d: dict[str, Any]) -> dict[str, float]:
    """The attributes an object record must carry, given its size and binary flags."""
    flags = {f for f in BINARY_ATTRIBUTES if d["attributes"].get(f) == 1}
    return attributes_of_box(tuple(d["size"]), flags)


def demonstration_record(scenario: Scenario, index: int) -> dict[str, Any]:
    """The log record of the `index`-th acceptable sequence of `scenario`."""
    state = scenario.initial
    steps = []
    for action in scenario.demonstrations[index]:
        steps.append({"primitive": action.primitive, "args": list(action.args), "state": state_to_dict(state)})
        state = execute(state, action)
    return {
        "format": FORMAT,
        "demo_id": f"{scenario.id}/{index + 1}",
        "scenario_id": scenario.id,
        "env_id": scenario.env_id,
        "task": {"name": scenario.task.name, "args": list(scenario.task.args)},
        "objects": [spec_to_dict(scenario.initial.specs[o]) for o in scenario.initial.specs],
        "steps": steps,
        "final_state": state_to_dict(state),
    }


def parse_record(record: dict[str, Any]) -> tuple[dict[str, ObjectSpec], Task, list[Action]]:
    """Simulator objects of a validated record."""
    specs = {d["id"]: spec_from_dict(d) for d in record["objects"]}
    task = Task(record["task"]["name"], tuple(record["task"]["args"]))
    actions = [Action(s["primitive"], tuple(s["args"])) for s in record["steps"]]
    return specs, task, actions


def dumps(record: dict[str, Any]) -> str:
    """One log line; the same record always gives the same bytes."""
    return json.dumps(record, separators=(",", ":"), allow_nan=False)


def scenario_records(scenarios: Iterable[Scenario]) -> list[dict[str, Any]]:
    """The log record of every acceptable sequence of every scenario, scenario by scenario: what `taskseq
    generate` writes for them, without files."""
    return [demonstration_record(s, i) for s in scenarios for i in range(len(s.demonstrations))]


_DIGESTS = Digests(100_000)


def state_digest(state: WorldState) -> bytes:
    """sha256 of a world state as a record writes it, its objects' descriptions included: what decides what a
    planner or the demonstrator does from it (kept per state object, `runtime.cache.Digests`)."""
    return _DIGESTS(state, lambda s: hashlib.sha256(json.dumps(
        [state_to_dict(s), [spec_to_dict(s.specs[o]) for o in sorted(s.specs)]]).encode()).digest())


def scenario_digest(scenario: Scenario) -> bytes:
    """sha256 of a scenario: its room, task, demonstrations and initial world (`state_digest`)."""
    return _DIGESTS(scenario, lambda s: hashlib.sha256(json.dumps(
        [s.env_id, str(s.task), [[str(a) for a in d] for d in s.demonstrations]]).encode()
        + state_digest(s.initial)).digest())
