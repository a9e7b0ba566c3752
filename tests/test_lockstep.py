"""Programs run together (`plan.planner.run_programs`): the steps of many programs scored in one batch give the
programs each gives alone, bit for bit."""

from __future__ import annotations

import numpy as np
import pytest

from taskseq.demonstrations.records import parse_record, state_from_dict
from taskseq.features.context import step_context
from taskseq.learn.estimator import StepScorer
from taskseq.plan.planner import POLICIES, Memo, learned_policy, program, run_loop, run_programs


@pytest.fixture(scope="module")
def scenarios(benchmark_tables):
    """Every other scenario of the tiny world: rooms of different sizes, so a batch pads most of its steps."""
    out = []
    for item in benchmark_tables[1][::2]:
        specs, task, _ = parse_record(item.record)
        out.append((state_from_dict(specs, item.record["steps"][0]["state"]), task))
    return out


@pytest.fixture(scope="module", params=["full", "choice"])
def scorers(request, benchmark_steps):
    """A fitted planner, whose programs mostly finish, and one of random weights, whose programs wander, loop and
    hit the step cap: between them every way a program ends. `choice` has every factor of the score (relations,
    their low-rank pair term, cues); `full` the paper's."""
    contexts, _ = benchmark_steps
    fitted = StepScorer(request.param, C=1.0, tol=0.05, max_iter=30).fit(contexts[:60])
    rng = np.random.default_rng(3)
    return [fitted, StepScorer.from_weights(request.param, rng.normal(size=fitted.w_.shape))]


def test_steps_scored_together_score_the_bits_they_score_alone(scorers, benchmark_steps):
    contexts, _ = benchmark_steps
    steps = contexts[::7]
    assert len({x.n for x in steps}) > 1  # the batch pads
    for scorer in scorers:
        together = scorer.scored(steps)
        for x, scored in zip(steps, together, strict=True):
            candidates, scores = scorer.model_.scores(x, scorer.w_)
            assert scored.scores.tobytes() == scores.tobytes()
            assert all(np.array_equal(a, b) for a, b in zip(scored.candidates, candidates, strict=True))
            assert scored.top_k(5) == scorer.top_k(x, 5)


@pytest.mark.parametrize("policy", POLICIES)
def test_programs_run_together_are_the_programs_run_alone(scorers, scenarios, policy):
    for scorer in scorers:
        def made(state, task, scorer=scorer):
            return learned_policy(policy, scorer, task, state), state, task, 12

        alone = [run_loop(*made(state, task), memo=Memo()) for state, task in scenarios]
        together = run_programs(scorer, [program(*made(state, task), memo=Memo()) for state, task in scenarios])
        assert len(together) == len(alone)
        for a, b in zip(alone, together, strict=True):
            assert (a.status, a.error) == (b.status, b.error)
            assert [(s.action, s.score, s.alternatives, s.unsafe) for s in a.steps] == \
                [(s.action, s.score, s.alternatives, s.unsafe) for s in b.steps]
            assert [s.key() for s in a.states] == [s.key() for s in b.states]
    assert len({tuple(map(str, p.actions)) for p in alone}) > 1  # the random planner's programs differ


def test_the_steps_of_programs_run_together_are_scored_in_batches(scorers, scenarios, monkeypatch):
    """Run together, the programs' steps reach the planner in batches, not one by one (each program's first step
    comes in one batch with the others')."""
    sizes: list[int] = []
    scorer = scorers[0]
    real = scorer.scored

    def spy(contexts):
        sizes.append(len(contexts))
        return real(contexts)

    monkeypatch.setattr(scorer, "scored", spy)
    run_programs(scorer, [program(learned_policy("lookahead", scorer, task, state), state, task, 12)
                          for state, task in scenarios])
    assert sizes[0] == len(scenarios) and max(sizes) > 1 and sum(sizes) > len(sizes)


def test_a_method_that_runs_its_own_policy_runs_it_together_too(scorers, scenarios):
    """`ScorerMethod.run_all` takes the policy `run` takes (`policy_for`), so a variant that changes the policy
    alone (the lookahead grid's) runs its own in both."""
    from dataclasses import dataclass

    from taskseq.evaluate.methods import ScorerMethod
    from taskseq.plan.planner import lookahead
    from taskseq.sim.scenarios import Scenario

    @dataclass
    class Shallow(ScorerMethod):
        def policy_for(self, scenario):
            return lookahead(self.planner_, scenario.task, scenario.initial, depth=1, width=1)

    method, default = Shallow(), ScorerMethod(policy="lookahead")
    method.planner_ = default.planner_ = scorers[1]
    chosen = [Scenario(f"env{i}", task, state, ()) for i, (state, task) in enumerate(scenarios)]
    alone = [method.run(sc, 12).actions for sc in chosen]
    assert [p.actions for p in method.run_all(chosen, 12)] == alone
    assert [p.actions for p in default.run_all(chosen, 12)] != alone  # the variant's policy is its own


def test_a_lookahead_program_builds_each_worlds_context_once(scorers, scenarios, monkeypatch):
    """The loop takes the context the lookahead built when it imagined the world the program reached: each
    (world, last two steps) a program meets is made into a context once."""
    import taskseq.plan.planner as planner

    built: list[tuple] = []

    def counted(state, task, history, gold=None):
        built.append((state.key(), tuple(history[-2:])))
        return step_context(state, task, history, gold)

    monkeypatch.setattr(planner, "step_context", counted)
    for state, task in scenarios[:8]:
        built.clear()
        ran = run_loop(learned_policy("lookahead", scorers[0], task, state), state, task, 12)
        assert len(ran.steps) > 1
        assert len(built) == len(set(built))


def test_noise_and_feedback_replays_run_together_are_their_programs_run_alone(scorers, benchmark_tables):
    """`robustness._replayed` runs each condition's programs of every test scenario together; each outcome is the
    one its program gives alone, with no memo, perception and observer made as the replay makes them."""
    from types import SimpleNamespace

    import numpy as np

    from taskseq.demonstrations.benchmark import Benchmark
    from taskseq.experiments.crossval import judge
    from taskseq.experiments.robustness import FeedbackCondition, NoiseCondition, _replayed, observer
    from taskseq.features.perception import flip_masks, noisy_perception

    scenarios = Benchmark.from_records([item.record for item in benchmark_tables[1]]).scenarios
    test = sorted(scenarios)[::3]
    conditions = [NoiseCondition(0.0, 0), NoiseCondition(0.2, 0), NoiseCondition(0.2, 1), FeedbackCondition(2, 1),
                  FeedbackCondition(3, 20)]
    order = sorted(scenarios)
    method = SimpleNamespace(policy="lookahead", planner_=scorers[0])
    replayed = _replayed(method, scenarios, set(test), conditions, 12, seed=5)
    expected = []
    for c in conditions:
        for sid in test:
            sc = scenarios[sid]
            perceive = choose = None
            if isinstance(c, NoiseCondition):
                rng = np.random.default_rng([5, c.draw, order.index(sid)])
                perceive = noisy_perception(flip_masks(sorted(sc.initial.specs), c.rate, rng))
            else:
                choose = observer(sc.demonstrations, c.n)
            top_k = c.k if isinstance(c, FeedbackCondition) else 3
            policy = learned_policy("lookahead", scorers[0], sc.task, sc.initial, top_k, perceive)
            expected.append((c, judge(sc, run_loop(policy, sc.initial, sc.task, 12, perceive, choose))))
    assert replayed == expected
    assert len({o.actions for _, o in replayed}) > len(test)  # the conditions change programs
