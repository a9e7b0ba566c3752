"""People's demonstrations in the pipeline: an empty folder changes nothing, the train switch adds their steps,
the people stage compares the planner with and without them, and the teach stage measures k taught tasks."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import pytest

from taskseq.demonstrations.people import people_records
from taskseq.features.dataset import build_steps, write_features
from taskseq.learn.estimator import StepScorer
from taskseq.learn.persist import describe
from taskseq.serve.environments import world_environment
from taskseq.serve.writer import RecordWriter, person_record
from taskseq.settings import Learner, Methods, People, Teach, Train, World
from taskseq.sim.demonstrator import demonstrate
from taskseq.sim.scenarios import doable_tasks
from taskseq.sim.tasks import Task
from taskseq.stages import people as people_stage
from taskseq.stages import teach as teach_stage
from taskseq.stages import train as train_stage
from taskseq.stages.options import PeopleOptions, TeachOptions, TrainOptions

LEARNER = Learner(tol=1e-2, max_iter=300)  # C: untuned, no selection file
TAUGHT = [Task("pour", ("obj27",)), Task("throw_away", ("obj43",))]  # in env01


@pytest.fixture(scope="module")
def features(benchmark_tables, tmp_path_factory) -> Path:
    """World 0's steps, as the features stage writes them."""
    out = tmp_path_factory.mktemp("features") / "features"
    write_features(*build_steps([item.record for item in benchmark_tables[1]]), out)
    return out


@pytest.fixture
def taught(tmp_path) -> Path:
    """Two demonstrations of env01, made by a person in the browser (the server's writer)."""
    env = world_environment(0, "env01")
    writer = RecordWriter(tmp_path / "people")
    for task in TAUGHT:
        writer.append(person_record(env, task, demonstrate(env.state, task)[0], "p1", corrected=[0]))
    return tmp_path / "people"


def test_an_empty_folder_is_an_empty_source(tmp_path):
    (tmp_path / "people").mkdir()
    records, summary = people_records(tmp_path / "people")
    assert records == [] and summary["sequences"] == 0 and summary["participants"] == 0
    with pytest.raises(FileNotFoundError, match="no such folder"):
        people_records(tmp_path / "absent")


def test_people_records_are_counted_with_their_participants_and_corrections(taught):
    records, summary = people_records(taught)
    assert len(records) == 2 and summary["sequences"] == 2 and summary["environments"] == 1
    assert summary["participants"] == 1 and summary["corrected_sequences"] == 2 and summary["corrections"] == 2


def test_the_people_stage_with_no_demonstrations_trains_nothing(tmp_path, features):
    (tmp_path / "people").mkdir()
    result = people_stage.run(people_stage.Settings(People(logs=str(tmp_path / "people")), LEARNER, 20),
                              PeopleOptions(features=features, output=tmp_path / "out"))
    assert result == {"environments": [], "success_before": None, "success_after": None}
    assert json.loads((tmp_path / "out" / "dataset.json").read_text())["sequences"] == 0
    assert "No people's demonstrations yet" in (tmp_path / "out" / "before_after.md").read_text()


def test_the_people_stage_judges_the_tasks_people_did_not_demonstrate(taught, tmp_path, features):
    result = people_stage.run(people_stage.Settings(People(logs=str(taught)), LEARNER, 20),
                              PeopleOptions(features=features, output=tmp_path / "out"))
    [row] = result["environments"]
    assert row["env_id"] == "w0-env01" and row["demonstrations"] == 2
    doable = [str(t) for t, _ in doable_tasks(world_environment(0, "env01").state)]
    assert all(str(t) in doable for t in TAUGHT)
    assert row["held_out_tasks"] == len(doable) - 2  # every task the demonstrator can do there but the two taught
    assert 0 <= row["success_before"] <= 100 and 0 <= row["success_after"] <= 100
    assert "| w0-env01 | 2 |" in (tmp_path / "out" / "before_after.md").read_text()


def test_the_train_switch_adds_people_steps_and_off_leaves_the_metrics_as_they_were(taught, tmp_path, features):
    train = Train(tol=1e-2, max_iter=300, method="full")  # C: untuned, no selection file
    without = train_stage.run(train_stage.Settings(train, None, Methods()),
                              TrainOptions(features=features, model=tmp_path / "a.npz"))
    with_people = train_stage.run(train_stage.Settings(train, taught, Methods()),
                                  TrainOptions(features=features, model=tmp_path / "b.npz"))
    assert "people_sequences" not in without and with_people["people_sequences"] == 2
    assert (tmp_path / "a.npz").read_bytes() != (tmp_path / "b.npz").read_bytes()
    # `taskseq plan` and the web app say which planner runs, people's part in it included
    assert "people's sequences 2, " in describe(StepScorer.load(tmp_path / "b.npz").meta_)
    assert "people" not in describe(StepScorer.load(tmp_path / "a.npz").meta_)


def test_the_teach_stage_runs_the_shipped_planner_on_the_same_tasks_for_every_k(tmp_path, capsys):
    """End to end on a drawn world of three rooms, with the full model as the method ranked first."""
    from taskseq.cli import main

    assert main(["--no-mlflow", "generate", "--world-seed", "0", "--set", "world.family=procedural",
                 "--set", "procedural.environments=3", "--output", str(tmp_path / "raw")]) == 0
    assert main(["--no-mlflow", "ingest", "--input", str(tmp_path / "raw"), "--output",
                 str(tmp_path / "worlds" / "0" / "processed")]) == 0
    selection = tmp_path / "selection.json"
    selection.write_text(json.dumps({"method": "full", "settings": {"full": {"C": 1.0}}}))
    settings = teach_stage.Settings(World(seeds=(0,)), Teach(environments=("proc003",), k=(0, 2), seed=0, weight=2),
                                    LEARNER, 20, Methods())
    options = TeachOptions(worlds=tmp_path / "worlds", output=tmp_path / "out", selection=selection)
    table = teach_stage.run(settings, options)
    assert [r["k"] for r in table] == [0, 2]
    assert all(0 <= r["sequence_arg_mean"] <= r["success_mean"] + 1e-9 <= 100 for r in table)
    out = capsys.readouterr().out
    held_out = {line.split("of ")[1].split()[0] for line in out.splitlines() if "held-out" in line}
    assert len(held_out) == 1  # one test set for every k
    assert "| 2 |" in (tmp_path / "out" / "teach.md").read_text() and (tmp_path / "out" / "teach.png").exists()
    assert "`full`" in (tmp_path / "out" / "teach.md").read_text()
    # one job per world and k: two processes write the same bytes as one
    teach_stage.run(settings, replace(options, output=tmp_path / "out2"), n_jobs=2)
    for name in ("teach.csv", "teach_seeds.csv", "teach_programs.csv", "teach.md"):
        assert (tmp_path / "out2" / name).read_bytes() == (tmp_path / "out" / name).read_bytes(), name
    with pytest.raises(ValueError, match="proc099 not among world 0's rooms"):
        teach_stage.run(teach_stage.Settings(World(seeds=(0,)), Teach(environments=("proc099",)), LEARNER, 20,
                                             Methods()), options)
