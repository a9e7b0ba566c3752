"""Noisy copies of training steps, and the method that trains on them (`ours + relations + noisy training`)."""

from __future__ import annotations

import numpy as np
import pytest

from taskseq.evaluate.methods import ScorerMethod
from taskseq.features.perception import BINARY_COLUMNS, noisy_copies
from taskseq.learn.persist import describe
from taskseq.methods import Lineup
from taskseq.selection import Selection
from taskseq.settings import Params


@pytest.fixture(scope="module")
def steps(benchmark_steps):
    """The steps of the benchmark's first six scenarios."""
    contexts, meta = benchmark_steps
    first = list(dict.fromkeys(m.scenario_id for m in meta))[:6]
    keep = [i for i, m in enumerate(meta) if m.scenario_id in first]
    return [contexts[i] for i in keep], [meta[i] for i in keep]


def _flipped(original, copy) -> dict[str, tuple[int, ...]]:
    """Per object id, the binary columns whose value differs between a step and its copy."""
    diff = original.objects[:, BINARY_COLUMNS] != copy.objects[:, BINARY_COLUMNS]
    return {o: tuple(np.flatnonzero(diff[i])) for i, o in enumerate(original.object_ids)}


def test_copies_keep_each_steps_label_and_meta_and_change_only_binary_attributes(steps):
    contexts, meta = steps
    copies, copies_meta = noisy_copies(contexts, meta, 0.3, 2)
    assert len(copies) == 2 * len(contexts) and copies_meta == meta + meta
    other = [c for c in range(contexts[0].objects.shape[1]) if c not in BINARY_COLUMNS]
    for k, copy in enumerate(copies):
        original = contexts[k % len(contexts)]
        assert copy.gold == original.gold and copy.object_ids == original.object_ids
        np.testing.assert_array_equal(copy.objects[:, other], original.objects[:, other])
        assert copy.relations is original.relations and copy.task == original.task
    changed = np.mean([(c.objects[:, BINARY_COLUMNS] != o.objects[:, BINARY_COLUMNS]).mean()
                       for c, o in zip(copies, contexts + contexts, strict=True)])
    assert 0.2 < changed < 0.4  # about the rate


def test_a_copy_of_a_scenario_sees_the_same_flips_at_every_step(steps):
    contexts, meta = steps
    copies, _ = noisy_copies(contexts, meta, 0.3, 2)
    for c in range(2):
        seen: dict[str, dict[str, tuple[int, ...]]] = {}
        for k, (x, m) in enumerate(zip(contexts, meta, strict=True)):
            flips = _flipped(x, copies[c * len(contexts) + k])
            assert seen.setdefault(m.scenario_id, flips) == flips
    first = [k for k, m in enumerate(meta) if m.scenario_id == meta[0].scenario_id][0]
    assert _flipped(contexts[first], copies[first]) != _flipped(contexts[first], copies[len(contexts) + first])


def test_a_scenarios_copies_do_not_depend_on_the_other_training_scenarios(steps):
    contexts, meta = steps
    alone = [k for k, m in enumerate(meta) if m.scenario_id == meta[-1].scenario_id]
    with_all, _ = noisy_copies(contexts, meta, 0.3, 1)
    by_itself, _ = noisy_copies([contexts[k] for k in alone], [meta[k] for k in alone], 0.3, 1)
    for k, copy in zip(alone, by_itself, strict=True):
        np.testing.assert_array_equal(with_all[k].objects, copy.objects)


def test_the_rate_decides_how_much_is_flipped(steps):
    contexts, meta = steps
    same, _ = noisy_copies(contexts, meta, 0.0, 1)
    every, _ = noisy_copies(contexts, meta, 1.0, 1)
    for x, s, e in zip(contexts, same, every, strict=True):
        np.testing.assert_array_equal(s.objects, x.objects)
        np.testing.assert_array_equal(e.objects[:, BINARY_COLUMNS], 1.0 - x.objects[:, BINARY_COLUMNS])
    assert noisy_copies(contexts, meta, 0.5, 0) == ([], [])


@pytest.mark.parametrize(("rate", "copies", "message"), [(-0.1, 1, "flip rate"), (1.5, 1, "flip rate"),
                                                          (0.1, -1, "number of copies")])
def test_a_bad_rate_or_number_of_copies_is_named(steps, rate, copies, message):
    contexts, meta = steps
    with pytest.raises(ValueError, match=message):
        noisy_copies(contexts, meta, rate, copies)


def test_steps_and_meta_of_different_lengths_are_refused(steps):
    contexts, meta = steps
    with pytest.raises(ValueError, match="zip"):
        noisy_copies(contexts, meta[:-1], 0.1, 1)


def test_the_method_trains_on_its_steps_and_their_copies_under_a_key_of_its_own(steps):
    contexts, meta = steps
    plain = ScorerMethod(features="relations", C=1.0, tol=0.05, max_iter=5)
    noisy = ScorerMethod(features="relations", C=1.0, tol=0.05, max_iter=5, noise_rate=0.2, noise_copies=2)
    assert "noise_copies" not in plain.learner_params()  # the other methods' stored models keep their keys
    assert noisy.learner_params()["noise_copies"] == 2 and noisy.learner_params()["noise_rate"] == 0.2
    assert plain.key(contexts) != noisy.key(contexts)
    assert noisy.key(contexts) != ScorerMethod(features="relations", C=1.0, tol=0.05, max_iter=5, noise_rate=0.1,
                                            noise_copies=2).key(contexts)
    assert noisy.fit(contexts, meta).planner_.n_steps_ == 3 * len(contexts)
    assert plain.fit(contexts, meta).planner_.n_steps_ == len(contexts)
    again = ScorerMethod(features="relations", C=1.0, tol=0.05, max_iter=5, noise_rate=0.2, noise_copies=2)
    np.testing.assert_array_equal(again.fit(contexts, meta).planner_.w_, noisy.planner_.w_)  # the same bytes


def test_the_registered_method_takes_its_own_settings_from_its_entry():
    methods = Params.load(None, ["methods.noise_trained.noise_rate=0.25"]).methods
    lineup = Lineup(methods, Selection({"noise_trained": 2.0}, source="s"))
    method = lineup.factory("noise_trained")()
    assert (method.features, method.noise_rate, method.noise_copies, method.C, method.policy) == \
        ("relations", 0.25, 3, 2.0, "greedy")  # the copies at their default


def test_a_model_file_says_how_many_noisy_copies_it_trained_on():
    meta = {"features": "relations", "method": "noise_trained", "C": 3.0, "tol": 0.001, "max_iter": 2000,
            "n_slacks": 0, "chained_starts": False, "dagger_rounds": 0, "policy": "greedy", "noise_rate": 0.1,
            "noise_copies": 2}
    assert "2 noisy copies at flip rate 0.1" in describe(meta)
    assert "noisy" not in describe({**meta, "noise_copies": 0})


@pytest.mark.parametrize(("setting", "message"), [("noise_rate=1.5", r"noise_rate must lie in \[0, 1\]"),
                                                  ("noise_rate=-0.1", r"noise_rate must lie in \[0, 1\]"),
                                                  ("noise_copies=-1", "noise_copies must be at least 0")])
def test_noisy_training_settings_are_checked_where_the_methods_are_configured(setting, message):
    with pytest.raises(ValueError, match=message):
        Lineup(Params.load(None, [f"methods.noise_trained.{setting}"]).methods).factory("noise_trained")
    for rate in ("0.0", "1.0"):  # both ends of the range are probabilities
        methods = Params.load(None, [f"methods.noise_trained.noise_rate={rate}",
                                     "methods.noise_trained.noise_copies=0"]).methods
        assert Lineup(methods).factory("noise_trained")().noise_copies == 0


def test_each_copy_is_the_draw_seeded_by_its_copy_scenario_and_objects(steps):
    # the copies are made once per (copy, scenario, objects); each must equal the draw made at its own step, so
    # noisy training's fits (and their cached keys) keep their bytes
    from zlib import crc32

    from taskseq.features.perception import flip_masks, noisy_perception

    contexts, meta = steps
    copies, _ = noisy_copies(contexts, meta, 0.3, 2)
    for k, copy in enumerate(copies):
        c, x, m = k // len(contexts), contexts[k % len(contexts)], meta[k % len(contexts)]
        rng = np.random.default_rng([c, crc32(m.scenario_id.encode())])
        drawn = noisy_perception(flip_masks(sorted(x.object_ids), 0.3, rng))(x)
        assert copy.objects.tobytes() == drawn.objects.tobytes()
