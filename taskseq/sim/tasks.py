"""The five under-specified tasks and their goal tests."""

from __future__ import annotations

import re
from dataclasses import dataclass

from ..words import counted
from .state import INSIDE, WorldState

TASK_ARITY = {"stir": 1, "pick_and_place": 2, "pour": 1, "pour_to": 2, "throw_away": 1}
TASKS = tuple(TASK_ARITY)


@dataclass(frozen=True)
class Task:
    name: str
    args: tuple[str, ...]

    def __post_init__(self) -> None:
        if self.name not in TASK_ARITY:
            raise ValueError(f"unknown task {self.name!r}; known: {', '.join(TASKS)}")
        if len(self.args) != TASK_ARITY[self.name]:
            raise ValueError(f"task {self.name} takes {counted(TASK_ARITY[self.name], 'argument', spelled=True)}, "
                             f"got {len(self.args)}")

    def __str__(self) -> str:
        return f"{self.name}({','.join(self.args)})"

    @classmethod
    def parse(cls, text: str) -> Task:
        """Parse `pour_to(obj30,obj15)`."""
        m = re.fullmatch(r"\s*(\w+)\s*\(([^)]*)\)\s*", text)
        if not m:
            raise ValueError(f"cannot parse task {text!r}; expected e.g. pour(obj16)")
        args = tuple(a.strip() for a in m.group(2).split(",") if a.strip())
        return cls(m.group(1), args)

    def check_objects(self, state: WorldState) -> None:
        for a in self.args:
            if a not in state.specs:
                raise ValueError(f"task {self}: object {a} is not in this environment")


def goal_reached(task: Task, initial: WorldState, state: WorldState) -> bool:
    """Whether `state` satisfies the task, judged from what the world looks like now.

    `initial` is needed by `pour`, whose goal is relative: the liquid left the
    container it started in for a vessel.
    """
    a = task.args[0]
    if task.name == "stir":
        return a in state.stirred
    if task.name == "pick_and_place":
        return state.held != a and state.support.get(a, ("", ""))[0] == task.args[1]
    if task.name == "pour":
        now = state.container_of(a)
        return now is not None and now != initial.container_of(a) and state.specs[now].category != "bin"
    if task.name == "pour_to":
        return state.support.get(a) == (task.args[1], INSIDE)
    if task.name == "throw_away":
        parent = state.support.get(a)
        return state.held != a and parent is not None and state.specs[parent[0]].category == "bin"
    raise AssertionError(task.name)
