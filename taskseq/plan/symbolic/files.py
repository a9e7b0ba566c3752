"""data/pddl/: the domain, a problem per scenario and its shortest plan, in the usual IPC formats."""

from __future__ import annotations

import re
import shutil
from pathlib import Path

from ...runtime.atomic import atomic_directory
from .problem import DOMAIN_PATH, build_problem
from .roles import demonstrated_roles
from .sat import solve


def file_stem(scenario_id: str) -> str:
    """`env01/pour_to(obj27,obj14)` -> `env01_pour_to_obj27_obj14`."""
    return re.sub(r"_+", "_", re.sub(r"[^A-Za-z0-9]+", "_", scenario_id)).strip("_")


def write_pddl(scenarios: dict, output: Path | str, horizon: int = 12) -> dict[str, int]:
    """Domain, problems (goals from the demonstrations) and plans; returns counts."""
    counts = {"problems": 0, "plans": 0, "no_plan": 0}
    with atomic_directory(output) as tmp:
        shutil.copyfile(DOMAIN_PATH, tmp / "domain.pddl")
        (tmp / "problems").mkdir()
        (tmp / "plans").mkdir()
        for sid in sorted(scenarios):
            sc = scenarios[sid]
            stem = file_stem(sid)
            problem = build_problem(stem, sc.initial, sc.task, demonstrated_roles(sc.task, sc.demonstrations[0]))
            (tmp / "problems" / f"{stem}.pddl").write_text(problem.to_pddl())
            counts["problems"] += 1
            result = solve(problem, horizon=horizon)
            if result.plan is None:
                counts["no_plan"] += 1
                (tmp / "plans" / f"{stem}.plan").write_text(f"; {result.message()}\n")
                continue
            lines = [a.pddl() for a in result.plan]
            lines.append(f"; {len(result.plan)} steps, shortest; {result.n_actions} ground actions")
            (tmp / "plans" / f"{stem}.plan").write_text("\n".join(lines) + "\n")
            counts["plans"] += 1
    return counts
