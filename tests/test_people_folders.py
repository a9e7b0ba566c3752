"""A folder of people's demonstrations never strands data: two versions of one room ingest together, and a bad
file is reported and left out, where it is, while the others are used. The benchmark's own logs still fail at
their first problem.

Every file here is written as a person's web session writes it: the server's environment reader and record
writer (`taskseq.serve`)."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import pytest

from taskseq.cli import main
from taskseq.demonstrations.ingest import (
    SCHEMAS,
    is_person_record,
    load_logs,
    load_people_logs,
    people_folder,
    read_tables,
    records_from_tables,
)
from taskseq.demonstrations.people import people_records
from taskseq.demonstrations.records import demonstration_record, spec_to_dict, state_to_dict
from taskseq.demonstrations.validate import LogError
from taskseq.serve.environments import file_environment, world_environment
from taskseq.serve.writer import RecordWriter, person_record
from taskseq.sim.demonstrator import demonstrate
from taskseq.sim.scenarios import candidate_scenarios
from taskseq.sim.tasks import Task

TASKS = [Task("pour", ("obj27",)), Task("throw_away", ("obj43",))]  # in env01: the water, the crumpled paper


def room_file(cup_width: float | None = None) -> str:
    """env01 of world 0 as a person's room file (`tearoom.json`); `cup_width` saves it again with the cup wider."""
    state = world_environment(0, "env01").state
    specs = dict(state.specs)
    if cup_width is not None:
        cup = specs["obj14"]
        specs["obj14"] = dataclasses.replace(cup, size=(cup_width, *cup.size[1:]))
    return json.dumps({"objects": [spec_to_dict(s) for s in specs.values()], "state": state_to_dict(state)})


def demonstrate_in(folder: Path, text: str) -> Path:
    """Demonstrate every task of TASKS in the room file, as the web page does; the log file written."""
    env = file_environment("tearoom.json", text)
    writer = RecordWriter(folder)
    for task in TASKS:
        path = writer.append(person_record(env, task, demonstrate(env.state, task)[0]))
    return path


@pytest.fixture
def two_versions(tmp_path) -> tuple[Path, Path, Path]:
    """A people's folder holding the records of a room and of the same room saved again with a wider cup."""
    folder = tmp_path / "people"
    return folder, demonstrate_in(folder, room_file()), demonstrate_in(folder, room_file(cup_width=0.095))


def lines(path: Path) -> list[dict]:
    return [json.loads(line) for line in path.read_text().splitlines()]


def test_two_versions_of_a_room_ingest_together_and_the_tables_give_back_every_record(two_versions, tmp_path):
    folder, v1, v2 = two_versions
    assert v1 != v2 and v1.name.startswith("tearoom-") and v2.name.startswith("tearoom-")
    assert main(["--no-mlflow", "ingest", "--people", "--input", str(folder), "--output", str(tmp_path / "t")]) == 0
    tables = read_tables(tmp_path / "t")
    cups = {(r["env_id"], r["w"]) for r in tables["objects"].to_pylist() if r["object_id"] == "obj14"}
    assert cups == {(v1.stem, 0.075), (v2.stem, 0.095)}
    written = sorted([*lines(v1), *lines(v2)], key=lambda r: r["env_id"])
    assert records_from_tables(tables) == written
    records, summary = people_records(folder)
    assert len(records) == 4 and summary["environments"] == 2
    assert summary["objects"] == len(world_environment(0, "env01").state.specs) + 1  # the two cups


def test_a_participant_and_corrections_survive_the_tables(tmp_path):
    """Record -> ingest -> tables -> records keeps each record's `participant` and `corrected` (absent, empty and
    not), as `taskseq serve` writes them; the sequences table holds them in columns null where a record has none."""
    folder = tmp_path / "people"
    writer = RecordWriter(folder)
    env = world_environment(0, "env01")
    actions = demonstrate(env.state, POUR)[0]
    kinds = [{}, {"participant": "p07"}, {"corrected": []}, {"participant": "p07", "corrected": [2, 0]},
             {"participant": "walkthrough", "corrected": [len(actions)]}]
    for kind in kinds:
        path = writer.append(person_record(env, POUR, actions, **kind))
    written = lines(path)
    assert [(r.get("participant"), r.get("corrected")) for r in written] == [
        (None, None), ("p07", None), (None, []), ("p07", [0, 2]), ("walkthrough", [len(actions)])]
    assert main(["--no-mlflow", "ingest", "--input", str(folder), "--output", str(tmp_path / "t")]) == 0
    tables = read_tables(tmp_path / "t")
    assert tables["sequences"].column_names[-2:] == ["participant", "corrected"]
    assert records_from_tables(tables) == written
    assert records_from_tables(load_people_logs(folder)[0]) == written


def test_the_person_columns_are_there_only_where_a_record_carries_the_field(tmp_path):
    """A column is written only where some record carries its field, so the benchmark's tables, whose records
    carry neither, keep their schema (and bytes), and a folder without corrections has no `corrected` column."""
    folder = tmp_path / "people"
    env = world_environment(0, "env01")
    RecordWriter(folder).append(person_record(env, POUR, demonstrate(env.state, POUR)[0], participant="p07"))
    tables = load_people_logs(folder)[0]
    assert tables["sequences"].column_names == [*SCHEMAS["sequences"].names, "participant"]
    assert records_from_tables(tables)[0]["participant"] == "p07"
    person, bench = people_and_benchmark(tmp_path / "mixed")
    person.unlink()  # the scripted demonstrator's log alone
    assert load_logs(bench.parent)[0]["sequences"].schema == SCHEMAS["sequences"]


def as_benchmark(path: Path) -> None:
    """Rewrite a log's records as the scripted demonstrator writes them: a sequence number for a demo_id."""
    records = lines(path)
    for k, record in enumerate(records, start=1):
        record["demo_id"] = f"{record['scenario_id']}/{k}"
    path.write_text("".join(json.dumps(r) + "\n" for r in records))


def test_the_benchmark_logs_keep_one_description_per_object_id(two_versions, tmp_path, capsys):
    """Records without the marks of `taskseq serve` are read as the benchmark's logs are, and the message says
    what to do."""
    folder, *versions = two_versions
    for path in versions:
        as_benchmark(path)
    first, second = sorted(versions)  # the order ingest reads them in
    assert main(["--no-mlflow", "ingest", "--input", str(folder), "--output", str(tmp_path / "t")]) != 0
    said = capsys.readouterr().err
    assert f"{second.name}:1: objects[6]: object obj14 differs from its description at {first.name}:1" in said
    assert "ingests with --people" in said
    assert not (tmp_path / "t").exists()


def test_an_environment_describes_its_objects_alike_in_every_record(tmp_path):
    """Per environment the check stays: a record of one room version with another cup is refused."""
    folder = tmp_path / "people"
    path = demonstrate_in(folder, room_file())
    first, second = lines(path)
    next(o for o in second["objects"] if o["id"] == "obj14")["name"] = "teacup_with_handle"
    path.write_text("\n".join(json.dumps(r) for r in (first, second)) + "\n")
    _, records, [problem] = load_people_logs(folder)
    assert records == []
    assert problem.line == 2 and f"object obj14 differs from its description in environment {path.stem}" in str(problem)


@pytest.mark.parametrize("damage, reason", [
    (lambda text: text[: len(text) // 2], "not valid JSON"),  # cut short: a full disk, a copy stopped
    (lambda text: text.replace('"name":"pour"', '"name":"fly"', 1), "task.name: 'fly' is not one of"),
])
def test_a_bad_file_of_a_people_folder_is_left_out_where_it_is_and_the_others_are_used(tmp_path, capsys, damage,
                                                                                        reason):
    folder = tmp_path / "people"
    writer = RecordWriter(folder)
    for env_id in ("env01", "env02"):
        env = world_environment(0, env_id)
        task = Task("pour", ("obj27",)) if env_id == "env01" else Task("pour", ("obj29",))
        writer.append(person_record(env, task, demonstrate(env.state, task)[0]))
    bad = folder / "w0-env01.jsonl"
    bad.write_text(damage(bad.read_text()))
    damaged = bad.read_bytes()

    records, summary = people_records(folder)
    assert [r["env_id"] for r in records] == ["w0-env02"] and summary["sequences"] == 1
    said = capsys.readouterr().err
    assert f"left out {bad}" in said and reason in said
    assert main(["--no-mlflow", "ingest", "--people", "--input", str(folder), "--output", str(tmp_path / "t")]) == 0
    out = capsys.readouterr()
    assert "ingested 1 sequence (" in out.out and f"left out {bad}" in out.err and reason in out.err
    assert bad.read_bytes() == damaged  # nothing is lost: the file stays as it was
    with pytest.raises(LogError, match=reason):  # the benchmark's own logs fail at their first problem
        load_logs(folder)


def test_a_file_at_odds_with_an_earlier_one_is_left_out(tmp_path):
    """A log copied under another name repeats its demo ids: the copy read second is left out, named."""
    folder = tmp_path / "people"
    path = demonstrate_in(folder, room_file())
    copy = folder / "zz-copy.jsonl"
    copy.write_bytes(path.read_bytes())
    _, records, [problem] = load_people_logs(folder)
    assert len(records) == len(TASKS) and problem.path == str(copy) and "already used at" in str(problem)


def test_a_people_folder_with_no_usable_file_is_an_error_naming_them(tmp_path, capsys):
    folder = tmp_path / "people"
    folder.mkdir()
    (folder / "w0-env01.jsonl").write_text("{not json\n")
    assert main(["--no-mlflow", "ingest", "--people", "--input", str(folder), "--output", str(tmp_path / "t")]) != 0
    said = capsys.readouterr().err
    assert "w0-env01.jsonl:1" in said and "no usable records: 1 file left out" in said
    assert not (tmp_path / "t").exists()


def people_and_benchmark(folder: Path) -> tuple[Path, Path]:
    """A person's log of env01 (written by the server's writer, no participant, demonstrate mode) and the
    scripted demonstrator's log of env02, each in its own file of `folder`."""
    env = world_environment(0, "env01")
    person = RecordWriter(folder).append(person_record(env, POUR, demonstrate(env.state, POUR)[0]))
    scenarios = [s for s in candidate_scenarios(0) if s.env_id == "env02"][:2]
    bench = folder / "env02.jsonl"
    bench.write_text("".join(json.dumps(demonstration_record(s, 0)) + "\n" for s in scenarios))
    return person, bench


POUR = TASKS[0]


def test_a_record_of_the_web_app_is_told_from_the_scripted_demonstrators(tmp_path):
    """Even a record with neither a participant nor corrections (demonstrate mode, no id typed) says who wrote it:
    the writer's demo_id; the generator's sequence numbers never look like one."""
    person, bench = people_and_benchmark(tmp_path)
    [record] = lines(person)
    assert "participant" not in record and "corrected" not in record and is_person_record(record)
    assert not any(is_person_record(r) for r in lines(bench))
    assert is_person_record({**lines(bench)[0], "participant": "p07"})
    assert is_person_record({**lines(bench)[0], "corrected": []})


def test_ingest_reads_a_people_folder_the_peoples_way_without_the_flag(tmp_path, capsys):
    """A cut-short file of a people's folder is left out, named, and the others ingest, with no --people."""
    folder = tmp_path / "people"
    writer = RecordWriter(folder)
    for env_id, task in (("env01", POUR), ("env02", Task("pour", ("obj29",)))):
        env = world_environment(0, env_id)
        writer.append(person_record(env, task, demonstrate(env.state, task)[0]))
    bad = folder / "w0-env01.jsonl"
    bad.write_text(bad.read_text()[:500])
    (folder / "README.md").write_text("not a log\n")
    assert people_folder(folder)
    assert main(["--no-mlflow", "ingest", "--input", str(folder), "--output", str(tmp_path / "t")]) == 0
    out = capsys.readouterr()
    assert "ingested 1 sequence (" in out.out
    assert "ingested as a folder of people's demonstrations" in out.err
    assert f"left out {bad}" in out.err and "not valid JSON" in out.err


def test_the_benchmarks_logs_and_a_mixed_folder_still_fail_at_their_first_problem(tmp_path, capsys):
    """The generator's logs are the pipeline's own data: a bad line there is a bug to see, not a file to skip. A
    folder holding both kinds of record is not a people's folder either."""
    bench_only = tmp_path / "bench"
    bench_only.mkdir()
    _, bench = people_and_benchmark(tmp_path / "mixed")
    (bench_only / bench.name).write_bytes(bench.read_bytes())
    for folder in (bench_only, tmp_path / "mixed"):
        assert not people_folder(folder)
        target = folder / "env02.jsonl"
        target.write_text(target.read_text().replace('"name":"pour"', '"name":"fly"', 1)
                          .replace('"name": "pour"', '"name": "fly"', 1))
        assert main(["--no-mlflow", "ingest", "--input", str(folder), "--output", str(tmp_path / "t")]) != 0
        said = capsys.readouterr().err
        assert "env02.jsonl:1: task.name: 'fly' is not one of" in said and "people's" not in said
        assert not (tmp_path / "t").exists()


def test_a_log_the_server_writes_can_be_read_by_others_as_a_file_open_makes_it(tmp_path, monkeypatch):
    """The records were written owner-only (a temporary file from mkstemp renamed into place): another user of
    the machine could not read people's demonstrations. A log takes the permissions `open` gives a new file, and
    an existing log keeps its own."""
    import os

    from taskseq.runtime import atomic

    monkeypatch.setattr(atomic, "_UMASK", 0o022)  # the usual umask, under which mkstemp's 0600 would show
    path = demonstrate_in(tmp_path / "people", room_file())
    assert path.stat().st_mode & 0o777 == 0o644
    os.chmod(path, 0o640)
    demonstrate_in(tmp_path / "people", room_file())
    assert path.stat().st_mode & 0o777 == 0o640
