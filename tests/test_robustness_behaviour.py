"""Attribute noise and the rows of the robustness stages, on hand-made outcomes with known answers."""

from __future__ import annotations

import numpy as np
import pytest

from taskseq.experiments.crossval import SequenceOutcome
from taskseq.experiments.robustness import (
    FeedbackCondition,
    NoiseCondition,
    feedback_steps,
    noise_curve,
    noise_runs,
    rates,
)
from taskseq.features.context import OBJECT_COLUMNS, step_context
from taskseq.features.perception import BINARY_COLUMNS, flip_masks, noisy_perception
from taskseq.settings import Feedback, Noise
from taskseq.sim.objects import BINARY_ATTRIBUTES
from taskseq.sim.tasks import Task
from tests.conftest import world


def _outcome(prim: bool, arg: bool, success: bool) -> SequenceOutcome:
    return SequenceOutcome("s", "pour", (), "done", prim, arg, success, True, success, "exact")


def test_rates_each_come_from_their_own_field():
    outcomes = [_outcome(True, True, False), _outcome(True, False, False), _outcome(False, False, True),
                _outcome(True, False, False)]
    assert rates(outcomes) == {"sequence_arg": 25.0, "sequence_prim": 75.0, "success": 25.0}


def test_noise_runs_and_curve_average_the_draws_of_each_rate():
    settings = Noise(rates=(0.0, 0.2), draws=2)
    right, wrong = _outcome(True, True, True), _outcome(False, False, False)
    results = [(NoiseCondition(0.0, 0), right), (NoiseCondition(0.0, 1), right),
               (NoiseCondition(0.2, 0), right), (NoiseCondition(0.2, 0), wrong),
               (NoiseCondition(0.2, 1), wrong), (FeedbackCondition(0.2, 1), right)]
    runs = noise_runs(settings, results)
    assert [(r["rate"], r["seed"], r["sequence_arg"]) for r in runs] == [(0.0, 0, 100.0), (0.0, 1, 100.0),
                                                                        (0.2, 0, 50.0), (0.2, 1, 0.0)]
    curve = noise_curve(settings, runs)
    assert curve[0] == {"rate": 0.0, "sequence_arg": 100.0, "sequence_arg_std": 0.0, "sequence_prim": 100.0,
                        "success": 100.0}
    assert curve[1] == {"rate": 0.2, "sequence_arg": 25.0, "sequence_arg_std": 25.0, "sequence_prim": 25.0,
                        "success": 25.0}


def test_feedback_steps_read_all_as_the_step_cap():
    assert feedback_steps(Feedback(k=(2,), n=("0", "3", "all")), 17) == [0, 3, 17]


def test_flip_masks_draw_each_attribute_at_the_rate():
    ids = [f"o{i}" for i in range(400)]
    masks = flip_masks(ids, 0.25, np.random.default_rng(3))
    assert set(masks) == set(ids) and all(m.shape == (len(BINARY_ATTRIBUTES),) for m in masks.values())
    share = np.mean([m.mean() for m in masks.values()])
    assert 0.2 < share < 0.3
    again = flip_masks(ids, 0.25, np.random.default_rng(3))
    assert all((again[o] == masks[o]).all() for o in ids)  # the same draw from the same seed


def test_noisy_perception_flips_exactly_the_masked_attributes_of_each_object():
    state = world({2: 0.0}, [(14, 2, 0, 0.4), (20, 2, 0, -0.3)])
    ctx = step_context(state, Task("pick_and_place", ("obj14", "obj02")), [])
    assert [OBJECT_COLUMNS[c] for c in BINARY_COLUMNS] == list(BINARY_ATTRIBUTES)
    masks = {o: np.zeros(len(BINARY_ATTRIBUTES), dtype=bool) for o in ctx.object_ids}
    masks["obj14"][[0, 2]] = True
    seen = noisy_perception(masks)(ctx)
    i = ctx.object_ids.index("obj14")
    changed = np.argwhere(seen.objects != ctx.objects)
    assert sorted(map(tuple, changed)) == [(i, BINARY_COLUMNS[0]), (i, BINARY_COLUMNS[2])]
    assert (seen.objects[i, BINARY_COLUMNS[[0, 2]]] == 1.0 - ctx.objects[i, BINARY_COLUMNS[[0, 2]]]).all()
    np.testing.assert_array_equal(seen.task_rel, ctx.task_rel)


@pytest.mark.parametrize("rate", [0.0, 1.0])
def test_noise_at_the_extremes(rate):
    state = world({2: 0.0}, [(14, 2, 0, 0.4)])
    ctx = step_context(state, Task("pick_and_place", ("obj14", "obj02")), [])
    seen = noisy_perception(flip_masks(ctx.object_ids, rate, np.random.default_rng(0)))(ctx)
    expected = ctx.objects[:, BINARY_COLUMNS] if rate == 0.0 else 1.0 - ctx.objects[:, BINARY_COLUMNS]
    np.testing.assert_array_equal(seen.objects[:, BINARY_COLUMNS], expected)
