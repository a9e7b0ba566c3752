"""Shortest plans kept across runs: the SAT planner's answers in the `plans/` folder of the cache.

A plan is a pure function of the planning problem, the horizon, the solver
and the code that grounds, encodes and solves it. The symbolic baselines ask
for the same plans in several processes and stages: both baselines from the
same state where their goal objects agree, `crossval` and the paper-shaped
rooms of `scenes_world` from every demonstrated state of a world, `pddl`
from every first state. One solve (grounding, writing the clauses, SAT)
takes some 8 ms; reading an answer back takes a small fraction of that.

An entry is one JSON file: the plan's steps as action names and objects (the
ground actions are rebuilt from the problem) or none, with the horizon and
the number of ground actions. The key hashes the problem's content (its name
aside), the horizon, the solver, the source files of the SAT planner with all
they import (`runtime.sources`) and the versions of Python and python-sat. An entry that
cannot be read, or names an action the problem does not have, is solved
again (with a warning) and replaced. A miss is solved here even while
`runtime.cache.stored_only` is in force: a plan is never work to send elsewhere.
"""

from __future__ import annotations

import hashlib
import json
from functools import partial
from pathlib import Path

from ...runtime.atomic import atomic_file
from ...runtime.cache import Entries, versions
from ...runtime.sources import code_fingerprint
from .problem import GroundAction, Problem, ground_actions

FORMAT = "taskseq.plans/1"
PLANNER = "taskseq.plan.symbolic.sat"  # the module whose code (and what it imports) decides a plan
Answer = tuple[list[GroundAction] | None, int]  # the plan (None: none within the horizon), ground actions


class PlanCache(Entries):
    """A folder of the SAT planner's answers, `<key>.json` each."""

    kind = "plans"
    follows_stored_only = False

    def load(self, key: str, problem: Problem) -> Answer | None:
        """The answer stored under `key` with its ground actions rebuilt from `problem`; None if there is none or
        it cannot be read."""
        return self.read(key, partial(_parsed, problem), "solved again")

    def save(self, key: str, plan: list[GroundAction] | None, n_actions: int) -> None:
        """Store an answer under `key`, atomically (not one of the command's outputs)."""
        steps = None if plan is None else [[a.name, list(a.args)] for a in plan]
        with atomic_file(self.path(key), output=False) as tmp:
            Path(tmp).write_text(json.dumps({"format": FORMAT, "plan": steps, "n_actions": n_actions}),
                                 encoding="utf-8")


def plan_key(problem: Problem, horizon: int, solver: str) -> str:
    """sha256 of what decides a plan: the problem's objects (in order), facts and goal, the horizon, the solver,
    the planner's code and the versions of Python and python-sat."""
    content = {"format": FORMAT, "code": code_fingerprint(PLANNER), **versions("python-sat"),
               "objects": list(problem.objects), "statics": sorted(problem.statics), "init": sorted(problem.init),
               "goal": sorted(problem.goal), "horizon": horizon, "solver": solver}
    return hashlib.sha256(json.dumps(content).encode()).hexdigest()


def _parsed(problem: Problem, path: Path) -> Answer:
    entry = json.loads(path.read_text(encoding="utf-8"))
    if entry.get("format") != FORMAT:
        raise ValueError(f"format {entry.get('format')!r}, expected {FORMAT!r}")
    if entry["plan"] is None:
        return None, int(entry["n_actions"])
    actions = {(a.name, a.args): a for a in ground_actions(problem)}
    return [actions[(name, tuple(args))] for name, args in entry["plan"]], int(entry["n_actions"])
