"""The precondition-aware planner: it never proposes a step that cannot run, and otherwise follows the scores."""

from __future__ import annotations

import numpy as np
import pytest

from taskseq.demonstrations.records import parse_record, state_from_dict
from taskseq.features.context import candidate_index, step_context
from taskseq.learn.estimator import StepScorer
from taskseq.methods import Lineup, specs
from taskseq.plan.planner import DONE, INFEASIBLE, feasible, greedy, learned_policy, run_loop
from taskseq.selection import Selection
from taskseq.settings import Methods
from taskseq.sim.primitives import try_execute


@pytest.fixture(scope="module")
def scenarios(benchmark_tables):
    out = []
    for item in benchmark_tables[1][:40]:
        specs, task, _ = parse_record(item.record)
        out.append((state_from_dict(specs, item.record["steps"][0]["state"]), task))
    return out


def _scorers(benchmark_steps):
    """Planners that often rank a step that cannot run first: random weights, and weights fitted on a few steps."""
    contexts, _ = benchmark_steps
    fitted = StepScorer("relations", C=1.0, tol=0.05, max_iter=50).fit(contexts[:40])
    rng = np.random.default_rng(0)
    return [fitted] + [StepScorer.from_weights("relations", rng.normal(size=fitted.w_.shape)) for _ in range(3)]


def test_a_precondition_aware_planner_never_proposes_a_step_that_cannot_run(scenarios, benchmark_steps):
    greedy_infeasible = 0
    for scorer in _scorers(benchmark_steps):
        for state, task in scenarios:
            greedy_infeasible += run_loop(greedy(scorer), state, task, 8).status == INFEASIBLE
            for name in ("feasible", "lookahead"):  # the policies that ask the controllers
                program = run_loop(learned_policy(name, scorer, task, state), state, task, 8)
                assert program.status != INFEASIBLE
                for before, step in zip(program.states, program.steps, strict=False):
                    for action in [step.action, *(a for a, _ in step.alternatives)]:
                        assert action.primitive == DONE or try_execute(before, action) is not None, (name, action)
    assert greedy_infeasible > 10  # the same scorers without the check do propose such steps


def test_among_the_steps_that_can_run_it_takes_the_best_scored(scenarios, benchmark_steps):
    scorer = _scorers(benchmark_steps)[1]
    for state, task in scenarios[:10]:
        ctx = step_context(state, task, [])
        ranked = scorer.top_k(ctx, len(candidate_index(ctx.n)[0]))
        runnable = [(y, s) for y, s in ranked
                    if ctx.action(y).primitive == DONE or try_execute(state, ctx.action(y)) is not None]
        assert feasible(scorer, top_k=3)(ctx, state) == runnable[:3]
        assert feasible(scorer)(ctx, state) == runnable[:3]  # three by default, as `plan` offers an observer
        assert feasible(scorer, top_k=1)(ctx, state) == runnable[:1]


def test_the_feasible_steps_method_is_a_labelled_row_sharing_the_dagger_models():
    methods = Lineup(Methods(), Selection(dict.fromkeys(specs(), 2.0), source="s")).factories()
    feasible_method, dagger = methods["feasible"](), methods["dagger"]()
    assert feasible_method.learner_params() == dagger.learner_params()
    assert feasible_method.features == dagger.features == "relations"
    assert list(methods).index("feasible") > list(methods).index("dagger")  # added rows after the built-in ones


def test_the_choice_cues_with_feasible_steps_share_the_choice_cue_models():
    methods = Lineup(Methods(), Selection({**dict.fromkeys(specs(), 2.0), "choice": 3.0, "choice_feasible": 3.0},
                                          source="s")).factories()
    both, choice = methods["choice_feasible"](), methods["choice"]()
    assert both.learner_params() == choice.learner_params() and both.features == choice.features == "choice"
    assert (both.policy, choice.policy) == ("feasible", "greedy")


def test_the_lookahead_rows_are_the_choice_cue_models_with_the_lookahead():
    methods = Lineup(Methods(), Selection({**dict.fromkeys(specs(), 2.0), "choice": 3.0, "choice_lookahead": 3.0},
                                          source="s")).factories()
    look, choice = methods["choice_lookahead"](), methods["choice"]()
    assert look.learner_params() == choice.learner_params() and look.features == "choice"
    assert look.policy == "lookahead"
    chained = methods["choice_chained_lookahead"]()
    assert (chained.features, chained.chained_starts, chained.policy) == ("choice", True, "lookahead")
