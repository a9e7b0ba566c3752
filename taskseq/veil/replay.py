"""Every sequence of the release replayed from its environment's initial state, under one rule for noisy data.

The rule (fixed before anything was measured; docs/veil.md gives the counts): people's sequences hold steps the
domain refuses. A step that names an object its environment does not hold (reason `unknown object`), or whose
precondition fails in the state reached so far (reason: the failed literal's code, e.g. `not near`,
`not grasping`, `hands full`), is skipped: the state stays as it was, the sequence keeps its other steps, and
the step is counted by its reason. No sequence is dropped: one with no action in the release has status
`no steps`, one whose every step was skipped `no executable step`, the others `complete` or `partial`.
A line of no domain action is not noise but an error of the release (`grounding.ActionError`); the importer
reports it before replaying.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass

from .grounding import ARITIES, ActionIndex, Step, UnknownObject
from .release import Catalog, Environment, Point, Release
from .state import State, StepRefused, initial_state, step

KEPT = "kept"
SKIPPED = "skipped"
UNKNOWN_OBJECT = "unknown object"
SEQUENCE_STATUSES = ("complete", "partial", "no executable step", "no steps")


@dataclass(frozen=True)
class StepRecord:
    """One action line of a sequence and what the replay did with it. `step` is None only for a line naming an
    unknown object; `kept_index` is the step's index among the kept steps (None when skipped)."""

    t: int
    raw: str
    segment: int
    line: int
    step: Step | None
    action: str | None
    status: str
    reason: str | None
    detail: str | None
    kept_index: int | None


@dataclass(frozen=True)
class Replay:
    """One replayed sequence: `states[i]` is the state before `kept[i]`, `final` the state after the last."""

    point: Point
    initial: State
    states: tuple[State, ...]
    kept: tuple[Step, ...]
    records: tuple[StepRecord, ...]
    final: State

    @property
    def status(self) -> str:
        if not self.records:
            return "no steps"
        if not self.kept:
            return "no executable step"
        return "complete" if len(self.kept) == len(self.records) else "partial"

    @property
    def skipped(self) -> Counter[str]:
        return Counter(r.reason for r in self.records if r.status == SKIPPED)


def replay_point(point: Point, env: Environment, catalog: Catalog, index: ActionIndex,
                 arities: Mapping[str, tuple[int, ...]] = ARITIES) -> Replay:
    """Replay one sequence under the module's rule. Lines of no domain action raise `grounding.ActionError`."""
    names = env.names
    state = start = initial_state(env, catalog)
    states: list[State] = []
    kept: list[Step] = []
    records: list[StepRecord] = []
    for t, raw in enumerate(point.actions):
        common = {"t": t, "raw": raw.text, "segment": raw.segment, "line": raw.line}
        try:
            g = index.ground(raw.text, names, arities)
        except UnknownObject as err:
            records.append(StepRecord(**common, step=None, action=None, status=SKIPPED, reason=UNKNOWN_OBJECT,
                                      detail=f"{raw.text}: {err}", kept_index=None))
            continue
        after = step(state, g.action, g.args)
        if isinstance(after, StepRefused):
            records.append(StepRecord(**common, step=g.step, action=g.action.name, status=SKIPPED,
                                      reason=after.code, detail=after.reason, kept_index=None))
            continue
        records.append(StepRecord(**common, step=g.step, action=g.action.name, status=KEPT, reason=None,
                                  detail=None, kept_index=len(kept)))
        states.append(state)
        kept.append(g.step)
        state = after
    return Replay(point, start, tuple(states), tuple(kept), tuple(records), state)


def replay_release(release: Release, points: Iterable[Point] | None = None,
                   progress: Callable[[Iterable[Point]], Iterable[Point]] | None = None) -> list[Replay]:
    """Replay `points` (default: all of the release) in order; `progress` may wrap them (e.g. tqdm)."""
    index = ActionIndex(release.domain)
    todo = list(release.points if points is None else points)
    arities = {k: tuple(len(p) for p in v) for k, v in release.instructions.items()}
    return [replay_point(p, release.environments[p.env_id], release.catalog, index, arities)
            for p in (progress(todo) if progress else todo)]
