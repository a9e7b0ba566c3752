"""The aggregate over world seeds on three hand-made worlds that differ, so every mean, spread and minimum has a
known answer (sample sd, n - 1 in the denominator)."""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import pytest

from pipeline.cli import main
from pipeline.evaluate.failures import KINDS
from pipeline.report.csvs import SEQUENCE_COLUMNS
from pipeline.report.seeds import mean_sd
from pipeline.report.tables import COLUMNS

SEEDS = (0, 3, 7)
# per seed: full model's sequence arg and success, Table I prim, noise at 0.3, feedback top-2 all, recipes
WORLD = {
    0: {"arg": 60.0, "success": 80.0, "prim": 90.0, "noisy": 30.0, "fb": 80.0, "recipes": (3, 4),
        "programs": {"exact": 6, "wrong_object": 2, "step_cap": 2}},
    3: {"arg": 70.0, "success": 90.0, "prim": 80.0, "noisy": 40.0, "fb": 90.0, "recipes": (5, 6),
        "programs": {"exact": 7, "wrong_object": 3}},
    7: {"arg": 95.0, "success": 70.0, "prim": 100.0, "noisy": 20.0, "fb": 100.0, "recipes": (1, 8),
        "programs": {"exact": 19, "wrong_object": 1}},
}
SD_ARG = math.sqrt(((60 - 75) ** 2 + (70 - 75) ** 2 + (95 - 75) ** 2) / 2)  # 18.03; the population sd is 14.72


def _write_world(d: Path, w: dict) -> None:
    d.mkdir(parents=True)
    lines = ["method,column,prim,arg"]
    for m in ("ours - full", "multiclass"):
        for c in COLUMNS:
            prim = w["prim"] if (m, c) == ("ours - full", "sequence") else 95.0
            arg = "" if m == "multiclass" else f"{w['arg'] if c == 'sequence' else 85.0:.2f}"
            lines.append(f"{m},{c},{prim:.2f},{arg}")
    (d / "table1.csv").write_text("\n".join(lines) + "\n")
    programs = {k: w["programs"].get(k, 0) for k in KINDS}
    (d / "crossval.json").write_text(json.dumps({
        "full": {"steps": {"average/prim": w["prim"], "average/arg": w["arg"] - 10}, "sequence/prim": w["prim"],
                 "sequence/arg": w["arg"], "success": w["success"], "goal_reached": w["success"] + 5,
                 "programs": programs, "per_task": {"pour": {"programs": programs}}},
        "multiclass": {"steps": {"average/prim": 95.0, "average/arg": None}}}))
    (d / "noise.csv").write_text("method,rate,sequence_arg,sequence_prim,success\n"
                                 f"full,0.0,{w['arg']},{w['prim']},{w['success']}\n"
                                 f"full,0.3,{w['noisy']},{w['noisy']},{w['noisy']}\n")
    (d / "feedback.csv").write_text("method,k,n,sequence_arg,sequence_prim,success\n"
                                    f"full,2,0,{w['arg']},{w['prim']},{w['success']}\n"
                                    f"full,2,all,{w['fb']},{w['fb']},{w['fb']}\n")
    (d / "crossval_sequences.csv").write_text(",".join(SEQUENCE_COLUMNS) + "\n")
    (d / "dataset.json").write_text(json.dumps({"environments": 2}))
    none, first = w["recipes"]
    (d / "recipes.json").write_text(json.dumps({"methods": {"full": {"totals": {
        "recipes": 10, "no_feedback": none, "feedback_first_step": first}}}}))


@pytest.fixture(scope="module")
def aggregated(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("worlds")
    for seed, w in WORLD.items():
        _write_world(root / "worlds" / str(seed), w)
    out = root / "out"
    assert main(["--no-mlflow", "aggregate", "--seeds", *map(str, SEEDS), "--dev_seed", "100",
                 "--worlds", str(root / "worlds"), "--output", str(out)]) == 0
    return out


def test_mean_sd_on_known_answers():
    assert mean_sd([60.0, 70.0, 95.0]) == pytest.approx((75.0, SD_ARG))
    assert mean_sd([1.0, 2.0, 3.0, 4.0]) == pytest.approx((2.5, math.sqrt(5 / 3)))
    assert mean_sd([5.0, 5.0]) == (5.0, 0.0)


def test_headline_mean_sd_and_worst_world(aggregated):
    full = json.loads((aggregated / "crossval_means.json").read_text())["full"]
    assert full["sequence_arg"] == pytest.approx(75.0) and full["sequence_arg_sd"] == pytest.approx(SD_ARG)
    assert full["sequence_arg_min"] == 60.0
    assert (full["success"], full["success_sd"], full["success_min"]) == pytest.approx((80.0, 10.0, 70.0))
    assert (full["goal_reached"], full["goal_reached_min"]) == pytest.approx((85.0, 75.0))
    rows = list(csv.DictReader((aggregated / "crossval_seeds.csv").open()))
    worst = min((r for r in rows if r["method"] == "full"), key=lambda r: float(r["sequence_arg"]))
    assert worst["world_seed"] == "0"  # the per-seed rows name the worst world


def test_table1_over_worlds(aggregated):
    rows = {(r["method"], r["column"]): r for r in csv.DictReader((aggregated / "table1.csv").open())}
    full = rows[("ours - full", "sequence")]
    assert (float(full["arg"]), float(full["arg_sd"])) == pytest.approx((75.0, SD_ARG), abs=0.005)
    assert (float(full["prim"]), float(full["prim_sd"])) == (90.0, 10.0)
    assert rows[("multiclass", "average")]["arg"] == "" and float(rows[("multiclass", "average")]["prim_sd"]) == 0
    per_seed = list(csv.DictReader((aggregated / "table1_seeds.csv").open()))
    full_rows = [r for r in per_seed if (r["method"], r["column"]) == ("ours - full", "sequence")]
    assert [(r["world_seed"], r["arg"]) for r in full_rows] == [("0", "60.00"), ("3", "70.00"), ("7", "95.00")]


def test_noise_and_feedback_curves_over_worlds(aggregated):
    noise = {r["rate"]: r for r in csv.DictReader((aggregated / "noise.csv").open())}
    assert (float(noise["0.3"]["sequence_arg"]), float(noise["0.3"]["sequence_arg_sd"])) == (30.0, 10.0)
    assert float(noise["0.0"]["sequence_arg_sd"]) == pytest.approx(SD_ARG, abs=0.005)
    fb = {r["n"]: r for r in csv.DictReader((aggregated / "feedback.csv").open())}
    assert (float(fb["all"]["success"]), float(fb["all"]["success_sd"])) == (90.0, 10.0)
    metrics = json.loads((aggregated / "metrics.json").read_text())
    assert metrics["noise"]["full"] == {"rate_0": 75.0, "rate_0.3": 30.0}
    assert metrics["feedback"]["full"] == {"top2_nall": 90.0}
    assert metrics["crossval"]["full"] == pytest.approx({"sequence_arg": 75.0, "sequence_arg_sd": SD_ARG,
                                                         "success": 80.0})


def test_recipes_over_worlds(aggregated):
    full = json.loads((aggregated / "recipes.json").read_text())["methods"]["full"]
    assert full["mean"] == {"no_feedback": 3.0, "feedback_first_step": 6.0}
    assert full["sd"] == {"no_feedback": 2.0, "feedback_first_step": 2.0}
    assert full["min"] == {"no_feedback": 1, "feedback_first_step": 4}
    assert full["per_seed"]["7"]["no_feedback"] == 1 and full["recipes"] == 10


def test_failure_shares_over_worlds(aggregated):
    text = (aggregated / "failures.md").read_text()
    line = next(x for x in text.splitlines() if x.startswith("| ours - full |"))
    cells = [c.strip() for c in line.strip("|").split("|")][1:]
    shares = dict(zip(KINDS, cells, strict=True))
    # exact: 60, 70 and 95 % of each world's programs; wrong object 20, 30, 5; step cap 20, 0, 0
    assert shares["exact"] == f"75.0 ± {SD_ARG:.1f}"
    assert shares["wrong_object"] == "18.3 ± 12.6" and shares["step_cap"] == "6.7 ± 11.5"
    assert shares["stopped_late"] == "0.0 ± 0.0"
    rows = list(csv.DictReader((aggregated / "failures.csv").open()))
    assert sum(int(r["programs"]) for r in rows if r["task"] == "all" and r["world_seed"] == "7") == 20
