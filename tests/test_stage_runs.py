"""Every stage, run end to end through the command line on a tiny world (two environments, 2 folds)."""

from __future__ import annotations

import csv
import importlib.util
import json
import os
import shutil
from pathlib import Path

import pytest
from params_files import params_with, selection_at

from taskseq.cli import main
from taskseq.demonstrations.benchmark import load_benchmark
from taskseq.demonstrations.records import spec_from_dict, state_from_dict
from taskseq.experiments import selection
from taskseq.experiments.selection import best_candidate
from taskseq.learn.estimator import StepScorer
from taskseq.methods.spec import added_modules
from taskseq.plan.planner import feasible, run_loop
from taskseq.settings import Params
from taskseq.sim.procedural import DrawReport
from taskseq.sim.tasks import Task
from taskseq.stages import generate as generate_stage

FOLDS = ["--set", "crossval.folds=2", "--set", "crossval.group_by=scenario", "--set", "crossval.seed=0"]
LEARN = ["--set", "train.tol=0.01", "--set", "train.max_iter=300", "--set", "train.n_slacks=0"]
_spec = importlib.util.spec_from_file_location("stage_deps", Path(__file__).resolve().parents[1] / "scripts" /
                                               "stage_deps.py")
stage_deps = importlib.util.module_from_spec(_spec)  # one module, so one import server, for the file's tests
_spec.loader.exec_module(stage_deps)



@pytest.fixture(scope="module")
def tiny(benchmark_logs, tmp_path_factory) -> Path:
    """A tiny world: the logs of two environments, ingested, featurised and with its fold models."""
    root = tmp_path_factory.mktemp("tiny")
    (root / "raw").mkdir()
    for env in ("env01", "env04"):
        shutil.copy(benchmark_logs / f"{env}.jsonl", root / "raw")
    w = root / "worlds" / "0"
    assert main(["ingest", "--input", str(root / "raw"), "--output", str(root / "processed"),
                 "--metrics", str(w / "dataset.json")]) == 0
    assert main(["features", "--input", str(root / "processed"), "--output", str(root / "features")]) == 0
    selection_at(root / "selection.json", 2.0)
    assert main(["fold_models", "--features", str(root / "features"), "--processed", str(root / "processed"), *FOLDS,
                 *LEARN, "--selection", str(root / "selection.json"), "--output", str(root / "store"),
                 "--metrics", str(root / "folds.json"), "--n-jobs", "1"]) == 0
    return root


def data(root: Path) -> list[str]:
    return ["--features", str(root / "features"), "--processed", str(root / "processed")]


def test_ingest_and_features_write_their_outputs(tiny):
    assert json.loads((tiny / "worlds" / "0" / "dataset.json").read_text())["environments"] == 2
    assert {p.name for p in (tiny / "processed").iterdir()} >= {"steps.parquet", "scenarios.parquet"}
    index = json.loads((tiny / "store" / "index.json").read_text())
    assert all(m["C"] == 2.0 for m in index["models"])  # C comes from the selection file


def test_train_and_pddl(tiny):
    out = tiny / "train"
    assert main(["train", "--features", str(tiny / "features"), *LEARN, "--set", "train.method=full", "--model",
                 str(out / "mrf.npz"), "--metrics", str(out / "train.json"), "--curve", str(out / "curve.csv")]) == 0
    metrics = json.loads((out / "train.json").read_text())
    assert metrics["train_average_arg"] > 50 and (out / "mrf.npz").exists()
    assert (out / "curve.csv").read_text().startswith("iteration,primal,best_primal,dual,gap,n_constraints\n")
    assert main(["pddl", "--processed", str(tiny / "processed"), "--output", str(tiny / "pddl")]) == 0
    n_problems = len(list((tiny / "pddl" / "problems").glob("*.pddl")))
    assert n_problems == len(list((tiny / "pddl" / "plans").glob("*.plan"))) > 0


def test_train_ships_the_method_the_development_world_ranked_first(tiny, tmp_path, capsys):
    tuned = {"settings": {name: {"C": 2.0} for name in ("full", "relations", "dagger")}}
    ranked = {"C": 2.0, "method": "relations", "methods": [{"method": "relations", "sequence_arg": 70.0},
                                                           {"method": "full", "sequence_arg": 60.0}], **tuned}
    (tmp_path / "selection.json").write_text(json.dumps(ranked))
    train = ["train", "--features", str(tiny / "features"), *LEARN, "--selection", str(tmp_path / "selection.json")]
    assert main([*train, "--model", str(tmp_path / "best.npz"), "--metrics", str(tmp_path / "train.json")]) == 0
    meta = StepScorer.load(tmp_path / "best.npz").meta_
    assert (meta["method"], meta["features"], meta["C"], meta["dagger_rounds"]) == ("relations", "relations", 2.0, 0)
    assert "development world" in meta["chosen_by"] and json.loads((tmp_path / "train.json").read_text())[
        "method"] == "relations"
    # the paper's model stays available by name
    assert main([*train, "--set", "train.method=full", "--model", str(tmp_path / "full.npz")]) == 0
    assert StepScorer.load(tmp_path / "full.npz").meta_["method"] == "full"
    # DAgger rolls out on the training scenarios: without them it says so, with them it trains
    capsys.readouterr()
    assert main([*train, "--set", "train.method=dagger", "--model", str(tmp_path / "d.npz")]) == 2
    assert "needs the training scenarios" in capsys.readouterr().err and not (tmp_path / "d.npz").exists()
    assert main([*train, "--set", "train.method=dagger", "--processed", str(tiny / "processed"),
                 "--model", str(tmp_path / "d.npz")]) == 0
    assert StepScorer.load(tmp_path / "d.npz").meta_["dagger_rounds"] == 1
    # a selection file from before methods were ranked, or an unknown method, is named
    (tmp_path / "old.json").write_text(json.dumps({"C": 2.0, **tuned}))
    assert main([*train[:-1], str(tmp_path / "old.json"), "--model", str(tmp_path / "o.npz")]) == 2
    assert f"{tmp_path / 'old.json'}: no field 'method'" in capsys.readouterr().err
    assert main([*train, "--set", "train.method=fancy", "--model", str(tmp_path / "o.npz")]) == 2
    assert "unknown methods ['fancy']" in capsys.readouterr().err


def test_the_shipped_model_records_its_own_c_and_policy_and_plan_uses_them(tiny, benchmark_logs, tmp_path, capsys):
    """The precondition-aware policy ranked first at its own C: the model file records method, C, rounds and
    policy, and `taskseq plan` prints them and plans with that policy."""
    ranked = {"C": 2.0, "settings": {"full": {"C": 2.0}, "feasible": {"C": 0.5}}, "method": "feasible",
              "methods": [{"method": "feasible", "C": 0.5}, {"method": "full", "C": 2.0}]}
    (tmp_path / "selection.json").write_text(json.dumps(ranked))
    assert main(["--no-mlflow", "train", "--features", str(tiny / "features"), "--processed", str(tiny / "processed"),
                 *LEARN, "--selection", str(tmp_path / "selection.json"), "--model", str(tmp_path / "f.npz")]) == 0
    planner = StepScorer.load(tmp_path / "f.npz")
    meta = planner.meta_
    assert (meta["method"], meta["C"], meta["dagger_rounds"], meta["policy"]) == ("feasible", 0.5, 1, "feasible")
    capsys.readouterr()
    record = json.loads((benchmark_logs / "env01.jsonl").read_text().splitlines()[0])
    task = f"{record['task']['name']}({','.join(record['task']['args'])})"
    main(["plan", "--model", str(tmp_path / "f.npz"), "--env", str(benchmark_logs / "env01.jsonl"), "--task", task,
          "--json"])
    captured = capsys.readouterr()
    assert "(method feasible: relations feature set, C 0.5" in captured.err and "DAgger rounds 1" in captured.err
    assert "policy feasible" in captured.err
    specs = {o["id"]: spec_from_dict(o) for o in record["objects"]}
    state = state_from_dict(specs, record["steps"][0]["state"])
    expected = run_loop(feasible(planner, 3), state, Task.parse(task), 20)
    assert [s["action"] for s in json.loads(captured.out)["steps"]] == [str(a) for a in expected.actions]


@pytest.fixture(scope="module")
def evaluated(tiny) -> Path:
    w = tiny / "worlds" / "0"
    sel = ["--selection", str(tiny / "selection.json"), "--model-store", str(tiny / "store")]
    assert main(["crossval", *data(tiny), *FOLDS, *LEARN, *sel, "--output", str(w), "--n-jobs", "1",
                 "--recordings", "1", "--recordings-dir", str(tiny / "recordings")]) == 0
    assert main(["noise", *data(tiny), *FOLDS, *LEARN, *sel, "--set", "noise.rates=0.0 0.3", "--set", "noise.draws=2",
                 "--output", str(w), "--n-jobs", "1"]) == 0
    assert main(["feedback", *data(tiny), *FOLDS, *LEARN, *sel, "--set", "feedback.k=2", "--set", "feedback.n=0 all",
                 "--output", str(w), "--n-jobs", "1"]) == 0
    assert main(["recipes", *data(tiny), *LEARN, *sel, "--output", str(w)]) == 0
    return w


def test_crossval_writes_table1_with_every_method_and_classified_programs(evaluated, tiny):
    summary = json.loads((evaluated / "crossval.json").read_text())
    assert set(summary) == {"chance", "multiclass", "symb_plan_svm", "symb_plan_manual", "only_edge",
                            "only_clique", "full", "relations", "chained", "dagger", "choice", "feasible",
                            "choice_feasible", "choice_lookahead", "choice_chained_lookahead", "noise_trained",
                            "drawn_rooms"}
    rows = list(csv.DictReader((evaluated / "crossval_sequences.csv").open()))
    full = [r for r in rows if r["method"] == "full"]
    assert len(full) == summary["full"]["n_scenarios"]
    assert all((r["failure"] == "exact") == (r["arg_correct"] == "1") for r in full)
    assert sum(summary["full"]["programs"].values()) == len(full)
    assert len(list((tiny / "recordings").glob("*.rrd"))) == 1
    assert (evaluated / "confusion.png").stat().st_size > 0


def test_noise_at_rate_zero_equals_the_clean_cross_validation(evaluated):
    summary = json.loads((evaluated / "crossval.json").read_text())
    curve = list(csv.DictReader((evaluated / "noise.csv").open()))
    methods = ("full", "relations", "choice", "noise_trained")
    assert [(r["method"], r["rate"]) for r in curve] == [(m, rate) for m in methods for rate in ("0.0", "0.3")]
    for r in curve[::2]:
        assert float(r["sequence_arg"]) == pytest.approx(summary[r["method"]]["sequence/arg"], abs=0.01)
    assert len(list(csv.DictReader((evaluated / "noise_runs.csv").open()))) == 16


def test_feedback_at_every_step_is_never_worse_than_none(evaluated):
    rows = {(r["method"], r["n"]): float(r["sequence_arg"])
            for r in csv.DictReader((evaluated / "feedback.csv").open())}
    assert set(rows) == {(m, n) for m in ("full", "relations") for n in ("0", "all")}  # "all" stays "all"
    assert all(rows[(m, "all")] >= rows[(m, "0")] for m in ("full", "relations"))


def test_every_evaluation_stage_keeps_each_program_it_ran(evaluated):
    """The per-program tables (DVC-cached) hold one row per scenario and condition, and agree with the rates."""
    summary = json.loads((evaluated / "crossval.json").read_text())
    n = summary["full"]["n_scenarios"]
    noise = list(csv.DictReader((evaluated / "noise_sequences.csv").open()))
    assert len(noise) == 4 * 2 * 2 * n  # methods x rates x draws x scenarios
    clean = [r for r in noise if r["method"] == "full" and r["rate"] == "0.0" and r["draw"] == "0"]
    assert 100 * sum(r["arg_correct"] == "1" for r in clean) / n == pytest.approx(summary["full"]["sequence/arg"])
    feedback = list(csv.DictReader((evaluated / "feedback_sequences.csv").open()))
    assert {(r["k"], r["n"]) for r in feedback} == {("2", "0"), ("2", "all")} and len(feedback) == 2 * 2 * n
    programs = list(csv.DictReader((evaluated / "recipes_programs.csv").open()))
    report = json.loads((evaluated / "recipes.json").read_text())["methods"]
    for method, r in report.items():
        firsts = [p for p in programs if p["method"] == method and p["position"] == "0"]
        assert len(firsts) == len(r["runs"])  # every recipe run starts with a program
        assert sum(p["recipe_success"] == "1" for p in firsts) == sum(x["success"] for x in r["runs"])


def test_aggregate_and_report_over_worlds(evaluated, tiny):
    second = tiny / "worlds" / "5"
    shutil.copytree(evaluated, second, dirs_exist_ok=True)  # a second world with the same results: sd 0
    out = tiny / "reports"
    assert main(["aggregate", "--set", "world.seeds=[0, 5]", "--set", "world.dev_seed=100",
                 "--worlds", str(tiny / "worlds"), "--output", str(out)]) == 0
    means = json.loads((out / "crossval_means.json").read_text())
    single = json.loads((evaluated / "crossval.json").read_text())["full"]
    assert means["full"]["sequence_arg"] == pytest.approx(single["sequence/arg"])
    assert means["full"]["sequence_arg_sd"] == 0.0
    metrics = json.loads((out / "metrics.json").read_text())  # the headline figures, grouped by experiment
    assert set(metrics) == {"crossval", "noise", "feedback", "recipes"}
    assert metrics["crossval"]["full"]["sequence_arg"] == pytest.approx(single["sequence/arg"])
    assert "multiclass" not in metrics["crossval"]  # it runs no programs
    assert set(metrics["feedback"]["full"]) == {"top2_nall"}  # n = 0 and all were run: only "all" is a headline
    assert set(metrics["noise"]["relations"]) == {"rate_0", "rate_0.3"}
    header = (out / "plots" / "feedback.csv").read_text().splitlines()
    assert header[0] == "n,ours - full top 2,ours + relations top 2" and [h.split(",")[0] for h in header[1:]] == [
        "0", "all"]
    assert (out / "plots" / "noise.csv").read_text().startswith(
        "rate,ours - full,ours + relations,ours + relations + choice cues,ours + relations + noisy training\n")
    every = list(csv.DictReader((out / "crossval_sequences.csv").open()))
    assert {r["world_seed"] for r in every} == {"0", "5"} and len(every) == 2 * len(
        list(csv.DictReader((evaluated / "crossval_sequences.csv").open())))
    assert "± 0.0" in (out / "table1.md").read_text() and "$\\pm$" in (out / "table1.tex").read_text()
    seeds = {r["world_seed"] for r in csv.DictReader((out / "table1_seeds.csv").open())}
    assert seeds == {"0", "5"}
    failures = (out / "failures.md").read_text()
    assert "The full model per task" in failures and "| environment | world 0 | world 5 |" in failures
    recipes = json.loads((out / "recipes.json").read_text())["methods"]
    assert recipes.keys() == {"full", "chained", "choice_chained_lookahead"}
    assert recipes["full"]["per_seed"].keys() == {"0", "5"}
    (out / "selection.json").write_text(json.dumps({"dev_seed": 100, "criterion": "sequence_arg", "settings": {
        "full": {"C": 2.0, "candidates": [{"C": 2.0, "sequence_arg": 50.0}]}}}))
    assert main(["stats", "--set", "world.seeds=[0, 5]", "--set", "stats.resamples=200",
                 "--worlds", str(tiny / "worlds"), "--output", str(out)]) == 0
    intervals = list(csv.DictReader((out / "table1_ci.csv").open()))
    seq = next(r for r in intervals if (r["method"], r["figure"]) == ("full", "sequence_arg"))
    assert float(seq["value"]) == pytest.approx(single["sequence/arg"], abs=0.01)
    avg = next(r for r in intervals if (r["method"], r["figure"]) == ("full", "average_arg"))
    assert float(avg["value"]) == pytest.approx(single["steps"]["average/arg"], abs=0.01)  # as Table I pools steps
    assert float(seq["low"]) <= float(seq["value"]) <= float(seq["high"])
    assert {r["method"] for r in csv.DictReader((out / "comparisons.csv").open())} == {
        "relations", "chained", "dagger", "feasible", "choice", "choice_feasible", "choice_lookahead",
        "choice_chained_lookahead", "noise_trained", "drawn_rooms"}
    assert main(["report", "--reports", str(out), "--output", str(out / "summary.md"),
                 "--plots-template", str(out / "page.html")]) == 0
    page = (out / "page.html").read_text()
    assert "{plot_divs}" in page and "window.vegaEmbed" in page and "cdn.jsdelivr" not in page  # works offline
    text = (out / "summary.md").read_text()
    for heading in ("## Dataset", "## Settings", "## Table I", "## Why programs fail", "## Attribute noise",
                    "## Human feedback", "## Recipes", "## Confidence intervals and paired comparisons",
                    "### Paired comparisons"):
        assert heading in text


def test_select_sees_only_the_development_world(tiny, monkeypatch, tmp_path, capsys):
    """Through the command line: `dev_world` draws the world from dev_seed alone, of its own size, into one folder
    with its manifest; `select` reads that folder and no reported world reaches the fits or the runs; the file
    holds per method every C tried and the one the documented rule prefers, and `train` then ships the method
    ranked first at its own C, with its policy."""
    drawn = []

    def spy_generate(world, output):
        drawn.append((world.seed, world.family, world.procedural.environments))
        shutil.copytree(tiny / "raw", output)
        return {"env01.jsonl": 1}, DrawReport(environments=2)

    seen = []  # the scenarios every fit and every cross-validation of the stage is given

    def spy(function, scenarios_of):
        def call(*args, **kwargs):
            seen.append(frozenset(scenarios_of(args)))
            return function(*args, **kwargs)

        return call

    monkeypatch.setattr(generate_stage, "generate", spy_generate)
    monkeypatch.setattr(selection, "train_fold_models", spy(selection.train_fold_models, lambda a: a[3]))
    monkeypatch.setattr(selection, "cross_validate", spy(selection.cross_validate, lambda a: a[3].scenarios))
    out, dev = tmp_path / "selection.json", tmp_path / "dev"
    worlds = ["--set", "world.seeds=[0, 3]", "--set", "world.dev_seed=100", "--set", "procedural.environments=130",
              "--set", "select.environments=2"]
    assert main(["--no-mlflow", "dev_world", *worlds, "--set", "world.family=procedural", "--output", str(dev)]) == 0
    # the dev world only, of its own size (a large benchmark tunes on a small world)
    assert drawn == [(100, "procedural", 2)]
    assert {p.name for p in dev.iterdir()} == {"raw", "processed", "features", "world.json", "dataset.json"}
    assert json.loads((dev / "world.json").read_text())["seed"] == 100
    choices, grid = tmp_path / "choices", ["--set", "select.C=0.5 2", "--set", "select.max_extensions=1"]
    lineup = params_with(tmp_path / "p.yaml", full="select", relations="select")
    for name in ("full", "relations"):
        assert main(["--no-mlflow", "choose_C", *worlds, *grid, *lineup, *FOLDS[:2], *LEARN, "--n-jobs", "1",
                     "--method", name, "--world", str(dev), "--output", str(choices / f"{name}.json")]) == 0
    dev_scenarios = frozenset(load_benchmark(dev / "processed").scenarios)
    assert len(seen) >= 4 and set(seen) == {dev_scenarios}
    assert main(["--no-mlflow", "select", *grid, *lineup, "--choices", str(choices), "--output", str(out)]) == 0
    result = json.loads(out.read_text())
    assert result["dev_seed"] == 100 and result["grid"] == [0.5, 2.0] and result["max_extensions"] == 1
    for name in ("full", "relations"):
        choice = result["settings"][name]
        tried = [c["C"] for c in choice["candidates"]]
        assert tried[:2] in ([0.5, 2.0], [0.125, 0.5]) and len(tried) == 2 + choice["extensions"]
        assert choice["extensions"] == 1 and set(tried) - {0.5, 2.0} <= {0.125, 8.0}  # both edges end where they are
        assert choice["C"] == best_candidate(choice["candidates"])["C"]
        assert choice["capped"] == (choice["C"] in (min(tried), max(tried)))
    assert "C" not in result  # each method's C is in `settings`, and nowhere else
    assert [r["method"] for r in result["methods"]] in (["full", "relations"], ["relations", "full"])
    first = result["methods"][0]
    assert result["method"] == first["method"] and first["C"] == result["settings"][first["method"]]["C"]
    assert f"ranked first: {result['method']} at C={first['C']:g}; written to {out}" in capsys.readouterr().out
    model = tmp_path / "shipped.npz"
    assert main(["--no-mlflow", "train", "--features", str(tiny / "features"), *LEARN, "--selection", str(out),
                 "--model", str(model)]) == 0
    meta = StepScorer.load(model).meta_
    assert (meta["method"], meta["C"], meta["policy"]) == (first["method"], first["C"], "greedy")
    code = main(["--no-mlflow", "choose_C", "--method", "chance", "--world", str(dev), "--output",
                 str(tmp_path / "s.json")])
    assert code == 2 and "chance: not MRF methods" in capsys.readouterr().err
    code = main(["--no-mlflow", "select", *params_with(tmp_path / "p.yaml", relations="select", dagger="select"),
                 "--choices", str(choices), "--output", str(tmp_path / "s.json")])
    assert code == 2 and "methods.full.experiments must include select" in capsys.readouterr().err
    # a method without its choice, or with one made on another grid, is named with the command that makes it
    code = main(["--no-mlflow", "select", *params_with(tmp_path / "p.yaml", full="select", dagger="select"),
                 *grid, "--choices", str(choices), "--output", str(tmp_path / "s.json")])
    assert code == 1 and f"{choices / 'dagger.json'}: no choice of C for method dagger; run `taskseq choose_C " \
                         "--method dagger" in capsys.readouterr().err
    code = main(["--no-mlflow", "select", *lineup, "--set", "select.C=0.5 3", "--choices", str(choices),
                 "--output", str(tmp_path / "s.json")])
    assert code == 2 and "chosen on the grid [0.5, 2.0] with 1 extensions, but params.yaml's select has " \
                         "[0.5, 3.0]" in capsys.readouterr().err
    # a development world that is also reported: refused when it would be drawn, and when it is read
    code = main(["--no-mlflow", "dev_world", "--set", "world.seeds=[0, 100]", "--set", "world.dev_seed=100",
                 "--output", str(tmp_path / "d")])
    assert code == 2 and "also a reported seed" in capsys.readouterr().err
    code = main(["--no-mlflow", "choose_C", "--method", "full", "--set", "world.seeds=[0, 100]", "--world", str(dev),
                 "--output", str(tmp_path / "s.json")])
    assert code == 2 and "the development world's seed 100 is also a reported seed" in capsys.readouterr().err
    code = main(["--no-mlflow", "choose_C", "--method", "full", "--world", str(tmp_path / "nowhere"), "--output",
                 str(tmp_path / "s.json")])
    assert code == 1 and "world.json: no such file" in capsys.readouterr().err
    assert not (tmp_path / "d").exists() and not (tmp_path / "s.json").exists()


def test_a_bad_selection_file_is_named(tiny, tmp_path, capsys):
    bad = tmp_path / "selection.json"
    bad.write_text(json.dumps({"C": 1, "settings": {"full": {"C": "big"}}}))
    code = main(["--no-mlflow", "recipes", "--features", str(tiny / "features"), "--selection", str(bad),
                 "--output", str(tmp_path)])
    assert code == 2 and f"{bad}: field 'settings.full.C' must be a positive number" in capsys.readouterr().err
    assert not (tmp_path / "recipes.json").exists()


def test_fold_models_read_back_from_the_cache_write_the_same_store(tiny, tmp_path, capsys, monkeypatch):
    monkeypatch.delenv("TASKSEQ_CACHE", raising=False)
    run = ["fold_models", *data(tiny), *FOLDS, *LEARN, "--selection", str(tiny / "selection.json"), "--n-jobs", "1",
           "--cache", str(tmp_path / "cache")]
    assert main([*run, "--output", str(tmp_path / "first"), "--metrics", str(tmp_path / "first.json")]) == 0
    assert "read from the fit cache" not in capsys.readouterr().out
    assert main([*run, "--output", str(tmp_path / "again"), "--metrics", str(tmp_path / "again.json")]) == 0
    said = capsys.readouterr().out
    first, again = sorted((tmp_path / "first").iterdir()), sorted((tmp_path / "again").iterdir())
    assert [p.name for p in first] == [p.name for p in again] and len(first) > 2
    assert all(a.read_bytes() == b.read_bytes() for a, b in zip(first, again, strict=True))
    # every fit read back, and the stores equal those of the fixture's run without the cache
    assert f"{len(first) - 1} of them read from the fit cache" in said
    assert all(a.read_bytes() == (tiny / "store" / a.name).read_bytes() for a in first)
    assert (tmp_path / "first.json").read_bytes() == (tmp_path / "again.json").read_bytes()
    assert "TASKSEQ_CACHE" not in os.environ  # the option held for the run only


def test_a_cache_that_is_a_file_is_named_and_nothing_is_written(tiny, tmp_path, capsys):
    not_a_folder = tmp_path / "cache.txt"
    not_a_folder.write_text("a file a person made\n")
    code = main(["fold_models", *data(tiny), *FOLDS, *LEARN, "--selection", str(tiny / "selection.json"),
                 "--n-jobs", "1", "--cache", str(not_a_folder), "--output", str(tmp_path / "store")])
    assert code == 2
    assert f"--cache {not_a_folder}: not a folder" in capsys.readouterr().err
    assert not (tmp_path / "store").exists() and not_a_folder.read_text() == "a file a person made\n"


LOADED_AT_EXIT = """
import atexit, json, sys
from taskseq.cli import main
atexit.register(lambda: print(json.dumps(sorted(m.__file__ for n, m in sys.modules.items()
                                                if n.startswith("taskseq.methods") and getattr(m, "__file__", None)))))
sys.exit(main(sys.argv[1:]))
"""


@pytest.mark.parametrize(("stage", "options"), [
    ("noise", ["--set", "noise.rates=0.0 0.3", "--set", "noise.draws=1"]),
    ("feedback", ["--set", "feedback.k=2", "--set", "feedback.n=0 all"]),
    ("recipes", [])])
def test_a_stage_loads_the_modules_of_the_methods_it_runs_and_no_other(stage, options, tiny, tmp_path):
    """What DVC re-runs after a change to a method's module rests on this: the stage really loads no other."""
    import subprocess
    import sys

    root = Path(__file__).resolve().parents[1]
    argv = [sys.executable, "-c", LOADED_AT_EXIT, "--no-mlflow", stage, *data(tiny), *FOLDS, *LEARN, *options,
            "--selection", str(tiny / "selection.json"), "--model-store", str(tiny / "store"),
            "--output", str(tmp_path), *(["--n-jobs", "1"] if stage != "recipes" else [])]
    out = subprocess.run(argv, capture_output=True, text=True, cwd=root)
    assert out.returncode == 0, out.stderr[-2000:]
    loaded = {str(Path(f).resolve().relative_to(root)) for f in json.loads(out.stdout.strip().splitlines()[-1])}
    deps = stage_deps.code_deps(stage)
    assert sorted(f for f in loaded if not any(f == d or f.startswith(d + "/") for d in deps)) == [], stage
    ran = {name for name, entry in Params.load(root / "params.yaml").methods.entries if stage in entry.experiments}
    added = {f"taskseq/methods/{name}.py" for name in added_modules()}
    assert loaded & added == {f"taskseq/methods/{name}.py" for name in ran} & added  # its own, no other


def test_the_recorded_scenarios_are_as_many_as_asked_evenly_spread():
    from taskseq.stages.crossval import _spread

    ids = [f"s{k:02d}" for k in range(10)]
    assert _spread(list(reversed(ids)), 3) == {"s00", "s03", "s06"}  # in sorted order, every len // n-th
    assert _spread(ids, 1) == {"s00"} and _spread(ids, 0) == frozenset()
    assert _spread(ids, 25) == set(ids)  # more asked than there are: every one
