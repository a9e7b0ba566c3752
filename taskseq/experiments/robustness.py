"""Closed-loop sequence accuracy of MRF methods under attribute noise and with an observer's feedback.

Both train each method once per cross-validation fold and replay the test
scenarios of that fold under each condition, so every condition is judged on
the same scenarios with the same models; programs pick steps with the
method's own policy, as its Table I programs do.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import asdict, dataclass

import numpy as np
from threadpoolctl import threadpool_limits

from ..evaluate.methods import ScorerMethod
from ..features.context import StepContext
from ..features.dataset import StepMeta
from ..features.perception import flip_masks, noisy_perception
from ..plan.planner import Memo, learned_policy, program, run_programs
from ..runtime.jobs import Shared, run_jobs
from ..settings import Feedback, Folds, Noise
from ..sim.primitives import Action
from ..sim.scenarios import Scenario
from . import outcome_cache
from .crossval import SequenceOutcome, judge, outcome_of, scenario_folds, training_index


def observer(demonstrations: tuple[tuple[Action, ...], ...], n_feedback: int):
    """A `choose` hook: at each of the first `n_feedback` steps, the observer picks the first
    offered candidate that continues one of the demonstrations; otherwise the robot's best."""

    def choose(history: list[Action], offered: list[Action]) -> int:
        if len(history) >= n_feedback:
            return 0
        for k, action in enumerate(offered):
            for demo in demonstrations:
                if tuple(history) == demo[: len(history)]:
                    expected = demo[len(history)] if len(history) < len(demo) else Action("done")
                    if action == expected:
                        return k
        return 0

    return choose


@dataclass(frozen=True)
class NoiseCondition:
    """The test scenarios seen with each binary attribute flipped with probability `rate`, in noise draw `draw`."""

    rate: float
    draw: int


@dataclass(frozen=True)
class FeedbackCondition:
    """The test scenarios run with an observer who picks among the top `k` candidates at the first `n` steps."""

    k: int
    n: int


Condition = NoiseCondition | FeedbackCondition


def _fold(make, contexts, meta, scenarios, test, conditions, max_steps, seed):
    with threadpool_limits(limits=1):  # the same sums, so the same bytes, in any process (see learn/estimator.py)
        return _replay(make, contexts, meta, scenarios, test, conditions, max_steps, seed)


def _replay(make, contexts, meta, scenarios, test, conditions, max_steps, seed):
    train = training_index(meta, test)
    method: ScorerMethod = make().fit([contexts[i] for i in train], [meta[i] for i in train], scenarios)
    return outcome_cache.read_or_run(
        "robustness", make, method, (contexts, meta, scenarios, test, None),
        {"conditions": [repr(c) for c in conditions], "max_steps": max_steps, "seed": seed},
        lambda: _replayed(method, scenarios, test, conditions, max_steps, seed),
        lambda result: [(asdict(c) | {"kind": type(c).__name__}, asdict(o)) for c, o in result],
        lambda entry: [(_condition(c), outcome_of(o)) for c, o in entry])


def _condition(entry: dict) -> Condition:
    kinds = {kind.__name__: kind for kind in (NoiseCondition, FeedbackCondition)}
    return kinds[entry["kind"]](**{k: v for k, v in entry.items() if k != "kind"})


def _replayed(method, scenarios, test, conditions, max_steps, seed):
    """Each condition's outcome on every test scenario, from the fitted `method`.

    A condition's programs of every test scenario run together, scored in
    batches (`run_programs`), one condition after the other; each scenario
    keeps one `Memo` across the conditions, which meet it in the same order as
    when each scenario's conditions ran in turn, so the programs are the same.
    """
    order, tested = sorted(scenarios), sorted(test)
    memos = {sid: Memo() for sid in tested}
    outcome = {}
    for c in conditions:
        programs = []
        for sid in tested:
            sc = scenarios[sid]
            perceive = choose = None
            top_k, flips = 3, ()  # flips: each object's attribute flips, bytes (none: seen as it is)
            if isinstance(c, NoiseCondition):
                # one draw per (seed, scenario): the same scenario sees the same errors in every fold layout
                rng = np.random.default_rng([seed, c.draw, order.index(sid)])
                masks = flip_masks(sorted(sc.initial.specs), c.rate, rng)
                perceive = noisy_perception(masks)
                flips = tuple((o, m.tobytes()) for o, m in masks.items())  # rate 0: every draw sees alike
            else:
                top_k = c.k
                choose = observer(sc.demonstrations, c.n)
            # what a program sees and what it offers; the observer changes which step is taken, not what it offers
            view = (top_k, flips)
            # as the method's own programs pick steps, imagined ones seen through the same perception
            policy = learned_policy(method.policy, method.planner_, sc.task, sc.initial, top_k, perceive)
            programs.append(program(policy, sc.initial, sc.task, max_steps, perceive, choose,
                                    memos[sid].seen_as(view)))
        for sid, ran in zip(tested, run_programs(method.planner_, programs), strict=True):
            outcome[c, sid] = judge(scenarios[sid], ran)
    return [(c, outcome[c, sid]) for c in conditions for sid in tested]


def evaluate_conditions(makes: Mapping[str, Callable[[], ScorerMethod]], contexts: list[StepContext],
                        meta: list[StepMeta], scenarios: dict[str, Scenario], conditions: list[Condition],
                        folds: Folds, max_steps: int, seed: int = 0,
                        n_jobs: int = 1) -> dict[str, list[tuple[Condition, SequenceOutcome]]]:
    """Per method, each condition's outcome on every scenario, from the method's model of the scenario's test fold.

    Every (method, fold) is one job of one flat list, so all of them share the workers.
    """
    tests = scenario_folds(scenarios, folds.folds, folds.seed, folds.group_by)
    jobs = [(name, k) for name in makes for k in range(folds.folds)]
    steps, shared_meta, shared_scenarios = Shared(contexts), Shared(meta), Shared(scenarios)
    parts = run_jobs([(_fold, (makes[name], steps, shared_meta, shared_scenarios, tests[k], conditions, max_steps,
                               seed)) for name, k in jobs], n_jobs, stored_first=True)
    out: dict[str, list[tuple[Condition, SequenceOutcome]]] = {name: [] for name in makes}
    for (name, _), part in zip(jobs, parts, strict=True):
        out[name] += part
    return out


def rates(outcomes: list[SequenceOutcome]) -> dict[str, float]:
    """Sequence accuracy (arg, prim) and success of a set of programs, in percent."""
    return {
        "sequence_arg": 100.0 * float(np.mean([o.arg_correct for o in outcomes])),
        "sequence_prim": 100.0 * float(np.mean([o.prim_correct for o in outcomes])),
        "success": 100.0 * float(np.mean([o.success for o in outcomes])),
    }


def noise_runs(settings: Noise, results: list[tuple[Condition, SequenceOutcome]]) -> list[dict[str, float]]:
    """One row per (rate, noise draw) over all scenarios."""
    return [{"rate": r, "seed": s, **rates([o for c, o in results if c == NoiseCondition(r, s)])}
            for r in settings.rates for s in range(settings.draws)]


def noise_curve(settings: Noise, runs: list[dict[str, float]]) -> list[dict[str, float]]:
    """Per rate, the mean over noise draws, with the spread of sequence accuracy (arg)."""
    out = []
    for r in settings.rates:
        mine = [x for x in runs if x["rate"] == r]
        arg = [x["sequence_arg"] for x in mine]
        out.append({"rate": r, "sequence_arg": float(np.mean(arg)), "sequence_arg_std": float(np.std(arg)),
                    "sequence_prim": float(np.mean([x["sequence_prim"] for x in mine])),
                    "success": float(np.mean([x["success"] for x in mine]))})
    return out


def feedback_steps(settings: Feedback, max_steps: int) -> list[int]:
    """The step counts with feedback; `all` is every step the loop may take."""
    return [max_steps if n == "all" else int(n) for n in settings.n]


def feedback_rows(settings: Feedback, max_steps: int,
                  results: list[tuple[Condition, SequenceOutcome]]) -> list[dict[str, float]]:
    """One row per (k, n) over all scenarios; n as the settings write it, so `all` stays `all`."""
    return [{"k": k, "n": label, **rates([o for c, o in results if c == FeedbackCondition(k, n)])}
            for k in settings.k for label, n in zip(settings.n, feedback_steps(settings, max_steps), strict=True)]
