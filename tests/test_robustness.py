"""Attribute noise and observer feedback hooks of the planner."""

import numpy as np
import pytest

from taskseq.demonstrations.benchmark import Benchmark
from taskseq.evaluate.methods import ScorerMethod
from taskseq.experiments.robustness import observer
from taskseq.features.context import step_context
from taskseq.features.perception import BINARY_COLUMNS, flip_masks, noisy_perception
from taskseq.plan.planner import plan
from taskseq.sim.primitives import Action


@pytest.fixture(scope="module")
def fitted(benchmark_steps, benchmark_tables):
    contexts, meta = benchmark_steps
    keep = [i for i, m in enumerate(meta) if m.sequence_id.startswith(("env01/", "env02/", "env03/"))]
    method = ScorerMethod(C=5.0, tol=1e-3, max_iter=300).fit([contexts[i] for i in keep], [meta[i] for i in keep])
    scenarios = Benchmark.from_records([i.record for i in benchmark_tables[1]]).scenarios
    return method, [s for sid, s in sorted(scenarios.items()) if sid.startswith(("env01/", "env02/", "env03/"))]


def test_flip_rate_zero_changes_nothing_and_one_flips_every_binary_attribute(fitted):
    _, scenarios = fitted
    sc = scenarios[0]
    ctx = step_context(sc.initial, sc.task, [])
    ids = sorted(sc.initial.specs)
    same = noisy_perception(flip_masks(ids, 0.0, np.random.default_rng(0)))(ctx)
    np.testing.assert_array_equal(same.objects, ctx.objects)
    flipped = noisy_perception(flip_masks(ids, 1.0, np.random.default_rng(0)))(ctx)
    np.testing.assert_array_equal(flipped.objects[:, BINARY_COLUMNS], 1.0 - ctx.objects[:, BINARY_COLUMNS])
    other = [c for c in range(ctx.objects.shape[1]) if c not in BINARY_COLUMNS]
    np.testing.assert_array_equal(flipped.objects[:, other], ctx.objects[:, other])


def test_noise_rate_zero_plans_exactly_as_without_noise(fitted):
    method, scenarios = fitted
    for sc in scenarios[:6]:
        clean = plan(method.planner_, sc.initial, sc.task)
        masks = flip_masks(sorted(sc.initial.specs), 0.0, np.random.default_rng(1))
        noisy = plan(method.planner_, sc.initial, sc.task, perceive=noisy_perception(masks))
        assert noisy.actions == clean.actions
        assert [s.score for s in noisy.steps] == [s.score for s in clean.steps]


def test_observer_picks_the_offered_candidate_that_continues_a_demonstration():
    demo = (Action.parse("move_close(obj1)"), Action.parse("grasp(obj1)"))
    choose = observer((demo,), n_feedback=1)
    offered = [Action.parse("move_close(obj2)"), Action.parse("move_close(obj1)")]
    assert choose([], offered) == 1
    assert choose([demo[0]], [Action.parse("release(obj1)"), demo[1]]) == 0  # past the feedback steps
    assert observer((demo,), 5)(list(demo), [Action.parse("grasp(obj1)"), Action("done")]) == 1
    assert choose([], [Action.parse("grasp(obj3)")]) == 0  # nothing right on offer: the robot's choice


def test_full_feedback_never_does_worse(fitted):
    method, scenarios = fitted
    for sc in scenarios:
        free = plan(method.planner_, sc.initial, sc.task)
        guided = plan(method.planner_, sc.initial, sc.task, top_k=3, choose=observer(sc.demonstrations, 20))
        if free.actions in [list(d) for d in sc.demonstrations]:
            assert guided.actions in [list(d) for d in sc.demonstrations]


def test_feedback_command_refuses_a_bad_step_count(capsys):
    from taskseq.cli import main

    assert main(["--no-mlflow", "feedback", "--set", "feedback.n=1 two", "--output", "unused"]) == 2
    err = capsys.readouterr().err
    assert "feedback.n must list whole numbers of steps or 'all', got 'two'" in err
    assert err.splitlines()[-1] == "nothing was written"  # a stage refusing a value says what it wrote, as any stop


def test_a_stage_says_what_it_wrote_itself_when_one_process_runs_several(tmp_path, capsys):
    """`taskseq.cli.main` run twice in a process (tests, a notebook): the second stage's stop counts only its own
    writes, not the first's."""
    from taskseq.cli import main

    assert main(["--no-mlflow", "generate", "--world-seed", "0", "--output", str(tmp_path / "raw")]) == 0
    assert any((tmp_path / "raw").glob("*.jsonl"))
    capsys.readouterr()
    assert main(["--no-mlflow", "feedback", "--set", "feedback.n=1 two", "--output", str(tmp_path / "unused")]) == 2
    assert capsys.readouterr().err.splitlines()[-1] == "nothing was written"
