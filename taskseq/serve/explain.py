"""Why each of the planner's proposals stands where it stands, in words a person reads beside the assist table.

A proposal's place comes from three things, each read here from the code
that decides it rather than described again: the model's score
(`StepScorer.ranked`), the lookahead of the shipped policy
(`plan.planner.lookahead`: of the best runnable steps it takes the first
whose imagined next steps break no safety rule), and the product's filter
(`product.runnable_first`: no step the simulator refuses, no unsafe step, no
`done` before the goal). The page shows the order the policy made; this
module replays the same checks to say why, so a step listed above a
better-scored one always carries the reason: the better one cannot run
here, or its imagined plan breaks a rule. Everything is said with the
objects' names, never their ids, and never Python's `None`.
"""

from __future__ import annotations

from dataclasses import dataclass

from ..features.context import StepContext, step_context
from ..learn.estimator import StepScorer
from ..plan.planner import DONE, LOOKAHEAD_DEPTH, LeadsBack, Ranked, best_runnable
from ..product import in_names
from ..sim.primitives import Action, PreconditionError, execute
from ..sim.safety import violations
from ..sim.state import WorldState
from ..sim.tasks import Task, goal_reached
from .rules import refusal, unsafe_reason

Y = tuple[int, int, int]
SHOWN_REASONS = 3  # steps that cannot run named per row; the rest are counted


def _loop(leads: str) -> str:
    """Why a step that closes a loop is passed over, `leads` saying whose step and how ("it leads")."""
    return (f"{leads} back to where this task already was, with the same last two steps, from where the planner "
            "would go round the same loop")


class Why(str):
    """Why a proposal is where it is: the text (its clauses joined by "; "), with the clauses themselves in `parts`,
    so that a page can show the first and fold the rest (the assist table does, for a long one)."""

    parts: tuple[str, ...]

    def __new__(cls, parts: list[str]) -> Why:
        why = super().__new__(cls, "; ".join(parts))
        why.parts = tuple(parts)
        return why


@dataclass(frozen=True)
class Imagined:
    """The plan the lookahead imagines after a step: each imagined step with the world before it (the step
    itself first), and whether one of them breaks a safety rule (then the last one does)."""

    steps: list[tuple[WorldState, Action]]
    harmful: bool

    def text(self) -> str:
        """`move_close(glass), grasp(milk_carton), then follow_traj_pour(...), which breaks ...` in names."""
        words = [in_names(action, state.specs) for state, action in self.steps]
        if not self.harmful:
            return ", ".join(words)
        state, action = self.steps[-1]
        lead = f"take {', '.join(words[:-1])}, then " if len(words) > 1 else ""
        return f"{lead}{words[-1]}, where {unsafe_reason(state, action)}"


def imagine(planner: StepScorer, task: Task, start: WorldState, state: WorldState, history: list[Action],
            action: Action, depth: int = LOOKAHEAD_DEPTH) -> Imagined:
    """The steps `plan.planner.lookahead` imagines after taking `action`, step for step as its `harms` walks them:
    from the state the step leads to, each next step the planner's best runnable one, until `done`, a world where
    the task's goal holds (judged against `start`, where the task began; the robot stops there), a step that breaks
    a safety rule, or `depth` steps."""
    steps: list[tuple[WorldState, Action]] = []
    if action.primitive == DONE:  # stopping imagines nothing and counts as safe
        return Imagined([(state, action)], False)
    for _ in range(depth):
        steps.append((state, action))
        if violations(state, action):
            return Imagined(steps, True)
        state = execute(state, action)
        if goal_reached(task, start, state):
            steps.append((state, Action(DONE)))
            return Imagined(steps, False)
        history = [*history[-1:], action]
        ctx = step_context(state, task, history)
        action = best_runnable(planner, ctx, state)
        if action.primitive == DONE:
            steps.append((state, action))
            return Imagined(steps, False)
    steps.append((state, action))
    return Imagined(steps, bool(violations(state, action)))


def _why_not_runnable(task: Task, initial: WorldState, state: WorldState, action: Action) -> str | None:
    """Why the page would not take `action` here (in names), or None when it would."""
    if action.primitive == DONE:
        if goal_reached(task, initial, state):
            return None
        return f"done: the goal of {in_names(task, state.specs)} does not hold yet"
    try:
        execute(state, action)
    except PreconditionError as err:
        return f"{in_names(action, state.specs)}: {refusal(state, err)} (check: {err.check})"
    reason = unsafe_reason(state, action)
    return None if reason is None else f"{in_names(action, state.specs)}: {reason}"


def explain(planner: StepScorer, policy: str, task: Task, initial: WorldState, ctx: StepContext, state: WorldState,
            offered: Ranked, closes_loop: LeadsBack | None = None) -> list[Why]:
    """For each proposal of `offered` (the policy's order, after `product.runnable_first` and
    `plan.planner.out_of_loops`), why it is where it is: its place in the model's scores, every better-scored step
    it stands above or in place of and why that step is not above it, and what the lookahead found for the steps
    it imagined (`policy` is the model file's). `closes_loop` says which steps would close a loop of the task so far
    (`plan.planner.closes_loop`); give it only when the rule against loops reordered the proposals, since a step
    that would close a loop is passed over for it only then."""
    if not offered:
        return []
    shown = [y for y, _ in offered]
    place = {y: i for i, y in enumerate(shown)}
    scored: list[tuple[Y, float]] = []  # the model's ranking down to the last proposal
    left = set(shown)
    for y, score in planner.ranked(ctx):
        scored.append((y, score))
        left.discard(y)
        if not left:
            break
    history = ctx.history()
    plans: dict[Y, Imagined] = {}

    def plan(y: Y) -> Imagined:
        if y not in plans:
            plans[y] = imagine(planner, task, initial, state, history, ctx.action(y))
        return plans[y]

    def words(y: Y) -> str:
        return in_names(ctx.action(y), state.specs)

    looks_ahead = policy == "lookahead"
    stops = looks_ahead and goal_reached(task, initial, state)  # the lookahead proposes `done` first

    def loops(y: Y) -> bool:
        return looks_ahead and closes_loop is not None and closes_loop(ctx.action(y))
    out: list[Why] = []
    demoted: set[Y] = set()
    explained: set[Y] = set()
    rank = {y: k for k, (y, _) in enumerate(scored)}
    score_of = dict(scored)
    for i, y in enumerate(shown):
        above = [z for z, _ in scored[: rank[y]] if place.get(z, len(shown)) > i]  # better scores not listed above
        below = [z for z in above if z in place]
        hidden = [z for z in above if z not in place and z not in explained]  # each said once, on the first row
        explained.update(hidden)
        parts: list[str] = []
        if y in demoted and stops:
            parts.append("below done: the goal holds, and the robot stops once it does")
        elif y in demoted:
            found = plan(y) if looks_ahead else None
            said = [_loop("it leads")] if loops(y) else []
            if found is not None and found.harmful:
                said.append(f"its plan would {found.text()}")
            parts.append(f"demoted: {'; and '.join(said)}" if said
                         else "placed below better-scored steps by the policy")
        elif not above and rank[y] == 0:
            parts.append("the best score of all the steps")
        elif not below and not hidden and i > 0 and f"{score_of[y]:.2f}" == f"{score_of[shown[i - 1]]:.2f}":
            parts.append("the same score as the step above")  # a tie, as the table shows the scores
        elif not above:
            parts.append("the next score down")
        elif not below and not hidden:
            parts.append("the next score down of the steps that can be proposed")
        if below:
            demoted.update(below)
            looping = [z for z in below if loops(z)] if not stops else []
            for group in (looping, [z for z in below if z not in looping]):
                if not group:
                    continue
                listed = "; ".join(f"{words(z)} ({score_of[z]:.2f})" for z in group)
                if stops and ctx.action(y).primitive == DONE:
                    cause = "the goal holds, and the lookahead stops once it does"
                elif group is looping:
                    cause = _loop("it would lead" if len(group) == 1 else "they would lead")
                else:
                    cause = ("the lookahead found its plan breaks a safety rule" if len(group) == 1
                             else "the lookahead found their plans break a safety rule")
                parts.append(f"moved up above {listed}: {cause if looks_ahead else 'the policy put it first'}")
        if hidden:
            reasons, runnable = [], []
            for z in hidden:
                reason = _why_not_runnable(task, initial, state, ctx.action(z))
                (reasons if reason is not None else runnable).append(reason or z)
            if reasons:
                more = len(reasons) - SHOWN_REASONS
                said = "; ".join(reasons[:SHOWN_REASONS]) + (f"; and {more} more that cannot run" if more > 0 else "")
                count = "a step scored above it" if len(reasons) == 1 else f"the {len(reasons)} steps scored above it"
                parts.append(f"moved up: {count} cannot run here ({said})")
            for z in runnable:  # runs, but not proposed: the lookahead passed it over and the list was full
                found = plan(z) if looks_ahead else None
                if found is not None and found.harmful:
                    parts.append(f"moved up: {words(z)} ({score_of[z]:.2f}) scores higher, but its plan would "
                                 f"{found.text()}")
                else:
                    parts.append(f"moved up: {words(z)} ({score_of[z]:.2f}) scores higher but is not proposed")
        if looks_ahead and i == 0 and ctx.action(y).primitive == DONE:
            parts.append("the goal holds, and stopping is always safe")
        elif looks_ahead and i == 0:
            found = plan(y)
            if found.harmful:
                parts.append(f"the lookahead found no safe plan among the best steps that can run; this one "
                             f"would {found.text()}")
            elif len(found.steps) > 1:
                parts.append(f"looking ahead ({found.text()}) it breaks no safety rule")
        out.append(Why(parts))
    return out
