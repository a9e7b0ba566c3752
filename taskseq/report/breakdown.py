"""One method's closed-loop programs per world seed and per environment or task: where a world's drop is.

A mean over world seeds hides which rooms and tasks one world loses. This table
keeps each seed apart: per group (an environment, the part of a scenario id
before `/`, or a task) the share of programs equal to a demonstration (the
sequence arg figure of Table I) and the most frequent other kind of program,
read from each world's `crossval_sequences.csv`. "Other success" counts as a
kind here: such a program reaches the goal but is not the demonstration, so it
lowers sequence arg as much as a failure does.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass
from typing import Any

from ..evaluate.failures import KINDS

GROUPS = ("environment", "task")


@dataclass(frozen=True)
class GroupOutcome:
    """A method's programs of one group in one world: how many, how many exact, the leading other kind."""

    world_seed: int
    group: str
    programs: int
    exact: int
    leading: str | None  # the most frequent kind besides exact (ties in `KINDS` order); None if all are exact
    leading_programs: int

    @property
    def sequence_arg(self) -> float:
        return 100.0 * self.exact / self.programs


def _group_of(row: dict[str, Any], by: str) -> str:
    if by == "environment":
        return str(row["scenario"]).split("/", 1)[0]
    if by == "task":
        return str(row["task"])
    raise ValueError(f"group programs by one of {GROUPS}, not {by!r}")


def _exact(row: dict[str, Any], seed: int) -> bool:
    value = str(row["arg_correct"])
    if value not in ("0", "1"):
        raise ValueError(f"world seed {seed}: program {row['scenario']} of {row['method']}: arg_correct is "
                         f"{value!r}, not 0 or 1")
    return value == "1"


def group_outcomes(programs: dict[int, list[dict[str, Any]]], method: str, by: str) -> list[GroupOutcome]:
    """Per world seed and group, `method`'s programs from `crossval_sequences.csv` rows (seed -> rows).

    Seeds in the given order, groups sorted; a seed where `method` ran no program has no rows.
    """
    out = []
    for seed, rows in programs.items():
        mine = [r for r in rows if r["method"] == method]
        for group in sorted({_group_of(r, by) for r in mine}):
            these = [r for r in mine if _group_of(r, by) == group]
            kinds = Counter(str(r["failure"]) for r in these)
            unknown = set(kinds) - set(KINDS)
            if unknown:
                raise ValueError(f"world seed {seed}, {method}, {group}: unknown program kinds {sorted(unknown)}")
            exact = sum(_exact(r, seed) for r in these)
            others = [(kinds[k], -i, k) for i, k in enumerate(KINDS) if k != "exact" and kinds[k] > 0]
            n, _, leading = max(others) if others else (0, 0, None)
            out.append(GroupOutcome(seed, group, len(these), exact, leading, n))
    return out


def breakdown_markdown(outcomes: list[GroupOutcome], label: str, by: str) -> str:
    """A table with one row per group and one column per world seed; empty text when there is no outcome."""
    if not outcomes:
        return ""
    seeds = list(dict.fromkeys(o.world_seed for o in outcomes))
    cell = {(o.group, o.world_seed): o for o in outcomes}
    lines = [f"{label} per {by} and world seed: sequence arg, % (exact programs / programs), and the most frequent "
             "other kind (programs).", "",
             f"| {by} | " + " | ".join(f"world {s}" for s in seeds) + " |", "|---|" + "---|" * len(seeds)]
    for group in sorted({o.group for o in outcomes}):
        cells = []
        for s in seeds:
            o = cell.get((group, s))
            if o is None:
                cells.append("")
                continue
            text = f"{o.sequence_arg:.1f} ({o.exact}/{o.programs})"
            cells.append(text + (f", {o.leading.replace('_', ' ')} {o.leading_programs}" if o.leading else ""))
        lines.append(f"| {group} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"
