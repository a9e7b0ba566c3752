"""On-policy training data (DAgger; Ross, Gordon and Bagnell, 2011).

The planner trained on demonstrations only ever saw the demonstrator's
states; once it strays it is somewhere no example shows. DAgger rolls the
learned planner out on the training scenarios, asks the demonstrator what it
would do in each state the planner reached that no demonstration passes
through, adds those labelled steps to the training set and refits; `rounds`
times. Every rollout follows the learner alone (the demonstrations are round
zero).

Rolling out costs seconds per training set (hundreds of programs), and a
stage that finds DAgger's fit in the fit cache would still roll out to learn
the steps that key it. So the last round's rollouts are kept in the cache's
`steps/` folder too (`features.drawn_rooms.StepsCache`, as `taskseq features`
writes steps), keyed by what decides them: this module's code with all it
imports (planner, simulator, demonstrator, features), the fitted policy's
settings and weights, the training data it was fitted on, every training
scenario and the histories earlier rounds labelled. Earlier rounds roll out
each time: what they see decides what later rounds skip.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Callable, Sequence

from ..demonstrations.records import scenario_digest
from ..features.context import StepContext, step_context
from ..features.dataset import StepMeta
from ..features.drawn_rooms import StepsCache
from ..learn.estimator import StepScorer
from ..learn.fit_cache import hash_steps
from ..plan.planner import Policy, greedy, run_loop
from ..runtime.cache import versions
from ..runtime.sources import code_fingerprint
from ..sim.primitives import Action
from ..sim.scenarios import Scenario
from ..sim.state import WorldState
from .expert import next_actions
from .starts import chained_contexts, chained_scenarios

ROLLOUT_STEPS = 20  # step cap of a training rollout, the evaluation's
FORMAT = "taskseq.rollouts/1"

Expert = Callable[[Scenario, Sequence[Action], WorldState], tuple[Action, ...]]


def _on_demonstration(scenario: Scenario, history: tuple[Action, ...]) -> bool:
    return any(d[: len(history)] == history for d in scenario.demonstrations if len(d) >= len(history))


def rollout_contexts(policy: Policy, scenario: Scenario, seen: set[tuple[Action, ...]],
                     expert: Expert | None = None) -> list[StepContext]:
    """Labelled steps of the states a rollout of `policy` reaches off every demonstration of `scenario`.

    `seen` holds the histories already labelled in earlier rounds; it is updated.
    `expert` defaults to the demonstrator (`expert.next_actions`).
    """
    expert = expert or next_actions
    program = run_loop(policy, scenario.initial, scenario.task, ROLLOUT_STEPS)
    out = []
    for k, state in enumerate(program.states):  # the world before each step, and the one it left
        history = tuple(program.actions[:k])
        if not _on_demonstration(scenario, history) and history not in seen:
            seen.add(history)
            labels = expert(scenario, history, state)
            if not labels:
                break
            out += [step_context(state, scenario.task, list(history), gold=a) for a in labels]
    return out


def fit_imitation(planner: StepScorer, contexts: list[StepContext], scenarios: Sequence[Scenario], rounds: int,
                  chained: bool, expert: Expert | None = None, base: StepScorer | None = None,
                  warm: StepScorer | None = None) -> StepScorer:
    """`planner` (unfitted) fitted on the demonstrations' `contexts` (of `scenarios`), with chained starts and
    DAgger rounds added; returns the fitted planner of the last round.

    `base` is the planner already fitted with these settings on the data
    before any DAgger round, when the caller has it: the first rollouts use it
    instead of fitting it again (either way, a fit certified within the same gap). `warm`, a
    planner of the same features fitted on `contexts`, is where the first fit
    starts (`StepScorer.fit`'s warm start); each round's refit starts where
    the fit before it ended, since its data begin with that fit's.
    """
    data = list(contexts)
    scenarios = sorted(scenarios, key=lambda s: s.id)
    if chained:
        extra = chained_scenarios(scenarios)
        data += [x for sc in extra for x in chained_contexts(sc)]
        scenarios += extra
    fitted = base if base is not None and rounds else planner.clone().fit(data, warm_start=warm)
    seconds = 0.0 if fitted is base else fitted.fit_seconds_
    refit = None
    seen: list[set[tuple[Action, ...]]] = [set() for _ in scenarios]
    for r in range(rounds):
        cache = StepsCache.active() if r == rounds - 1 and expert is None else None
        new = _rollouts(fitted, scenarios, seen, expert, cache, data)
        if not new:
            break
        data += new
        fitted = refit = planner.clone().fit(data, warm_start=fitted)
        seconds += refit.fit_seconds_
    if fitted is base and refit is None:  # the rollouts found nothing to add: the base is the answer,
        fitted = planner.clone().fit(data, warm_start=base)  # fitted here for its record (from the base: same data)
        seconds += fitted.fit_seconds_
    fitted.fit_seconds_ = seconds
    return fitted


def _rollouts(fitted: StepScorer, scenarios: list[Scenario], seen: list[set[tuple[Action, ...]]],
              expert: Expert | None, cache: StepsCache | None, data: list[StepContext]) -> list[StepContext]:
    """The labelled steps of one round's rollouts of `fitted` on every scenario, read from `cache` when it holds
    them (the same steps, `read_features` giving back what `write_features` wrote), else rolled out (and kept)."""
    policy = greedy(fitted, top_k=1)
    if cache is None:
        return [x for sc, s in zip(scenarios, seen, strict=True) for x in rollout_contexts(policy, sc, s, expert)]
    key = _key(fitted, scenarios, seen, data)
    kept = cache.load(key, "rolled out again")
    if kept is not None:
        return list(kept)
    new, meta = [], []
    for sc, s in zip(scenarios, seen, strict=True):
        steps = rollout_contexts(policy, sc, s, expert)
        new += steps
        meta += [StepMeta(f"{sc.id} rollout", sc.id, k) for k in range(len(steps))]
    if new:  # an empty round ends the rounds; rolling out again finds it as cheaply
        cache.save(key, new, meta)
    return new


def _key(fitted: StepScorer, scenarios: Sequence[Scenario], seen: list[set[tuple[Action, ...]]],
         data: list[StepContext]) -> str:
    """sha256 of what decides a round's rollouts: the code, the policy's scorer (settings and weights), the steps
    it was fitted on, the scenarios rolled out and the histories earlier rounds labelled there."""
    h = hashlib.sha256()
    h.update(json.dumps({"format": FORMAT, "code": code_fingerprint(__name__), "scorer": repr(fitted),
                         "cap": ROLLOUT_STEPS, **versions("numpy", "scipy", "numba", "pyarrow")},
                        sort_keys=True).encode())
    h.update(json.dumps([sorted(repr(history) for history in s) for s in seen]).encode())
    h.update(fitted.w_.tobytes())
    hash_steps(h, data)
    for sc in scenarios:
        h.update(scenario_digest(sc))
    return h.hexdigest()
