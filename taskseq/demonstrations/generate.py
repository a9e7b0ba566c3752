"""Write the benchmark's demonstrations as JSON Lines, one file per environment."""

from __future__ import annotations

from pathlib import Path

from ..runtime.atomic import atomic_directory
from ..settings import Generate
from ..sim.procedural import DrawReport
from ..sim.scenarios import Scenario, world_scenarios
from .records import dumps, scenario_records


def write_demonstrations(scenarios: list[Scenario], output: Path | str) -> dict[str, int]:
    """Replace `output` with one `<env>.jsonl` per environment; returns lines per file."""
    by_env: dict[str, list[str]] = {}
    for record in scenario_records(scenarios):
        by_env.setdefault(record["env_id"], []).append(dumps(record))
    with atomic_directory(output) as tmp:
        for env_id, lines in by_env.items():
            (tmp / f"{env_id}.jsonl").write_text("\n".join(lines) + "\n", encoding="utf-8")
    return {env_id: len(lines) for env_id, lines in by_env.items()}


def generate(world: Generate, output: Path | str) -> tuple[dict[str, int], DrawReport]:
    """Write the logs of `world`; returns lines per file and what drawing its rooms cost."""
    scenarios, report = world_scenarios(world)
    return write_demonstrations(scenarios, output), report
