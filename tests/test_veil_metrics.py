"""Figures of the people's-demonstrations evaluation: edit distance, goal share, intervals, paired test."""

from __future__ import annotations

import pytest

from taskseq.veil.metrics import bootstrap_by_group, edit_distance, goal_share, nearest_edit_distance, paired_sign_flip


def test_edit_distance_counts_inserts_deletes_and_substitutions() -> None:
    assert edit_distance("kitten", "sitting") == 3
    assert edit_distance([], ["a", "b"]) == 2
    assert edit_distance(["a", "b"], ["a", "b"]) == 0
    assert edit_distance(["a", "b", "c"], ["a", "c"]) == 1


def test_nearest_edit_distance_takes_the_closest_person_over_the_longer_sequence() -> None:
    run = ["moveto", "grasp", "pour"]
    assert nearest_edit_distance(run, [["x", "y", "z", "w"], ["moveto", "grasp"]]) == pytest.approx(1 / 3)
    assert nearest_edit_distance(run, [run]) == 0.0
    with pytest.raises(ValueError, match="no reference"):
        nearest_edit_distance(run, [])


def test_goal_share_is_the_share_of_goal_facts_that_hold() -> None:
    goal = frozenset({("On", "a", "b"), ("state", "c", "Water")})
    assert goal_share(frozenset({("On", "a", "b")}), goal) == 0.5
    assert goal_share(frozenset(goal), goal) == 1.0
    assert goal_share(frozenset(), frozenset()) == 1.0


def test_the_bootstrap_resamples_groups_and_brackets_the_mean() -> None:
    values = [1.0, 1.0, 0.0, 0.0, 1.0, 0.0]
    groups = ["e1", "e1", "e2", "e2", "e3", "e3"]
    interval = bootstrap_by_group(values, groups, resamples=500, seed=3)
    assert interval.mean == pytest.approx(0.5)
    assert interval.low <= 0.5 <= interval.high
    assert interval.low >= 0.0 and interval.high <= 1.0 and interval.high > interval.low
    assert bootstrap_by_group(values, groups, resamples=500, seed=3) == interval  # deterministic
    one_group = bootstrap_by_group([0.25, 0.75], ["e", "e"], resamples=100)
    assert one_group.low == one_group.high == 0.5


def test_the_paired_test_separates_a_consistent_gain_from_noise() -> None:
    better = [0.9, 0.8, 0.95, 0.85, 0.9, 0.8, 0.9, 0.85, 0.95, 0.9, 0.8, 0.9]
    worse = [b - 0.2 for b in better]
    assert paired_sign_flip(better, worse, resamples=2000) < 0.01
    assert paired_sign_flip(better, better, resamples=2000) == 1.0
    mixed = [w + (0.01 if i % 2 else -0.01) for i, w in enumerate(worse)]
    assert paired_sign_flip(mixed, worse, resamples=2000) > 0.5
