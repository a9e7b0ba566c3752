"""The aggregate over world seeds on three hand-made worlds that differ, so every mean, spread and minimum has a
known answer (sample sd, n - 1 in the denominator)."""

from __future__ import annotations

import csv
import json
import math
from contextlib import contextmanager
from pathlib import Path

import pytest

from taskseq.cli import main
from taskseq.evaluate.failures import KINDS
from taskseq.methods import method_labels
from taskseq.report.csvs import SEQUENCE_COLUMNS, csv_text
from taskseq.report.seeds import mean_sd
from taskseq.report.summary import build_summary
from taskseq.report.tables import COLUMNS
from taskseq.settings import World
from taskseq.stages import aggregate
from taskseq.stages.options import AggregateOptions

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
    stir = {k: (1 if k == "stopped_late" else 0) for k in KINDS}  # one program, stopped late, in every world
    (d / "crossval.json").write_text(json.dumps({
        "multiclass": {"steps": {"average/prim": 95.0, "average/arg": None}},
        "full": {"steps": {"average/prim": w["prim"], "average/arg": w["arg"] - 10}, "sequence/prim": w["prim"],
                 "sequence/arg": w["arg"], "success": w["success"], "goal_reached": w["success"] + 5,
                 "programs": programs, "per_task": {"pour": {"programs": programs}, "stir": {"programs": stir}}}}))
    (d / "noise.csv").write_text("method,rate,sequence_arg,sequence_prim,success\n"
                                 f"full,0.0,{w['arg']},{w['prim']},{w['success']}\n"
                                 f"full,0.3,{w['noisy']},{w['noisy']},{w['noisy']}\n")
    (d / "feedback.csv").write_text("method,k,n,sequence_arg,sequence_prim,success\n"
                                    f"full,2,0,{w['arg']},{w['prim']},{w['success']}\n"
                                    f"full,2,1,{w['fb'] - 10},{w['fb'] - 10},{w['fb'] - 10}\n"
                                    f"full,2,all,{w['fb']},{w['fb']},{w['fb']}\n")
    (d / "crossval_sequences.csv").write_text(",".join(SEQUENCE_COLUMNS) + "\n")
    (d / "dataset.json").write_text(json.dumps({"environments": 2}))
    none, first = w["recipes"]
    (d / "recipes.json").write_text(json.dumps({"methods": {"full": {"totals": {
        "recipes": 10, "no_feedback": none, "feedback_first_step": first}}}}))


class RecordingTracker:
    """Stands in for a stage's MLflow run: keeps what the stage records."""

    def __init__(self, name: str = "aggregate", params: dict | None = None) -> None:
        self.name, self.params, self.children, self.recorded, self.artifacts = name, params, [], {}, []

    def metrics(self, values: dict) -> None:
        self.recorded.update(values)

    def artifact(self, path) -> None:
        self.artifacts.append(Path(path).name)

    @contextmanager
    def child(self, name: str, params: dict | None = None):
        child = RecordingTracker(name, params)
        self.children.append(child)
        yield child


@pytest.fixture
def tracker() -> RecordingTracker:
    return RecordingTracker()


PLOTS: dict[str, dict] = {}


@pytest.fixture
def aggregated(tmp_path, tracker, monkeypatch) -> Path:
    """The stage run on three different worlds (function-scoped, so every test sees the stage run under it);
    what each figure draws is kept in PLOTS, by file name."""
    draw = aggregate.line_plot_png

    def recording(series, path, title, xlabel, ylabel, **options):
        PLOTS[Path(path).name] = {"series": series, "title": title, "xlabel": xlabel, "ylabel": ylabel, **options}
        draw(series, path, title, xlabel, ylabel, **options)

    monkeypatch.setattr(aggregate, "line_plot_png", recording)
    PLOTS.clear()
    for seed, w in WORLD.items():
        _write_world(tmp_path / "worlds" / str(seed), w)
    out = tmp_path / "out"
    means = aggregate.run(World(seeds=SEEDS, dev_seed=100), AggregateOptions(worlds=tmp_path / "worlds", output=out),
                         tracker)
    assert means == json.loads((out / "crossval_means.json").read_text())
    return out


def test_the_command_line_runs_the_stage_over_the_seeds_it_is_given(tmp_path, capsys):
    for seed, w in WORLD.items():
        _write_world(tmp_path / "worlds" / str(seed), w)
    assert main(["--no-mlflow", "aggregate", "--set", "world.seeds=[0, 7]", "--set", "world.dev_seed=100", "--worlds",
                 str(tmp_path / "worlds"), "--output", str(tmp_path / "out")]) == 0
    means = json.loads((tmp_path / "out" / "crossval_means.json").read_text())
    assert means["full"]["sequence_arg"] == 77.5 and means["full"]["sequence_arg_min"] == 60.0
    assert f"over world seeds 0, 7; failure kinds in {tmp_path / 'out' / 'failures.md'}" in capsys.readouterr().out


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
    assert metrics["feedback"]["full"] == {"top2_n1": 80.0, "top2_nall": 90.0}  # one step and every step
    assert metrics["recipes"] == {"full": {"no_feedback": 3.0, "feedback_first_step": 6.0}}
    assert set(metrics) == {"crossval", "noise", "feedback", "recipes"}
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


def test_every_table_names_its_columns_and_the_world_seeds(aggregated):
    assert (aggregated / "table1_seeds.csv").read_text().splitlines()[1] == "0,ours - full,move_close,95.00,85.00"
    table = (aggregated / "table1.csv").read_text().splitlines()
    assert table[0] == "method,column,prim,prim_sd,arg,arg_sd"
    assert [line for line in table if ",sequence," in line] == ["ours - full,sequence,90.00,10.00,75.00,18.03",
                                                               "multiclass,sequence,95.00,0.00,,"]  # two decimals
    assert "| ours - full |" in (aggregated / "table1.md").read_text()
    tex = (aggregated / "table1.tex").read_text()
    assert "over 3 world seeds (0, 3, 7), each a 6-fold cross-validation: percentage of primitives (prim)" in tex
    assert "(arg) right, teacher-forced, and of closed-loop sequences equal to a demonstration.}" in tex
    head = (aggregated / "crossval_seeds.csv").read_text().splitlines()
    assert head[0] == "world_seed,method,average_prim,average_arg,sequence_prim,sequence_arg,success,goal_reached"
    assert head[1] == "0,multiclass,95,,,,,"
    assert (aggregated / "noise_seeds.csv").read_text().splitlines()[:2] == [
        "world_seed,method,rate,sequence_arg,sequence_prim,success", "0,full,0.0,60.0000,90.0000,80.0000"]
    assert (aggregated / "feedback_seeds.csv").read_text().splitlines()[3] == "0,full,2,all,80.0000,80.0000,80.0000"
    assert (aggregated / "noise.csv").read_text().splitlines() == [
        "method,rate,sequence_arg,sequence_arg_sd,sequence_prim,sequence_prim_sd,success,success_sd",
        "full,0.0,75.0000,18.0278,90.0000,10.0000,80.0000,10.0000",
        "full,0.3,30.0000,10.0000,30.0000,10.0000,30.0000,10.0000"]
    assert (aggregated / "feedback.csv").read_text().splitlines()[1:] == [
        "full,2,0,75.0000,18.0278,90.0000,10.0000,80.0000,10.0000",
        "full,2,1,80.0000,10.0000,80.0000,10.0000,80.0000,10.0000",
        "full,2,all,90.0000,10.0000,90.0000,10.0000,90.0000,10.0000"]
    assert (aggregated / "feedback.csv").read_text().splitlines()[0].startswith("method,k,n,sequence_arg,")
    assert (aggregated / "failures.csv").read_text().splitlines()[1] == "0,full,all,exact,6"
    assert (aggregated / "crossval_sequences.csv").read_text() == "world_seed," + ",".join(SEQUENCE_COLUMNS) + "\n"
    assert json.loads((aggregated / "dataset.json").read_text()) == {s: {"environments": 2} for s in ("0", "3", "7")}
    assert (aggregated / "plots" / "noise.csv").read_text().splitlines() == [
        "rate,ours - full", "0.0,75.00", "0.3,30.00"]
    assert (aggregated / "plots" / "feedback.csv").read_text().splitlines() == [
        "n,ours - full top 2", "0,75.00", "1,80.00", "all,90.00"]
    assert (aggregated / "noise.png").stat().st_size > 0 and (aggregated / "feedback.png").stat().st_size > 0


def test_the_run_records_per_world_children_means_and_artifacts(aggregated, tracker):
    names = [c.name for c in tracker.children]
    assert names == ["multiclass seed=0", "full seed=0", "multiclass seed=3", "full seed=3", "multiclass seed=7",
                     "full seed=7"]
    full7 = tracker.children[-1]
    assert full7.params == {"method": "full", "world_seed": 7}
    assert full7.recorded["sequence_arg"] == 95.0 and not {"method", "world_seed"} & set(full7.recorded)
    assert tracker.recorded["full.sequence_arg"] == 75.0 and tracker.recorded["full.sequence_arg_min"] == 60.0
    assert sorted(tracker.artifacts) == sorted(["table1.md", "table1.tex", "metrics.json", "crossval_means.json",
                                                "failures.md", "noise.png", "feedback.png", "recipes.json"])


def test_the_failure_table_per_task(aggregated):
    text = (aggregated / "failures.md").read_text()
    first = "Programs by kind, % of each method's closed-loop programs, mean ± sd over 3 world seeds."
    assert text.startswith(first + "\n\n")
    lines = text.splitlines()
    header = "| method | " + " | ".join(k.replace("_", " ") for k in KINDS) + " |"
    assert lines[2] == header and lines[3] == "|---|" + "---:|" * len(KINDS)
    assert not any(line.startswith("| multiclass") for line in lines)  # it runs no programs
    start = lines.index("The full model per task:")
    assert lines[start - 1] == "" and lines[start + 1] == "" and lines[start + 2] == header.replace("method", "task")
    stir = next(line for line in lines if line.startswith("| stir |"))
    cells = dict(zip(KINDS, [c.strip() for c in stir.strip("|").split("|")][1:], strict=True))
    assert cells["stopped_late"] == "100.0 ± 0.0" and cells["exact"] == "0.0 ± 0.0"
    assert text.endswith(" |\n") and [line for line in lines if line.startswith("| pour |")]


def test_failure_shares_of_a_world_with_one_program_and_of_an_unknown_method():
    from taskseq.report.seeds import failure_shares

    rows = [{"world_seed": 0, "method": "m", "task": "all", "kind": "exact", "programs": 1},
            {"world_seed": 0, "method": "m", "task": "pour", "kind": "exact", "programs": 0},
            {"world_seed": 1, "method": "other", "task": "all", "kind": "exact", "programs": 0}]
    assert failure_shares(rows, "m")["exact"] == (100.0, 0.0)
    assert failure_shares(rows, "m", "pour")["exact"] == (0.0, 0.0)
    assert failure_shares(rows, "nobody") == dict.fromkeys(KINDS, (0.0, 0.0))


def test_the_figures_draw_the_means_and_spreads_over_worlds(aggregated):
    noise = PLOTS["noise.png"]
    (label, (xs, ys, sds)), = noise["series"].items()
    assert label == "ours - full (mean, sd over 3 world seeds)" and xs == [0.0, 0.3] and ys == [75.0, 30.0]
    assert sds == pytest.approx([SD_ARG, 10.0])
    assert noise["title"] == "Sequence accuracy (arg) with binary attributes flipped"
    assert noise["xlabel"] == "probability of flipping each binary attribute"
    assert noise["ylabel"] == "% sequences correct"
    assert list(noise["reference"]) == ["paper"] and noise["reference"]["paper"][0][0] == 0.0
    fb = PLOTS["feedback.png"]
    assert fb["series"] == {"ours - full, top 2": ([0, 1, 2], [75.0, 80.0, 90.0], pytest.approx([SD_ARG, 10.0, 10.0]))}
    assert fb["title"] == "Sequence accuracy (arg) with an observer's feedback"
    assert (fb["xlabel"], fb["ylabel"]) == ("steps with feedback", "% sequences correct")
    assert fb["xticks"] == [0, 1, 2] and fb["xticklabels"] == ["0", "1", "all"]


def test_bad_or_missing_inputs_are_named(tmp_path):
    from taskseq.report.seeds import crossval_over_seeds, table1_over_seeds

    for seed, w in WORLD.items():
        _write_world(tmp_path / str(seed), w)
    dirs = {s: tmp_path / str(s) for s in SEEDS}
    text = (dirs[3] / "table1.csv").read_text().splitlines()
    text[2] = text[2].rsplit(",", 1)[0] + ",lots"  # record 3 (the header is record 1), field arg
    (dirs[3] / "table1.csv").write_text("\n".join(text) + "\n")
    with pytest.raises(ValueError, match=rf"^{dirs[3] / 'table1.csv'}: record 3, field 'arg': not a number: 'lots'$"):
        table1_over_seeds(dirs)
    text[2] = text[2].replace(",95.00,", ",much,", 1)
    (dirs[3] / "table1.csv").write_text("\n".join(text) + "\n")
    with pytest.raises(ValueError, match=r"record 3, field 'prim': not a number: 'much'$"):
        table1_over_seeds(dirs)
    (dirs[7] / "crossval.json").unlink()
    with pytest.raises(FileNotFoundError, match=rf"^{dirs[7] / 'crossval.json'}: missing; run the stage that writes "
                                                 "it for world seed 7$"):
        crossval_over_seeds(dirs)
    with pytest.raises(ValueError, match="^mean_sd: no values$"):
        mean_sd([])


def test_methods_without_a_label_keep_their_name_and_a_summary_without_tasks_is_read():
    from taskseq.report.seeds import failures_markdown, failures_over_seeds, plot_columns

    programs = dict.fromkeys(KINDS, 0) | {"exact": 2}
    rows = failures_over_seeds({0: {"mine": {"programs": programs}}})  # no per-task figures
    assert {r["task"] for r in rows} == {"all"}
    assert "| mine | 100.0 ± 0.0 |" in failures_markdown(rows, ["mine"], 1)
    columns, wide = plot_columns([{"n": "1", "method": "mine", "k": 2, "v": 5.0}], "n", ["method", "k"], "v", {})
    assert columns == ["n", "method mine k 2"] and wide == [{"n": "1", "method mine k 2": 5.0}]


@pytest.mark.parametrize("missing", ["noise.csv", "feedback.csv", "recipes.json", "dataset.json"])
def test_a_table_only_some_worlds_lack_stops_the_stage_and_one_every_world_lacks_is_left_out(tmp_path, missing):
    """Worlds evaluated with other folds (the scenes stage) have Table I alone: what none of them has is not
    written, and its group is absent from metrics.json; a file one world lacks is an error that names it."""
    for seed, w in WORLD.items():
        _write_world(tmp_path / "worlds" / str(seed), w)
    (tmp_path / "worlds" / "3" / missing).unlink()
    with pytest.raises(FileNotFoundError, match=missing):
        aggregate.run(World(seeds=SEEDS), AggregateOptions(worlds=tmp_path / "worlds", output=tmp_path / "a"))
    for seed in SEEDS:
        (tmp_path / "worlds" / str(seed) / missing).unlink(missing_ok=True)
    out = tmp_path / "b"
    aggregate.run(World(seeds=SEEDS), AggregateOptions(worlds=tmp_path / "worlds", output=out))
    written = {p.relative_to(out).as_posix() for p in out.rglob("*") if p.is_file()}
    left_out = {"noise.csv": {"noise.csv", "noise_seeds.csv", "noise.png", "plots/noise.csv"},
                "feedback.csv": {"feedback.csv", "feedback_seeds.csv", "feedback.png", "plots/feedback.csv"},
                "recipes.json": {"recipes.json"}, "dataset.json": {"dataset.json"}}[missing]
    assert not written & left_out and {"table1.md", "failures.md", "crossval_means.json"} <= written
    kept = {"noise.csv": "feedback", "feedback.csv": "noise"}.get(missing)  # the other curve is still drawn
    assert kept is None or {f"{kept}.csv", f"{kept}.png", f"plots/{kept}.csv"} <= written
    groups = json.loads((out / "metrics.json").read_text())
    group = {"noise.csv": "noise", "feedback.csv": "feedback", "recipes.json": "recipes"}.get(missing)
    assert group is None or groups.get(group, {}) == {}
    assert groups["crossval"]["full"]["sequence_arg"] == 75.0


@pytest.mark.parametrize("family", ["paper", "procedural"])
def test_failures_per_environment_and_task_of_each_world(tmp_path, family):
    """World 0: env01's two programs exact; world 7: one of env01's two, the other a wrong object; world 3 ran none
    (no column). Drawn rooms differ from seed to seed, so a drawn world's report compares tasks only."""
    kinds = {0: ("exact", "exact"), 7: ("exact", "wrong_object")}
    for seed, w in WORLD.items():
        d = tmp_path / "worlds" / str(seed)
        _write_world(d, w)
        rows = [{"method": "full", "fold": 0, "scenario": f"env01/stir(obj3{i})", "task": "stir", "status": "done",
                 "prim_correct": 1, "arg_correct": int(k == "exact"), "goal_reached": 1, "safe": 1,
                 "success": int(k == "exact"), "failure": k, "program": ""} for i, k in enumerate(kinds.get(seed, ()))]
        (d / "crossval_sequences.csv").write_text(csv_text(SEQUENCE_COLUMNS, rows))
    aggregate.run(World(seeds=SEEDS, dev_seed=100, family=family),
                  AggregateOptions(worlds=tmp_path / "worlds", output=tmp_path / "out"))
    text = (tmp_path / "out" / "failures.md").read_text()
    assert ("| env01 | 100.0 (2/2) | 50.0 (1/2), wrong object 1 |" in text) == (family == "paper")
    assert "| stir | 100.0 (2/2) | 50.0 (1/2), wrong object 1 |" in text
    assert "The full model per task and world seed: sequence arg, % (exact programs / programs)" in text


def test_the_results_page_rounds_the_curves_once(tmp_path, tracker):
    """Three worlds whose noise and feedback means are 79.7467 (sd 2.6871): the page must say 79.7 ± 2.7.

    Curves kept at two decimals said 79.8, because 79.75 was rounded again (and an sd of 6.6453, kept as 6.65,
    became 6.7); the per-world files are written at four decimals as the noise and feedback stages write them.
    """
    for seed, (arg, w) in zip(SEEDS, ((77.0, WORLD[0]), (79.87, WORLD[3]), (82.37, WORLD[7])), strict=True):
        d = tmp_path / "worlds" / str(seed)
        _write_world(d, w)
        (d / "noise.csv").write_text(f"method,rate,sequence_arg,sequence_prim,success\nfull,0.1,{arg:.4f},90,90\n")
        (d / "feedback.csv").write_text(f"method,k,n,sequence_arg,sequence_prim,success\nfull,2,1,{arg:.4f},90,90\n")
    out = tmp_path / "out"
    aggregate.run(World(seeds=SEEDS, dev_seed=100), AggregateOptions(worlds=tmp_path / "worlds", output=out), tracker)
    mean, sd = mean_sd([77.0, 79.87, 82.37])
    assert (f"{mean:.2f}", f"{mean:.1f}", f"{sd:.1f}") == ("79.75", "79.7", "2.7")  # where the two roundings part
    assert (out / "noise.csv").read_text().splitlines()[1] == "full,0.1,79.7467,2.6871,90.0000,0.0000,90.0000,0.0000"
    text = build_summary(out, method_labels())
    assert "| ours - full | 0.1 | 79.7 ± 2.7 |" in text
    assert "| ours - full | 2 | 1 | 79.7 ± 2.7 |" in text
