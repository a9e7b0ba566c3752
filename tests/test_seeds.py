"""Figures over world seeds: means, spreads and per-seed rows from hand-made per-world results."""

import json

import pytest

from taskseq.report.seeds import (
    curve_over_seeds,
    failure_shares,
    failures_over_seeds,
    headline_over_seeds,
    mean_sd,
    table1_over_seeds,
)


def test_mean_and_sample_sd():
    assert mean_sd([60.0, 70.0, 80.0]) == (70.0, 10.0)
    assert mean_sd([55.5]) == (55.5, 0.0)
    with pytest.raises(ValueError):
        mean_sd([])


@pytest.fixture
def worlds(tmp_path):
    dirs = {}
    for seed, (arg, succ, kinds) in {0: (60.0, 80.0, (6, 2, 2)), 3: (80.0, 90.0, (8, 1, 1))}.items():
        d = tmp_path / str(seed)
        d.mkdir()
        (d / "table1.csv").write_text(f"method,column,prim,arg\nours - full,sequence,90.00,{arg:.2f}\n"
                                      "multiclass,average,95.00,\n")
        programs = {"exact": kinds[0], "wrong_object": kinds[1], "step_cap": kinds[2]}
        (d / "crossval.json").write_text(json.dumps({"full": {
            "steps": {"average/prim": 95.0, "average/arg": 88.0}, "sequence/arg": arg, "success": succ,
            "programs": programs, "per_task": {"pour": {"programs": programs}}}}))
        (d / "noise.csv").write_text(f"rate,sequence_arg,sequence_prim,success\n0.0,{arg},90,{succ}\n")
        dirs[seed] = d
    return dirs


def test_table1_keeps_every_seed_and_gives_mean_and_spread(worlds):
    per_seed, table = table1_over_seeds(worlds)
    assert [(r["world_seed"], r["arg"]) for r in per_seed if r["column"] == "sequence"] == [(0, 60.0), (3, 80.0)]
    full = next(r for r in table if r["method"] == "ours - full")
    assert full["arg"] == 70.0 and full["arg_sd"] == pytest.approx(14.142, abs=1e-3)
    multiclass = next(r for r in table if r["method"] == "multiclass")
    assert multiclass["arg"] is None and multiclass["prim"] == 95.0


def test_headline_and_failures_over_seeds(worlds):
    from taskseq.report.seeds import crossval_over_seeds

    summaries = crossval_over_seeds(worlds)
    rows, means = headline_over_seeds(summaries)
    assert len(rows) == 2 and means["full"]["sequence_arg"] == 70.0 and means["full"]["sequence_arg_min"] == 60.0
    assert means["full"]["success"] == 85.0
    failures = failures_over_seeds(summaries)
    shares = failure_shares(failures, "full")
    assert shares["exact"] == pytest.approx((70.0, 14.142), abs=1e-3)
    assert shares["wrong_object"][0] == 15.0 and shares["infeasible_step"] == (0.0, 0.0)


def test_a_curve_is_averaged_per_key(worlds):
    per_seed, curve = curve_over_seeds(worlds, "noise.csv", ["rate"], ["sequence_arg", "success"])
    assert len(per_seed) == 2 and curve[0]["rate"] == "0.0" and curve[0]["sequence_arg"] == 70.0


def test_a_bad_number_names_the_file_record_and_field(worlds):
    (worlds[3] / "noise.csv").write_text("rate,sequence_arg,sequence_prim,success\n0.0,lots,90,80\n")
    with pytest.raises(ValueError, match=r"noise.csv: record 2, field 'sequence_arg'"):
        curve_over_seeds(worlds, "noise.csv", ["rate"], ["sequence_arg", "success"])


def test_a_missing_world_is_named(worlds):
    (worlds[0] / "table1.csv").unlink()
    with pytest.raises(FileNotFoundError, match="table1.csv: missing"):
        table1_over_seeds(worlds)
