"""`taskseq scaling` on two tiny drawn worlds: the JSON's shape and sane figures; bad plans refused by name."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from taskseq.bench.scaling import EVALUATE, PREPARE, Plan, growth
from taskseq.cli import main


def test_scaling_on_two_tiny_worlds(tmp_path: Path, capsys):
    out, plot, keep = tmp_path / "scaling.json", tmp_path / "scaling.png", tmp_path / "keep"
    # loose gaps and two folds: what is checked is the shape and the bookkeeping, not the figures' size; the
    # stages run in the pipeline's order whatever the order given
    assert main(["scaling", "--rooms", "2", "1", "--stages", "crossval", "fold_models", "--methods", "full",
                 "--set", "train.tol=0.5", "--set", "crossval.folds=2", "--tol", "0.5", "--C", "1",
                 "--n-jobs", "1", "--keep", str(keep), "--plot", str(plot), "--output", str(out)]) == 0
    result = json.loads(out.read_text())
    assert result["settings"]["rooms"] == [2, 1] and result["settings"]["C"] == 1.0
    sizes = result["sizes"]
    assert [s["rooms"] for s in sizes] == [1, 2]  # smallest first
    assert sizes[0]["steps"] < sizes[1]["steps"] and sizes[0]["scenarios"] < sizes[1]["scenarios"]
    for s in sizes:
        assert set(s["stages"]) == {*PREPARE, "fold_models", "crossval"}
        assert all(m["seconds"] > 0 and m["cpu_seconds"] > 0 and m["peak_rss_mib"] > 0 for m in s["stages"].values())
        t = s["train"]
        assert t["seconds"] > 0 and t["iterations"] >= 1 and t["converged"]
        assert t["ms_per_step"] == pytest.approx(1000 * t["seconds"] / s["steps"])
        assert t["peak_rss_mib"] >= t["loaded_rss_mib"] > 0
        assert t["dual_objective"] <= t["primal_objective"] * (1 + 1e-9)
        i = s["inference"]
        assert i["median_ms"] > 0 and 0 < i["steps_timed"] <= s["steps"] and i["candidates_max"] >= 1
        # every stage wrote where it was told, inside the kept world
        world = keep / f"rooms-{s['rooms']}"
        assert json.loads((world / "world.json").read_text())["environments"] == s["rooms"]
        assert (world / "folds" / "index.json").is_file() and (world / "crossval" / "table1.csv").is_file()
    assert set(result["growth"]) >= {"train_seconds", "inference_ms", "stage.generate", "stage.crossval"}
    assert plot.stat().st_size > 0
    text = capsys.readouterr().out
    assert "[2 rooms] crossval" in text and f"written to {out}" in text


@pytest.mark.parametrize(("change", "message"), [
    ({"rooms": ()}, "at least one size"),
    ({"rooms": (13, 13)}, "each size once"),
    ({"rooms": (0,)}, "positive whole numbers"),
    ({"stages": ("crossval",)}, "add fold_models to --stages"),
    ({"stages": ("train",)}, "unknown stage"),
    ({"tol": 0.0}, "tol must be positive"),
    ({"methods": ("full",), "stages": ("fold_models",)}, "add crossval"),
])
def test_a_plan_that_cannot_run_is_refused_by_name(change, message):
    plan = {"rooms": (1, 2), "stages": EVALUATE, "C": 1.0, "tol": 1e-3, "max_iter": 10, "n_slacks": 0} | change
    with pytest.raises(ValueError, match=message):
        Plan(**plan).check()


def test_bad_rooms_on_the_command_line_exit_with_one_line(tmp_path, capsys):
    assert main(["scaling", "--rooms", "ten", "--output", str(tmp_path / "s.json")]) == 2
    assert "rooms must be positive whole numbers, got 'ten'" in capsys.readouterr().err
    assert not (tmp_path / "s.json").exists()


def test_growth_is_the_log_log_slope_against_steps():
    def size(steps: int, seconds: float) -> dict:
        return {"steps": steps, "train": {"seconds": seconds, "cpu_seconds": seconds, "iterations": 10,
                                          "peak_rss_mib": 100.0},
                "inference": {"median_ms": 0.1}, "stages": {"fold_models": {"seconds": seconds, "cpu_seconds": 1.0}}}

    slopes = growth([size(1000, 4.0), size(100, 1.0), size(10, 0.25)])
    assert slopes["train_seconds"]["overall"] == pytest.approx(0.6020599913)  # log10(16) / log10(100)
    assert [b["steps"] for b in slopes["stage.fold_models"]["between"]] == [[10, 100], [100, 1000]]
    assert slopes["train_iterations"]["overall"] == pytest.approx(0.0)
    assert slopes["stage.fold_models.cpu"]["overall"] == pytest.approx(0.0)
