"""The dynamic planner: score every candidate in the current state, execute the best, repeat.

This is the paper's Program 3: the loop looks at the environment afresh at
every step, so an object that moved, or a step that did something else than
expected, changes the next choice.
"""

from __future__ import annotations

from collections.abc import Callable, Generator, Hashable, Iterator
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Protocol, TypeVar

import numpy as np

from ..features.context import StepContext, step_context
from ..sim.primitives import Action, PreconditionError, execute, try_execute
from ..sim.safety import violations
from ..sim.state import WorldState
from ..sim.tasks import Task, goal_reached
from .records import DONE, INFEASIBLE, STEP_CAP, PlanStep, Program

if TYPE_CHECKING:  # only named in hints: the stages that read programs need not import the learner (Numba, scipy)
    from ..learn.estimator import StepScorer

Y = tuple[int, int, int]
Ranked = list[tuple[Y, float]]
# A policy ranks the candidates of the current step, best first: from what the model sees of the step
# (the context, after `perceive`) and the world itself, which a symbolic planner plans from.
Policy = Callable[[StepContext, WorldState], Ranked]
Perceive = Callable[[StepContext], StepContext]
Choose = Callable[[list[Action], list[Action]], int]
LeadsBack = Callable[[Action], bool]  # whether a step would close a loop of the program
T = TypeVar("T")


class Ranking(Protocol):
    """One step's candidates ranked by a learned planner's scores (`learn.mrf.Scored`)."""

    def top_k(self, k: int) -> Ranked: ...

    def ranked(self) -> Iterator[tuple[Y, float]]: ...


# Work that asks for a learned planner's scores as it goes: it yields each step context it needs scored, is sent
# that step's `Ranking` and returns its result. Run alone (`alone`), each context is scored by itself; many such
# generators advance together and are scored in batches (`run_programs`); the scores, so the results, are the same.
Scoring = Generator[StepContext, Ranking, T]
Contexts = dict[tuple[Hashable, tuple[Action, ...]], StepContext]  # by `seen_at`


def seen_at(state: WorldState, history: tuple[Action, ...] | list[Action]) -> tuple[Hashable, tuple[Action, ...]]:
    """What a step's context is made of: the world's contents (`WorldState.key`) and the last two steps, all
    `step_context` reads of the past (the world's objects are the program's own)."""
    return state.key(), tuple(history[-2:])


@dataclass(frozen=True)
class LoopAware:
    """A policy that can rank a step again without the steps that would close a loop: `run_loop` asks
    `without_revisits` when the first proposal would (see `lookahead`). It ranks as `rank` does; `without_revisits`
    gives its proposals with a step that leads out first, or None when it has none to offer."""

    rank: Policy
    without_revisits: Callable[[StepContext, WorldState, LeadsBack], Ranked | None]

    def __call__(self, ctx: StepContext, state: WorldState) -> Ranked:
        return self.rank(ctx, state)


class Abstain(Exception):
    """Raised by a policy that has no step to offer (a planner that finds no plan): the program ends
    infeasible, with the exception's message as its error."""


class _Alone:
    """A step's `Ranking` read from the planner when it is read, as a policy alone always read it."""

    def __init__(self, planner: Any, ctx: StepContext) -> None:
        self.planner, self.ctx = planner, ctx

    def top_k(self, k: int) -> Ranked:
        return self.planner.top_k(self.ctx, k)

    def ranked(self) -> Iterator[tuple[Y, float]]:
        return self.planner.ranked(self.ctx)


def alone(planner: Any, work: Scoring[T]) -> T:
    """The result of `work`, each context it asks for scored by itself."""
    try:
        ctx = next(work)
        while True:
            ctx = work.send(_Alone(planner, ctx))
    except StopIteration as end:
        return end.value


@dataclass(frozen=True)
class Learned:
    """A policy that ranks from a learned planner's scores, in both forms: `steps(ctx, state)` asks for them
    (`Scoring`), so that programs advancing together are scored in batches; called, it scores alone.
    `revisits`, where given, is its way out of a loop (as `LoopAware.without_revisits`), in the same form."""

    planner: Any
    steps: Callable[[StepContext, WorldState], Scoring[Ranked]]
    revisits: Callable[[StepContext, WorldState, LeadsBack], Scoring[Ranked | None]] | None = None
    # contexts of the worlds the program may reach as they are (unperceived), by the world's contents
    # (`WorldState.key`) and the last two steps (what `step_context` reads), shared by the policy and the loop:
    # each made once, by whichever meets its world first
    contexts: Contexts | None = None

    def __call__(self, ctx: StepContext, state: WorldState) -> Ranked:
        return alone(self.planner, self.steps(ctx, state))

    def without_revisits(self, ctx: StepContext, state: WorldState, leads_back: LeadsBack) -> Ranked | None:
        if self.revisits is None:
            raise TypeError("this policy has no way out of loops")
        return alone(self.planner, self.revisits(ctx, state, leads_back))


def _planner_of(policy: Policy) -> Any:
    """The planner whose scores `policy` asks for; None for a policy that asks for none (chance, the symbolic
    planner, a wrapper that calls a learned policy itself)."""
    return policy.planner if isinstance(policy, Learned) else None


def leaves_loops(policy: Policy) -> bool:
    """Whether `run_loop` may ask `policy` again for a way out of a loop (`out_of_loops`)."""
    return isinstance(policy, LoopAware) or (isinstance(policy, Learned) and policy.revisits is not None)


def greedy(planner: StepScorer, top_k: int = 3) -> Learned:
    """The learned planner as a policy: its `top_k` candidates of the step."""
    def steps(ctx: StepContext, state: WorldState) -> Scoring[Ranked]:
        return (yield ctx).top_k(top_k)

    return Learned(planner, steps)


class _Runnable:
    """The planner's candidates of one step among `done` and the steps whose preconditions hold, best first,
    found only as far down the ranking as they are asked for."""

    def __init__(self, ranking: Ranking, ctx: StepContext, state: WorldState) -> None:
        self.ctx, self.state = ctx, state
        self._ranked = ranking.ranked()
        self._found: Ranked = []

    def first(self, limit: int) -> Ranked:
        """The best `limit` of them (fewer when the step has fewer)."""
        while len(self._found) < limit:
            candidate = next(self._ranked, None)
            if candidate is None:
                break
            action = self.ctx.action(candidate[0])
            if action.primitive == DONE or try_execute(self.state, action) is not None:
                self._found.append(candidate)
        return self._found[:limit]

    def stop(self) -> tuple[Y, float]:
        """`done` with its score, read down the same ranking (every step's candidates include `done`)."""
        limit = 1
        while True:
            found = self.first(limit)
            stop = next((c for c in found if self.ctx.action(c[0]).primitive == DONE), None)
            if stop is not None:
                return stop
            if len(found) < limit:
                raise ValueError("the planner ranks no `done` among the step's candidates")
            limit *= 2


def best_runnable(planner: Any, ctx: StepContext, state: WorldState) -> Action:
    """The planner's best candidate of the step among `done` and the steps whose preconditions hold: the step
    `lookahead` imagines next, read from the planner alone (the web app's explanations retrace its imagined steps)."""
    step = _Runnable(_Alone(planner, ctx), ctx, state)
    return ctx.action(step.first(1)[0][0])


def feasible(planner: StepScorer, top_k: int = 3) -> Learned:
    """The learned planner's `top_k` best candidates among the steps that can run in the world as it is.

    A robot's controllers report whether a primitive's preconditions hold
    (the gripper is empty, the object is within reach) before it is sent;
    this policy asks them down the ranking, so a step whose preconditions fail
    is never proposed, and the model's scores decide among the rest.
    """
    def steps(ctx: StepContext, state: WorldState) -> Scoring[Ranked]:
        return _Runnable((yield ctx), ctx, state).first(top_k)

    return Learned(planner, steps)


# Chosen on the development world (scripts/lookahead_grid.py; docs/model.md, "Safety lookahead"): the best
# sequence arg of depth 2, 4, 6, 8, 12 x width 2, 3, 5, the smaller of two ties.
LOOKAHEAD_DEPTH = 4
LOOKAHEAD_WIDTH = 3


def lookahead(planner: StepScorer, task: Task, start: WorldState, top_k: int = 3, perceive: Perceive | None = None,
              depth: int = LOOKAHEAD_DEPTH, width: int = LOOKAHEAD_WIDTH, stop_at_goal: bool = True) -> Learned:
    """`feasible`, but a step is taken only if the plan it starts breaks no safety rule in the next `depth` steps,
    and the robot stops once the task's goal holds.

    The learned score picks each step by itself, so it can walk into a state
    where its best continuation is unsafe (a cup left on a shelf, then poured
    into there). Before sending a step, the robot imagines what follows with
    its model of the primitives (`sim.primitives.execute`) and its own
    planner: from the state the step leads to, `depth` more steps, each the
    best runnable one, stopping at `done`. Of the `width` best runnable
    candidates it takes the first whose imagined steps, itself included,
    break no rule of `sim.safety`; when every one of them does, the best.
    Imagined steps are seen through `perceive` as real ones are (attribute
    noise flips an object's attributes alike at every step). The other
    proposals follow in score order, so an observer still sees `top_k`.

    The robot that imagines with its model of the primitives also checks the
    task's goal (`sim.tasks.goal_reached`, judged against `start`, the world
    the program began in): once it holds, `done` is proposed first, in real
    steps and imagined ones. The learned score decides when to stop only from
    the step and the last two steps, and after a release it cannot tell
    setting the task's object down on its target from setting down a load
    cleared out of the way, so in rooms it never saw it went on moving things
    after the goal held, and came back to the goal by a longer route. A
    demonstration never goes on past the goal (no demonstration of the
    development or reported worlds reaches it before its last step), so the
    rule changes no program that matches one. The rule is the lookahead's, not
    the learned score's: Table I's paper rows keep their policies.
    `stop_at_goal=False` takes it away, for measuring what it changes
    (`scripts/goal_stop.py`).

    The imagined continuation is the planner's plain best runnable step, not
    this policy's own later choices, and stopping counts as safe: a step that
    a safe plan and an unsafe one share is refused when the unsafe one scores
    higher, and the robot may stop rather than take it (`tests/test_lookahead.py`
    scripts such a room). A longer `depth` sees more harm and refuses more
    for it; the development world chose 4.

    Nor does a program go round a loop. A policy is a function of the step
    and the world, so a program that comes back to a world with the same two
    steps remembered (all `step_context` reads of the past) ranks it as
    before and repeats itself until the step cap. The loop keeps the
    program's worlds: when the first proposal would close such a loop,
    `run_loop` asks the policy again (`without_revisits`), and the policy
    takes the first of the `width` best runnable candidates that leads out
    of it and whose imagined steps break no rule (`done` always qualifies);
    when none does, the proposals stay as they were. So the rule never takes
    a step the lookahead refused, and it changes only programs that would
    have looped to the step cap.
    """
    seen = perceive or (lambda ctx: ctx)
    # The steps the robot imagined, kept for the program's later steps: after it takes a step, the plan it
    # imagines from there is mostly the one it imagined a step earlier, one step further on, and the step it now
    # ranks for real is the first it imagined. Keyed by the world's contents (`WorldState.key`) and the steps a
    # context remembers, what step_context reads: a hit is the very step computed before.
    worlds: dict[tuple[Hashable, Action], WorldState] = {}
    steps: dict[tuple[Hashable, tuple[Action, ...]], _Runnable] = {}
    contexts: Contexts = {}  # the worlds' contexts as they are, made by the loop or imagined here (`Learned`)

    def imagine(state: WorldState, history: list[Action]) -> Scoring[_Runnable]:
        known = seen_at(state, history)
        step = steps.get(known)
        if step is None:
            ctx = contexts.get(known)  # made by the loop, for a step it took that was not imagined
            if ctx is None:
                ctx = contexts[known] = step_context(state, task, history)
            ctx = seen(ctx)
            step = steps[known] = _Runnable((yield ctx), ctx, state)
        return step

    def harms(state: WorldState, history: list[Action], action: Action) -> Scoring[bool]:
        for _ in range(depth):
            if violations(state, action):
                return True
            after = worlds.get((state.key(), action))
            if after is None:
                after = worlds[state.key(), action] = execute(state, action)
            state = after
            if stop_at_goal and goal_reached(task, start, state):  # the robot stops here, and stopping is safe
                return False
            history = [*history[-1:], action]
            step = yield from imagine(state, history)
            action = step.ctx.action(step.first(1)[0][0])
            if action.primitive == DONE:
                return False
        return bool(violations(state, action))

    def ranking(ctx: StepContext, state: WorldState) -> Scoring[_Runnable]:
        """The step's runnable candidates as ranked for real: the imagined step when it is the same."""
        history = ctx.history()
        step = steps.get(seen_at(state, history))
        if step is None and history:  # a step not imagined (the program took another proposal): kept, as imagined
            step = yield from imagine(state, history)  # ones are, for its imagined plans that come back to it
        if step is None or step.ctx.object_ids != ctx.object_ids or not np.array_equal(step.ctx.objects, ctx.objects):
            step = _Runnable((yield ctx), ctx, state)  # the first step, or seen otherwise than the imagined steps
        return step

    def proposals(ctx: StepContext, state: WorldState,
                  leads_back: LeadsBack | None) -> Scoring[tuple[Ranked, int | None]]:
        """The runnable candidates, best first, and the position of the first of the `width` best whose imagined
        steps break no rule (and, given `leads_back`, that does not lead back to a world the program was in), or
        None when no candidate is such. `done` always is."""
        history = ctx.history()
        runnable = (yield from ranking(ctx, state)).first(max(top_k, width))
        for i, (y, _) in enumerate(runnable[:width]):
            action = ctx.action(y)
            if action.primitive == DONE:
                return runnable, i
            if not (leads_back is not None and leads_back(action)) and not (yield from harms(state, history, action)):
                return runnable, i
        return runnable, None

    def first(runnable: Ranked, pick: int) -> Ranked:
        return ([runnable[pick]] + runnable[:pick] + runnable[pick + 1:])[:top_k]

    def stopping(ctx: StepContext, state: WorldState) -> Scoring[Ranked]:
        """`done` first, with its score, then the best runnable steps: the goal holds."""
        step = yield from ranking(ctx, state)
        stop, runnable = step.stop(), step.first(top_k)
        return ([stop] + [c for c in runnable if c[0] != stop[0]])[:top_k]

    def policy(ctx: StepContext, state: WorldState) -> Scoring[Ranked]:
        if stop_at_goal and goal_reached(task, start, state):
            return (yield from stopping(ctx, state))
        runnable, pick = yield from proposals(ctx, state, None)
        return first(runnable, 0 if pick is None else pick)

    def without_revisits(ctx: StepContext, state: WorldState, leads_back: LeadsBack) -> Scoring[Ranked | None]:
        runnable, pick = yield from proposals(ctx, state, leads_back)
        return None if pick is None else first(runnable, pick)

    return Learned(planner, policy, without_revisits, contexts)


def closes_loop(states: list[WorldState], history: tuple[Action, ...]) -> LeadsBack:
    """Whether a step from the last of `states` (the program's worlds, one before each step of `history` and one
    after the last) closes a loop: it leads to a world the program was in with the same two steps remembered,
    which is all a policy reads of the past (`step_context`), so from there the program would repeat itself to the
    step cap. A world met again after other steps is no loop. A step that cannot run counts as closing one: it
    leads nowhere new."""
    met = {(s.key(), history[max(0, i - 2):i]) for i, s in enumerate(states)}
    state = states[-1]

    def leads_back(action: Action) -> bool:
        after = try_execute(state, action)
        return after is None or (after.key(), (*history, action)[-2:]) in met

    return leads_back


def out_of_loops(policy: Policy, ranked: Ranked, ctx: StepContext, states: list[WorldState],
                 history: tuple[Action, ...]) -> Ranked:
    """`ranked`, or, when its first step would close a loop (`closes_loop`) and the policy can rank again
    (`leaves_loops`), its proposals with a step that leads out of it first; as they were when it has none. `run_loop`
    applies it to every step, and the web app's assist table to the step it shows."""
    return alone(_planner_of(policy), _out_of_loops(policy, ranked, ctx, states, history))


def _out_of_loops(policy: Policy, ranked: Ranked, ctx: StepContext, states: list[WorldState],
                  history: tuple[Action, ...]) -> Scoring[Ranked]:
    if not leaves_loops(policy):
        return ranked
    leads_back = closes_loop(states, history)
    first = ctx.action(ranked[0][0])
    if first.primitive == DONE or not leads_back(first):
        return ranked
    if isinstance(policy, Learned):
        elsewhere = yield from policy.revisits(ctx, states[-1], leads_back)
    else:
        elsewhere = policy.without_revisits(ctx, states[-1], leads_back)
    return ranked if elsewhere is None else elsewhere


# The policies a learned planner can run with, by the name a model file records (`policy` in its metadata).
POLICIES = ("greedy", "feasible", "lookahead")


def learned_policy(name: str, planner: StepScorer, task: Task, start: WorldState, top_k: int = 3,
                   perceive: Perceive | None = None) -> Policy:
    """The policy called `name` (one of `POLICIES`) for one program of `task` begun in `start`, offering `top_k`
    candidates.

    `perceive` is the hook the program's steps are seen through, and `start` the world the task's goal is judged
    against; only the policy that imagines steps of its own and checks the goal (`lookahead`) needs them.
    """
    if name == "greedy":
        return greedy(planner, top_k)
    if name == "feasible":
        return feasible(planner, top_k)
    if name == "lookahead":
        return lookahead(planner, task, start, top_k, perceive)
    raise ValueError(f"unknown policy {name!r}; known: {', '.join(POLICIES)}")


def plan(planner: StepScorer, state: WorldState, task: Task, max_steps: int = 20,
         top_k: int = 3, perceive: Perceive | None = None, choose: Choose | None = None) -> Program:
    """Run the loop in the simulator until `done`, an infeasible step, or `max_steps` primitives.

    `perceive` changes what the model sees of each step (attribute noise);
    `choose(history, ranked actions)` lets an observer pick among the top
    `top_k` candidates (human feedback); by default the best one is taken.
    """
    return run_loop(greedy(planner, top_k), state, task, max_steps, perceive, choose)


@dataclass(frozen=True)
class Memo:
    """What one scenario's programs met at each history (the actions taken so far), for programs to share.

    `worlds` holds the world before the next step and its context as it is,
    the same however a program sees it; `ranked` holds, per way of seeing the
    scenario (`view`: the perception and what the policy offers), the context
    as seen and the policy's ranking of it (or its abstention). A caller makes
    one `Memo` per scenario and task and one `seen_as` per view, and promises
    that programs given the same view see and rank alike. A policy given a
    memo must be a function of the step's context and world only: one that
    keeps a plan between calls (the symbolic baselines' `SymbolicPolicy`)
    would rank a history differently from one program to the next.
    """

    view: Hashable = ()
    worlds: dict[tuple[Action, ...], tuple[WorldState, StepContext]] = field(default_factory=dict)
    ranked: dict[tuple[Hashable, tuple[Action, ...]], tuple[StepContext, Ranked | str]] = field(
        default_factory=dict)  # a str: why the policy abstained

    def seen_as(self, view: Hashable) -> Memo:
        """The same memo for programs that see the scenario as `view` says."""
        return Memo(view, self.worlds, self.ranked)


def run_loop(policy: Policy, state: WorldState, task: Task, max_steps: int = 20, perceive: Perceive | None = None,
             choose: Choose | None = None, memo: Memo | None = None) -> Program:
    """The rollout loop of every method: rank the step's candidates, take the best, execute it, repeat.

    A program is a function of the actions it took: the simulator, the
    features, `perceive` and the policy are deterministic. So programs of one
    scenario that differ only in the observer (`choose`) share every step up
    to the first the observer changes, and programs that see it differently
    (attribute noise) share the world and its context at a history they both
    reach. Given the same `memo` (see `Memo`) a later program reads those back
    instead of computing them again: the same objects, so the same program.
    This holds only for a policy that ranks a step from its context and world
    alone, as the learned policies do.
    """
    return alone(_planner_of(policy), program(policy, state, task, max_steps, perceive, choose, memo))


def program(policy: Policy, state: WorldState, task: Task, max_steps: int = 20, perceive: Perceive | None = None,
            choose: Choose | None = None, memo: Memo | None = None) -> Scoring[Program]:
    """`run_loop`'s program as work that asks for its scores (`Scoring`): a learned policy's steps are scored
    where it is run, alone (`run_loop`) or beside other programs (`run_programs`)."""
    task.check_objects(state)
    contexts = policy.contexts if isinstance(policy, Learned) else None
    states, steps = [state], []
    history: tuple[Action, ...] = ()
    while True:
        known = memo.ranked.get((memo.view, history)) if memo is not None else None
        if known is None:
            world = memo.worlds.get(history) if memo is not None else None
            if world is None:
                # the context the policy made of this world (`lookahead`, imagining it), or one made here for it
                ctx = contexts.get(at := seen_at(state, history)) if contexts is not None else None
                if ctx is None:
                    ctx = step_context(state, task, list(history))
                    if contexts is not None:
                        contexts[at] = ctx
                if memo is not None:
                    memo.worlds[history] = (state, ctx)
            else:
                _, ctx = world
            if perceive is not None:
                ctx = perceive(ctx)
            try:
                ranked: Ranked | str = (yield from policy.steps(ctx, state)) if isinstance(policy, Learned) \
                    else policy(ctx, state)
            except Abstain as why:
                ranked = str(why)
            if memo is not None:
                memo.ranked[memo.view, history] = (ctx, ranked)
        else:
            ctx, ranked = known
        if isinstance(ranked, str):
            return Program(task, steps, INFEASIBLE, states, ranked)
        ranked = yield from _out_of_loops(policy, ranked, ctx, states, history)
        if choose is not None:
            pick = choose(list(history), [ctx.action(y) for y, _ in ranked])
            ranked = [ranked[pick]] + ranked[:pick] + ranked[pick + 1 :]
        (best, score), rest = ranked[0], ranked[1:]
        action = ctx.action(best)
        if action.primitive == DONE:
            return Program(task, steps, DONE, states)
        if len(steps) == max_steps:
            return Program(task, steps, STEP_CAP, states)
        step = PlanStep(action, score, [(ctx.action(y), s) for y, s in rest], violations(state, action))
        steps.append(step)
        history = (*history, action)
        world = memo.worlds.get(history) if memo is not None else None
        if world is not None:
            state, _ = world
        else:
            try:
                state = execute(state, action)
            except PreconditionError as err:
                return Program(task, steps, INFEASIBLE, states, str(err))
        states.append(state)


def run_programs(planner: StepScorer, programs: list[Scoring[Program]]) -> list[Program]:
    """The programs (`program`, each of a learned policy of `planner`), run together: in every round each program
    still running has asked for one step's scores, and the steps are scored in one batch (`StepScorer.scored`).

    Scoring a step alone costs Python's work per call more than its sums;
    in a batch that work is paid once per round. The programs are the ones
    each gives alone (a test compares them): a step's
    scores are the same bits in a batch, and each program's own work runs in
    its order, the others' between its steps touching only what is theirs.
    """
    done: list[Program | None] = [None] * len(programs)
    asking: list[tuple[int, StepContext]] = []

    def advance(i: int, ranking: Ranking | None) -> None:
        try:
            asking.append((i, programs[i].send(ranking)))  # `send(None)` starts a program
        except StopIteration as end:
            done[i] = end.value

    def scored(contexts: list[StepContext]) -> list[Ranking]:  # a planner with no batch (a test's) step by step
        if hasattr(planner, "scored"):
            return planner.scored(contexts)
        return [_Alone(planner, ctx) for ctx in contexts]

    for i in range(len(programs)):
        advance(i, None)
    while asking:
        batch, asking = asking, []
        for (i, _), ranking in zip(batch, scored([ctx for _, ctx in batch]), strict=True):
            advance(i, ranking)
    return done  # type: ignore[return-value]  # every program has ended: each holds its Program
