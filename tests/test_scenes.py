"""Rooms never seen in training: the `scenes` stage end to end on tiny worlds, and the transfer's split."""

from __future__ import annotations

import csv
import json
import shutil
from dataclasses import dataclass, field

import pytest
from params_files import params_with, selection_at

from taskseq.cli import main
from taskseq.demonstrations.benchmark import Benchmark
from taskseq.demonstrations.generate import generate
from taskseq.demonstrations.ingest import load_logs
from taskseq.evaluate.methods import ScorerMethod
from taskseq.experiments.transfer import transfer
from taskseq.features.dataset import build_steps
from taskseq.settings import Generate, Params, Procedural
from taskseq.stages import drawn_world, scenes, scenes_world

LEARN = ["--set", "train.tol=0.01", "--set", "train.max_iter=300", "--set", "train.n_slacks=0"]


def _world(folder, world):
    generate(world, folder)
    records = [r.record for r in load_logs(folder)[1]]
    return (*build_steps(records), Benchmark.from_records(records))


@dataclass
class _Spy:
    """A method that notes what it trains on and what it is asked to run."""

    seen: dict = field(default_factory=dict)
    name: str = "spy"
    predicts_args: bool = True

    def fit(self, contexts, meta, scenarios=None):
        self.seen["trained"] = {m.scenario_id for m in meta}
        return self

    def predict_steps(self, contexts, meta, demos):
        self.seen["predicted"] = {m.scenario_id for m in meta}
        return [(0, 0, 0) for _ in contexts]

    def run(self, scenario, max_steps):
        self.seen.setdefault("run", set()).add(scenario.id)
        return None  # as a method that runs no programs


def test_transfer_trains_on_the_first_world_only_and_tests_every_scenario_of_the_second(tmp_path, monkeypatch):
    """The models are trained once, as fold models, on every step of the first world and no other; the fold then
    loads them (no second fit) and tests every scenario of the second world; a DAgger model starts from its base
    model, trained once for both."""
    import taskseq.experiments.transfer as transfer_module
    from taskseq.learn.estimator import StepScorer

    paper = _world(tmp_path / "paper", Generate(seed=0))
    drawn = _world(tmp_path / "drawn", Generate(seed=0, family="procedural", procedural=Procedural(environments=2)))
    trained, fits = [], []
    real_train, real_fit = transfer_module.train_fold_models, StepScorer.fit

    def spy_train(methods, contexts, meta, scenarios, jobs, output, n_jobs=1):
        trained.append(([m.scenario_id for m in meta], {j.method: j.index for j in jobs}, set(scenarios)))
        return real_train(methods, contexts, meta, scenarios, jobs, output, n_jobs)

    def spy_fit(self, contexts, *args, **kwargs):
        fits.append(len(contexts))
        return real_fit(self, contexts, *args, **kwargs)

    monkeypatch.setattr(transfer_module, "train_fold_models", spy_train)
    monkeypatch.setattr(StepScorer, "fit", spy_fit)
    small = {"tol": 0.05, "max_iter": 30}
    methods = {"plain": lambda: ScorerMethod("edge", C=1.0, name="plain", **small),
               "dagger": lambda: ScorerMethod("edge", C=1.0, name="dagger", dagger_rounds=1, **small)}
    results, contexts, meta = transfer(methods, paper, drawn, max_steps=5)
    (seen, jobs, scenarios), = trained
    assert seen == [m.scenario_id for m in paper[1]] and scenarios == set(paper[2].scenarios)
    assert jobs == dict.fromkeys(methods, tuple(range(len(paper[0]))))
    assert len(fits) == 2  # the plain model, which is DAgger's base, and DAgger's refit: none in the fold
    for result in results:
        assert {s.scenario_id for s in result.sequences} == set(drawn[2].scenarios)
        assert [contexts[i] for i in result.step_index] == drawn[0]
        assert [meta[i] for i in result.step_index] == drawn[1] and len(meta) == len(contexts)
    with pytest.raises(ValueError, match="share scenario ids"):
        transfer(methods, paper, paper, max_steps=5)


def test_scenes_hold_out_whole_rooms_whatever_crossval_group_by_says():
    s = scenes_world.settings(Params.load(None, ["crossval.group_by=scenario", "crossval.folds=4"]))
    assert drawn_world.settings(Params.load(None, ["world.family=paper"]), 3).family == "procedural"
    assert (s.fold_models.folds.group_by, s.crossval.crossval.group_by, s.noise.replay.folds.group_by,
            s.feedback.replay.folds.group_by) == ("environment",) * 4
    assert s.crossval.crossval.folds == 4


def _scenes(root, paper, settings):
    """The scenes stages of world seed 0, as dvc.yaml runs them: the drawn world into root/drawn/0, its
    evaluations (and the paper-shaped world's, `paper`) into root/data, the tables over seeds into root/reports."""
    drawn, data = root / "drawn" / "0", root / "data"
    assert main(["--no-mlflow", "drawn_world", "--world-seed", "0", "--output", str(drawn), *settings]) == 0
    assert main(["--no-mlflow", "scenes_world", "--world-seed", "0", "--selection", str(root / "selection.json"),
                 "--paper", str(paper), "--drawn", str(drawn), "--paper-results", str(data / "paper" / "0"),
                 "--drawn-results", str(data / "drawn" / "0"), "--transfer-results", str(data / "transfer" / "0"),
                 *settings, "--n-jobs", "1"]) == 0
    assert main(["--no-mlflow", "scenes", "--results", str(data), "--worlds", str(root / "drawn"), "--output",
                 str(root / "reports"), *settings]) == 0


def test_the_scenes_stage_writes_every_table_over_seeds(benchmark_logs, tmp_path):
    paper = tmp_path / "paper" / "0"
    raw = tmp_path / "paper_raw"
    raw.mkdir()
    for env in ("env01", "env04"):
        shutil.copy(benchmark_logs / f"{env}.jsonl", raw)
    assert main(["--no-mlflow", "ingest", "--input", str(raw), "--output", str(paper / "processed")]) == 0
    assert main(["--no-mlflow", "features", "--input", str(paper / "processed"), "--output",
                 str(paper / "features")]) == 0
    selection_at(tmp_path / "selection.json", 2.0)
    out, data = tmp_path / "reports", tmp_path / "data"
    settings = ["--set", "world.seeds=[0]", "--set", "procedural.environments=3", "--set", "crossval.folds=2",
                *params_with(tmp_path / "p.yaml", full="noise feedback transfer", relations="transfer"),
                "--set", "noise.rates=0 0.4", "--set", "noise.draws=1", "--set", "feedback.k=2",
                "--set", "feedback.n=0 all", *LEARN]
    _scenes(tmp_path, tmp_path / "paper" / "0", settings)
    for name in ("table1.md", "table1.csv", "failures.md", "crossval_means.json", "metrics.json"):
        assert (out / "paper" / name).is_file() and (out / "drawn" / name).is_file(), name
    for name in ("noise.csv", "feedback.csv", "worlds.json", "dataset.json"):
        assert (out / "drawn" / name).is_file() and not (out / "paper" / name).exists(), name
    assert (out / "transfer.md").is_file() and (out / "transfer_seeds.csv").is_file()
    assert not (out / "drawn" / "recipes.json").exists()  # recipes name the paper-shaped rooms' objects
    draw = json.loads((out / "drawn" / "worlds.json").read_text())["0"]
    assert draw["family"] == "procedural" and draw["environments"] == 3
    rows = list(csv.DictReader((out / "transfer.csv").open()))
    assert [r["method"] for r in rows] == ["full", "relations"]
    means = json.loads((out / "transfer.json").read_text())  # the same figures, unrounded
    assert [{k: f"{v:.2f}" for k, v in means[r["method"]].items()} for r in rows] == [
        {k: v for k, v in r.items() if k != "method"} for r in rows]
    assert all(0.0 <= float(r["sequence_arg"]) <= float(r["success"]) + 1e-9 <= 100.0 for r in rows)
    # the transfer's programs, one per drawn scenario and method, agree with its table and feed `taskseq stats`
    moved = list(csv.DictReader((data / "transfer" / "0" / "crossval_sequences.csv").open()))
    drawn_scenarios = {r["scenario"] for r in csv.DictReader((data / "drawn" / "0" / "crossval_sequences.csv").open())}
    for r in rows:
        mine = [p for p in moved if p["method"] == r["method"]]
        assert {p["scenario"] for p in mine} == drawn_scenarios and len(mine) == len(drawn_scenarios)
        assert f"{100 * sum(p['arg_correct'] == '1' for p in mine) / len(mine):.2f}" == r["sequence_arg"]
    steps = list(csv.DictReader((data / "transfer" / "0" / "crossval_steps.csv").open()))
    assert steps and {p["scenario"].split("/")[0] for p in steps} <= {"proc001", "proc002", "proc003"}
    assert main(["stats", "--worlds", str(data / "transfer"), "--output", str(out / "transfer"),
                 "--set", "world.seeds=[0]", "--set", "stats.resamples=50"]) == 0
    assert "| ours + relations | ours - full (the paper's model) | seq arg |" in \
        (out / "transfer" / "comparisons.md").read_text()
    for part in ("paper", "drawn"):
        means = json.loads((out / part / "crossval_means.json").read_text())
        assert 0.0 <= means["full"]["sequence_arg"] <= 100.0
    assert json.loads((tmp_path / "drawn" / "0" / "dataset.json").read_text())["environments"] == 3
    assert json.loads((out / "drawn" / "dataset.json").read_text())["0"]["environments"] == 3
    # whole rooms held out: every room's programs come from one fold, in the paper-shaped and the drawn world
    for part, rooms in (("paper", {"env01", "env04"}), ("drawn", {"proc001", "proc002", "proc003"})):
        programs = list(csv.DictReader((data / part / "0" / "crossval_sequences.csv").open()))
        folds_of = {}
        for r in programs:
            folds_of.setdefault(r["scenario"].split("/")[0], set()).add(r["fold"])
        assert set(folds_of) == rooms and all(len(f) == 1 for f in folds_of.values()), folds_of


def test_rooms_held_out_never_reach_training(tmp_path):
    """A spy in every fold of a drawn world's cross-validation grouped by room: no step of a tested room trains."""
    from taskseq.experiments.crossval import cross_validate

    contexts, meta, bench = _world(tmp_path / "drawn", Generate(seed=1, family="procedural",
                                                                 procedural=Procedural(environments=4)))
    spies = []

    def make():
        spies.append(_Spy())
        return spies[-1]

    cross_validate({"spy": make}, contexts, meta, bench, n_folds=4, group_by="environment")
    spies = [s for s in spies if s.seen]  # one more is made, unfitted, to weigh the jobs
    assert len(spies) == 4
    tested_rooms = set()
    for spy in spies:
        trained = {s.split("/")[0] for s in spy.seen["trained"]}
        tested = {s.split("/")[0] for s in spy.seen["predicted"]}
        assert len(tested) == 1 and not trained & tested
        tested_rooms |= tested
    assert tested_rooms == {f"proc{i:03d}" for i in range(1, 5)}


def test_a_drawn_objects_logged_attributes_follow_from_its_size_and_flags(tmp_path):
    """A new object's flags are its kind's fixed ones and some of those drawn for it; objects of a kind differ."""
    from taskseq.demonstrations.records import expected_attributes
    from taskseq.sim.objects import BINARY_ATTRIBUTES, attributes_of_box
    from taskseq.sim.procedural import NEW_KINDS

    generate(Generate(seed=2, family="procedural", procedural=Procedural(environments=3, new_objects=0.9)),
             tmp_path / "raw")
    kinds = {k.name: k for group in NEW_KINDS.values() for k in group}
    flag_sets: dict[str, set[frozenset[str]]] = {}
    for record in (r.record for r in load_logs(tmp_path / "raw")[1]):
        for obj in record["objects"]:
            if obj["name"] in kinds:
                kind = kinds[obj["name"]]
                flags = frozenset(f for f in BINARY_ATTRIBUTES if obj["attributes"][f] == 1)
                drawn = {f for f, _ in kind.maybe} | {s for s, _ in kind.shapes}
                assert set(kind.flags.split()) <= flags <= set(kind.flags.split()) | drawn, obj["id"]
                assert obj["attributes"] == pytest.approx(attributes_of_box(tuple(obj["size"]), flags))
                assert obj["attributes"] == pytest.approx(expected_attributes(obj))
                assert obj["attributes"]["volume"] == pytest.approx(obj["size"][0] * obj["size"][1] * obj["size"][2])
                flag_sets.setdefault(kind.name, set()).add(flags)
    assert sum(len(s) for s in flag_sets.values()) > 10
    assert any(len(s) > 1 for s in flag_sets.values())  # one kind, objects with different drawn flags


def test_with_drawn_reported_worlds_the_stage_runs_and_says_no_transfer_was_measured(tmp_path, capsys):
    """`world.family: procedural` makes the reported world of a seed the very world this stage draws for it, so
    there is nothing to transfer from; the stage still writes every table and says why the transfer is missing."""
    common = ["--set", "world.family=procedural", "--set", "procedural.environments=2", *LEARN]
    reported = tmp_path / "worlds" / "0"
    assert main(["--no-mlflow", "generate", "--world-seed", "0", "--output", str(reported / "raw"), *common]) == 0
    assert main(["--no-mlflow", "ingest", "--input", str(reported / "raw"), "--output",
                 str(reported / "processed")]) == 0
    assert main(["--no-mlflow", "features", "--input", str(reported / "processed"), "--output",
                 str(reported / "features")]) == 0
    selection_at(tmp_path / "selection.json", 2.0)
    out = tmp_path / "reports"
    settings = ["--set", "world.seeds=[0]", "--set", "crossval.folds=2",
                *params_with(tmp_path / "p.yaml", full="noise feedback transfer"), "--set", "noise.rates=0",
                "--set", "noise.draws=1", "--set", "feedback.k=2", "--set", "feedback.n=0", *common]
    _scenes(tmp_path, reported, settings)
    assert "Not measured" in (out / "transfer.md").read_text() and "procedural" in (out / "transfer.md").read_text()
    assert list(csv.DictReader((out / "transfer.csv").open())) == []
    assert json.loads((out / "transfer.json").read_text()) == {}
    assert not (tmp_path / "data" / "drawn" / "0" / "transfer.csv").exists()
    assert not any((tmp_path / "data" / "transfer" / "0").iterdir())  # the declared folder, empty
    # a drawn world that is not there is named before any work, and nothing is written
    code = main(["--no-mlflow", "scenes_world", "--paper", str(reported), "--drawn", str(tmp_path / "nowhere"),
                 "--paper-results", str(tmp_path / "p"), "--drawn-results", str(tmp_path / "d"),
                 "--transfer-results", str(tmp_path / "t")])
    assert code == 1 and not any((tmp_path / name).exists() for name in ("p", "d", "t"))
    assert f"{tmp_path / 'nowhere' / 'features'}: no such folder" in capsys.readouterr().err
    for part in ("paper", "drawn"):
        assert 0.0 <= json.loads((out / part / "crossval_means.json").read_text())["full"]["sequence_arg"] <= 100.0
    for stage in (scenes, scenes_world):
        assert stage.settings(Params.load(None, ["world.family=procedural"])).paper_shaped is False
        assert stage.settings(Params.load(None, [])).paper_shaped is True


def test_the_summary_names_the_drawn_worlds_size(tmp_path):
    from taskseq.report.summary import _scenes

    drawn = tmp_path / "scenes" / "drawn"
    drawn.mkdir(parents=True)
    (drawn / "crossval_means.json").write_text(json.dumps({"full": {"sequence_arg": 50.0, "success": 60.0}}))
    (drawn / "worlds.json").write_text(json.dumps({"0": {"environments": 130}, "3": {"environments": 130}}))
    text = "\n".join(_scenes(tmp_path, {"full": {"sequence_arg": 55.0}}, {"full": "ours - full"}))
    assert "a world of 130 rooms drawn by the same seed" in text
    assert "| ours - full | 55.0 ± 0.0 | - | 50.0 ± 0.0 (60.0) | - |" in text
