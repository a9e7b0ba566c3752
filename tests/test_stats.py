"""Intervals and paired tests of Table I on hand-made outcomes whose answers are known."""

from __future__ import annotations

import json
from math import comb

import numpy as np
import pytest

from taskseq.cli import main
from taskseq.report.csvs import SEQUENCE_COLUMNS, STEP_COLUMNS, csv_text
from taskseq.report.stats import (
    World,
    best_baseline,
    bootstrap_rates,
    confidence_intervals,
    holm,
    mcnemar_exact,
    paired_comparisons,
    world_outcomes,
)
from taskseq.report.stats_tables import p_text


def programs(method: str, right: list[int], prefix: str = "s") -> list[dict[str, str]]:
    """One program per scenario: arg, prim and success all equal to `right`."""
    return [{"method": method, "scenario": f"{prefix}{i:03d}", "arg_correct": str(v), "prim_correct": str(v),
             "success": str(v)} for i, v in enumerate(right)]


def world(outcomes: dict[str, list[int]]) -> World:
    return world_outcomes([r for m, right in outcomes.items() for r in programs(m, right)], [])


def test_mcnemar_counts_the_discordant_pairs_and_gives_the_exact_binomial_p():
    # 8 programs only the method gets right, 2 only the other does, 5 both, 3 neither
    a = [1] * 8 + [0] * 2 + [1] * 5 + [0] * 3
    b = [0] * 8 + [1] * 2 + [1] * 5 + [0] * 3
    better, worse, p = mcnemar_exact(np.array(a), np.array(b))
    assert (better, worse) == (8, 2)
    assert p == pytest.approx(2 * sum(comb(10, k) for k in (8, 9, 10)) / 2 ** 10)  # 0.109375
    assert mcnemar_exact(np.array(b), np.array(a))[2] == pytest.approx(p)  # two-sided: symmetric
    assert mcnemar_exact(np.array([1, 0, 1]), np.array([1, 0, 1])) == (0, 0, 1.0)  # no discordant pair
    assert mcnemar_exact(np.array([1, 0]), np.array([0, 1]))[2] == 1.0
    with pytest.raises(ValueError, match="same length"):
        mcnemar_exact(np.array([1, 0]), np.array([1]))


def test_all_equal_outcomes_give_a_zero_width_interval():
    worlds = [world({"m": [1] * 20, "n": [0] * 20}), world({"m": [1] * 30, "n": [0] * 30})]
    out = {(r.method, r.figure): r for r in confidence_intervals(worlds, 300, 0)}
    assert (out[("m", "sequence_arg")].low, out[("m", "sequence_arg")].high) == (100.0, 100.0)
    assert (out[("n", "success")].low, out[("n", "success")].value, out[("n", "success")].high) == (0.0, 0.0, 0.0)


def test_worlds_are_resampled_as_clusters():
    # one world all right, the other all wrong: a resample holds 0, 1 or 2 copies of the good world, so the figure
    # is 0, 50 or 100, and the 95% interval spans both ends; the scenarios inside each world change nothing
    worlds = [world({"m": [1] * 40}), world({"m": [0] * 40})]
    samples = bootstrap_rates(worlds, [("m", "sequence_arg")], 2000, 0)[:, 0]
    assert set(np.unique(samples)) == {0.0, 50.0, 100.0}
    assert np.mean(samples == 50.0) == pytest.approx(0.5, abs=0.05)
    (ci,) = [r for r in confidence_intervals(worlds, 2000, 0) if r.figure == "sequence_arg"]
    assert (ci.low, ci.value, ci.high) == (0.0, 50.0, 100.0)


def test_scenarios_are_resampled_within_a_world():
    # one world, 200 programs, half right: the interval is the binomial one, 50 ± 1.96 * sqrt(.25 / 200) * 100
    rng = np.random.default_rng(3)
    right = rng.permutation([1] * 100 + [0] * 100).tolist()
    (ci,) = [r for r in confidence_intervals([world({"m": right})], 4000, 0) if r.figure == "sequence_arg"]
    half = 1.96 * np.sqrt(0.25 / 200) * 100
    assert ci.value == 50.0
    assert ci.low == pytest.approx(50 - half, abs=1.0) and ci.high == pytest.approx(50 + half, abs=1.0)


def test_the_bootstrap_is_deterministic_given_its_seed():
    worlds = [world({"m": [1, 0, 1, 1, 0] * 6}), world({"m": [0, 0, 1, 1, 1] * 6})]
    key = [("m", "sequence_arg")]
    assert np.array_equal(bootstrap_rates(worlds, key, 500, 7), bootstrap_rates(worlds, key, 500, 7))
    assert not np.array_equal(bootstrap_rates(worlds, key, 500, 7), bootstrap_rates(worlds, key, 500, 8))


def test_step_figures_pool_the_seven_primitives_of_each_scenario_and_leave_done_out():
    steps = [{"method": "m", "scenario": s, "primitive": p, "prim_correct": pc, "arg_correct": ac}
             for s, p, pc, ac in [("a", "grasp", "1", "1"), ("a", "release", "1", "0"), ("a", "done", "0", "0"),
                                  ("b", "grasp", "0", "0"), ("b", "done", "1", "1")]]
    steps += [{"method": "k", "scenario": "a", "primitive": "grasp", "prim_correct": "1", "arg_correct": ""}]
    sequences = [{**r, "scenario": s} for r, s in zip(programs("m", [1, 0]), "ab", strict=True)]
    w = world_outcomes(sequences, steps)
    assert w.scenarios == ("a", "b")
    assert w.rate(("m", "average_prim")) == pytest.approx(100 * 2 / 3)
    assert w.rate(("m", "average_arg")) == pytest.approx(100 * 1 / 3)
    assert ("k", "average_prim") in w.hits and ("k", "average_arg") not in w.hits  # no arguments, no arg figure


def test_a_method_missing_a_scenario_cannot_be_paired():
    rows = programs("m", [1, 1, 0]) + programs("n", [1, 0])
    with pytest.raises(ValueError, match="method n has no program for scenarios"):
        world_outcomes(rows, [])
    with pytest.raises(ValueError, match="twice"):
        world_outcomes(programs("m", [1]) + programs("m", [0]), [])


def test_holm_adjusts_step_down():
    assert holm([0.01, 0.04, 0.03]) == pytest.approx([0.03, 0.06, 0.06])
    assert holm([0.5, 0.9]) == pytest.approx([1.0, 1.0])


def test_paired_comparison_of_a_method_better_on_exactly_the_discordant_pairs_built():
    # two worlds; the method fixes 6 programs the paper's model gets wrong and breaks 1 it gets right
    full = [[1] * 10 + [0] * 4 + [1] * 1, [1] * 8 + [0] * 2 + [0] * 5]
    ours = [[1] * 10 + [1] * 4 + [0] * 1, [1] * 8 + [1] * 2 + [0] * 5]
    worlds = [world({"full": f, "ours": o, "chance": [0] * 15}) for f, o in zip(full, ours, strict=True)]
    rows = paired_comparisons(worlds, [("ours", "full", "paper")], 1000, 0)
    arg = next(r for r in rows if r.figure == "sequence_arg")
    assert (arg.better, arg.worse, arg.pairs) == (6, 1, 30)
    assert arg.p_value == pytest.approx(2 * (comb(7, 6) + comb(7, 7)) / 2 ** 7)
    assert arg.difference == pytest.approx(100 * 5 / 30)  # net five programs of thirty
    assert arg.low <= arg.difference <= arg.high
    assert best_baseline(worlds, ["chance", "full"]) == "full"


def write_world(path, seed: int, added: tuple[tuple[str, float], ...] = (("relations", 0.8),)) -> None:
    rng = np.random.default_rng(seed)
    rows, steps = [], []
    for method, p in (("chance", 0.0), ("symb_plan_manual", 0.5), ("full", 0.6), *added):
        for i in range(40):
            right = int(rng.random() < p)
            rows.append({"method": method, "fold": i % 6, "scenario": f"s{i:02d}", "task": "pour", "status": "done",
                         "prim_correct": right, "arg_correct": right, "goal_reached": right, "safe": 1,
                         "success": right, "failure": "exact" if right else "wrong_object", "program": ""})
            steps += [{"method": method, "fold": i % 6, "scenario": f"s{i:02d}", "sequence": f"s{i:02d}/0",
                       "step": k, "primitive": "grasp", "prim_correct": right, "arg_correct": right}
                      for k in range(3)]
    path.mkdir(parents=True)
    (path / "crossval_sequences.csv").write_text(csv_text(SEQUENCE_COLUMNS, rows))
    (path / "crossval_steps.csv").write_text(csv_text(STEP_COLUMNS, steps))


def test_stats_stage_writes_intervals_and_comparisons_the_same_bytes_every_run(tmp_path):
    for seed in (0, 3):
        write_world(tmp_path / "worlds" / str(seed), seed)
    args = ["stats", "--worlds", str(tmp_path / "worlds"), "--set", "world.seeds=0 3", "--set", "stats.resamples=300"]
    assert main([*args, "--output", str(tmp_path / "a")]) == 0
    assert main([*args, "--output", str(tmp_path / "b")]) == 0
    for name in ("table1_ci.csv", "table1_ci.md", "comparisons.csv", "comparisons.md"):
        assert (tmp_path / "a" / name).read_bytes() == (tmp_path / "b" / name).read_bytes(), name
    comparisons = (tmp_path / "a" / "comparisons.csv").read_text().splitlines()
    # the one added method, against the paper's model and against the best baseline (symb-plan-manual, not chance)
    assert [r.split(",")[:3] for r in comparisons[1:]] == [["relations", "full", "paper"]] * 3 + \
        [["relations", "symb_plan_manual", "baseline"]] * 3
    md = (tmp_path / "a" / "table1_ci.md").read_text()
    assert "| ours + relations |" in md and "300 resamples (seed 0)" in md


def test_with_a_selection_every_added_method_is_also_paired_with_the_shipped_planner_but_itself(tmp_path):
    for seed in (0, 3):
        write_world(tmp_path / "worlds" / str(seed), seed, (("relations", 0.8), ("choice", 0.9)))
    args = ["stats", "--worlds", str(tmp_path / "worlds"), "--set", "world.seeds=0 3", "--set", "stats.resamples=300"]
    # the shipped planner is an added method, then the paper's model (whose pairs are rows already)
    for shipped, name in (("choice", "added"), ("full", "paper")):
        selection = tmp_path / f"{name}.json"
        selection.write_text(json.dumps({"method": shipped, "settings": {shipped: {"C": 1.0}}}))
        assert main([*args, "--selection", str(selection), "--output", str(tmp_path / name)]) == 0

    def pairs(name: str) -> list[list[str]]:
        rows = (tmp_path / name / "comparisons.csv").read_text().splitlines()[1:]
        return list(dict.fromkeys(tuple(r.split(",")[:3]) for r in rows))

    both = [("relations", "full", "paper"), ("relations", "symb_plan_manual", "baseline"),
            ("choice", "full", "paper"), ("choice", "symb_plan_manual", "baseline")]
    assert pairs("added") == [*both[:2], ("relations", "choice", "shipped"), *both[2:]]  # never choice with itself
    assert pairs("paper") == both
    assert "| ours + relations | ours + relations + choice cues (the shipped planner) | seq arg |" in \
        (tmp_path / "added" / "comparisons.md").read_text()


def test_p_values_print_with_two_digits_down_to_a_floor():
    assert [p_text(p) for p in (0.034, 0.00098, 1e-4, 9.9e-5, 0.0)] == ["0.034", "0.00098", "0.0001", "< 1e-4",
                                                                        "< 1e-4"]
