"""The generated benchmark has the paper's shape, replays exactly and is reproducible."""

import filecmp

from taskseq.cli import main
from taskseq.demonstrations.generate import generate
from taskseq.demonstrations.ingest import dataset_summary, load_logs, write_tables
from taskseq.demonstrations.records import parse_record, state_from_dict
from taskseq.settings import Generate
from taskseq.sim.objects import ATTRIBUTE_NAMES
from taskseq.sim.primitives import PRIMITIVES, execute
from taskseq.sim.safety import violations
from taskseq.sim.tasks import TASKS, goal_reached


def test_dataset_has_the_papers_figures(benchmark_tables):
    tables, _ = benchmark_tables
    d = dataset_summary(tables)
    assert d["environments"] == 13
    assert d["objects"] == 43
    assert d["tasks"] == 5 and set(d["sequences_per_task"]) == set(TASKS)
    assert d["scenarios"] == 113
    assert d["sequences"] == 127
    assert d["min_steps"] >= 4 and d["max_steps"] <= 10
    assert 700 <= d["steps"] <= 770
    assert set(d["steps_per_primitive"]) == set(PRIMITIVES)


def test_every_object_has_its_own_attributes(benchmark_tables):
    objects = benchmark_tables[0]["objects"].to_pylist()
    assert len({tuple(o[a] for a in ATTRIBUTE_NAMES) for o in objects}) == len(objects) == 43


def test_demonstrations_are_safe_and_reach_their_goal(benchmark_tables):
    for item in benchmark_tables[1]:
        specs, task, actions = parse_record(item.record)
        state = initial = state_from_dict(specs, item.record["steps"][0]["state"])
        for action in actions:
            assert violations(state, action) == [], (item.record["demo_id"], action)
            state = execute(state, action)
        assert goal_reached(task, initial, state)


def test_no_object_name_or_category_in_the_attributes(benchmark_tables):
    # the model sees attributes only; names exist for people
    record = benchmark_tables[1][0].record
    for obj in record["objects"]:
        assert set(obj["attributes"]) == set(ATTRIBUTE_NAMES)


def test_same_seed_gives_byte_identical_logs_and_tables(benchmark_logs, benchmark_tables, tmp_path):
    again = tmp_path / "raw"
    generate(Generate(seed=0), again)
    names = sorted(p.name for p in benchmark_logs.iterdir())
    assert names == sorted(p.name for p in again.iterdir())
    match, mismatch, errors = filecmp.cmpfiles(benchmark_logs, again, names, shallow=False)
    assert mismatch == [] and errors == []
    write_tables(benchmark_tables[0], tmp_path / "a")
    write_tables(load_logs(again)[0], tmp_path / "b")
    tables = sorted(p.name for p in (tmp_path / "a").iterdir())
    _, mismatch, errors = filecmp.cmpfiles(tmp_path / "a", tmp_path / "b", tables, shallow=False)
    assert mismatch == [] and errors == []


def test_other_seed_gives_another_draw_of_the_same_shape(tmp_path):
    generate(Generate(seed=1), tmp_path / "raw")
    d = dataset_summary(load_logs(tmp_path / "raw")[0])
    assert (d["scenarios"], d["sequences"], d["environments"]) == (113, 127, 13)


def test_replay_command_passes_on_generated_logs(benchmark_logs, capsys):
    assert main(["replay", str(benchmark_logs)]) == 0
    assert "127 demonstrations replay exactly; 0 with problems" in capsys.readouterr().out


def test_replay_takes_one_log_and_names_what_is_wrong_with_a_path(benchmark_logs, tmp_path, capsys):
    first = sorted(benchmark_logs.glob("*.jsonl"))[0]
    one = tmp_path / "one.jsonl"
    one.write_text(first.read_text().splitlines()[0] + "\n")
    assert main(["replay", str(one)]) == 0
    assert "1 demonstration replays exactly; 0 with problems" in capsys.readouterr().out
    assert main(["replay", str(tmp_path / "nowhere")]) == 2
    assert f"{tmp_path / 'nowhere'}: no such folder" in capsys.readouterr().err
    assert main(["--no-mlflow", "ingest", "--input", str(one), "--output", str(tmp_path / "tables")]) == 1
    assert f"{one}: is a file; give the folder that holds it" in capsys.readouterr().err
    assert not (tmp_path / "tables").exists()
