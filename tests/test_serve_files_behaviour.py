"""The web app's file access on hand-made folders: the record writer writes only `<folder>/<env_id>.jsonl`, whole,
and refuses every other name; environment files are read only by a name listed in their folder; an environment's
id and label say which initial state it is."""

from __future__ import annotations

import codecs
import json
import os
import pathlib
import re

import numpy as np
import pytest

from taskseq.demonstrations.records import dumps, spec_to_dict, state_to_dict
from taskseq.demonstrations.validate import LogError, LoggedRecord
from taskseq.serve import writer as writer_module
from taskseq.serve.environments import (
    MAX_SEED,
    SAFE_NAME,
    file_environment,
    named_files,
    read_named,
    world_environment,
)
from taskseq.serve.writer import LOCK_NAME, RecordWriter, WriterClosed, check_safe, person_record
from taskseq.sim.catalog import ENVIRONMENTS, build_environment
from taskseq.sim.demonstrator import demonstrate
from taskseq.sim.primitives import Action
from taskseq.sim.tasks import Task

POUR = Task("pour", ("obj27",))  # env01: the water in its bottle, on the kitchen table


@pytest.fixture(scope="module")
def env01():
    return world_environment(0, "env01")


@pytest.fixture(scope="module")
def pour(env01) -> list[Action]:
    return demonstrate(env01.state, POUR)[0]


def listing(folder):
    return sorted(p.name for p in folder.iterdir())


def environment_text(state) -> str:
    return json.dumps({"objects": [spec_to_dict(s) for s in state.specs.values()], "state": state_to_dict(state)})


# --- the record writer ---------------------------------------------------------------------------------------------

@pytest.mark.parametrize("env_id", ["../x", "a/b", "/abs", ".hidden", "a.b", "", "-lead", "_lead", "a b", "x" * 65,
                                    "w0-env01.jsonl", "a\nb", "a\n"])
def test_a_name_that_is_not_a_plain_file_stem_is_refused_and_nothing_is_written(tmp_path, env_id):
    writer = RecordWriter(tmp_path / "people")
    with pytest.raises(ValueError, match="cannot name a log file"):
        writer.path_for(env_id)
    assert not (tmp_path / "people").exists()


@pytest.mark.parametrize("env_id", ["w0-env01", "A", "9", "a_b-c", "x" * 64])
def test_a_plain_name_is_a_jsonl_file_directly_in_the_writers_folder(tmp_path, env_id, monkeypatch):
    monkeypatch.chdir(tmp_path)
    writer = RecordWriter("people")  # a relative folder is the one under the working folder of the start
    assert writer.folder == tmp_path / "people" and writer.folder.is_absolute()
    assert writer.path_for(env_id) == tmp_path / "people" / f"{env_id}.jsonl"


def test_the_folder_check_stands_even_if_the_name_pattern_let_a_path_through(tmp_path, monkeypatch):
    monkeypatch.setattr(writer_module, "SAFE_NAME", re.compile(r".*"))
    writer = RecordWriter(tmp_path)
    with pytest.raises(ValueError, match=r"'\.\./x' would write outside"):
        writer.path_for("../x")
    with pytest.raises(ValueError, match="would write outside"):
        writer.path_for("a/b")
    assert writer.path_for("ok") == tmp_path / "ok.jsonl"


def test_a_record_is_appended_whole_to_its_environments_file_and_nothing_else_is_left(tmp_path, env01, pour):
    folder = tmp_path / "data" / "people"  # made on the first append
    writer = RecordWriter(folder)
    first, second = person_record(env01, POUR, pour, "p1"), person_record(env01, POUR, pour, "p2")
    assert writer.append(first) == folder / "w0-env01.jsonl"
    assert (folder / "w0-env01.jsonl").read_bytes() == (dumps(first) + "\n").encode("utf-8")
    assert writer.append(second) == folder / "w0-env01.jsonl"
    assert (folder / "w0-env01.jsonl").read_bytes() == (dumps(first) + "\n" + dumps(second) + "\n").encode("utf-8")
    assert listing(folder) == [LOCK_NAME, "w0-env01.jsonl"] and LOCK_NAME == ".lock"
    assert listing(tmp_path) == ["data"] and listing(tmp_path / "data") == ["people"]


def test_a_log_that_does_not_end_with_a_whole_line_is_left_as_it_is(tmp_path, env01, pour):
    (tmp_path / "w0-env01.jsonl").write_bytes(b'{"half": ')
    with pytest.raises(ValueError, match="w0-env01.jsonl does not end with a whole line"):
        RecordWriter(tmp_path).append(person_record(env01, POUR, pour))
    assert (tmp_path / "w0-env01.jsonl").read_bytes() == b'{"half": '
    assert listing(tmp_path) == [LOCK_NAME, "w0-env01.jsonl"]


def test_a_write_that_fails_part_way_leaves_the_old_log_and_no_temporary_file(tmp_path, env01, pour, monkeypatch):
    writer = RecordWriter(tmp_path)
    writer.append(person_record(env01, POUR, pour))
    before = (tmp_path / "w0-env01.jsonl").read_bytes()

    def broken(fd):
        raise OSError("disk full")

    monkeypatch.setattr(writer_module.os, "fsync", broken)
    with pytest.raises(OSError, match="disk full"):
        writer.append(person_record(env01, POUR, pour))
    assert (tmp_path / "w0-env01.jsonl").read_bytes() == before
    assert listing(tmp_path) == [LOCK_NAME, "w0-env01.jsonl"]


def test_a_write_that_reads_back_other_bytes_is_an_error(tmp_path, env01, pour, monkeypatch):
    writer = RecordWriter(tmp_path)
    record = person_record(env01, POUR, pour)
    real = os.replace

    def lossy(src, dst):
        with open(src, "ab") as fh:
            fh.write(b"x")
        real(src, dst)

    monkeypatch.setattr(writer_module.os, "replace", lossy)
    n = len((dumps(record) + "\n").encode("utf-8"))
    with pytest.raises(OSError, match=rf"w0-env01.jsonl: read back {n + 1} bytes, expected {n}$"):
        writer.append(record)


def test_the_temporary_file_is_hidden_beside_the_log_and_the_folder_is_synced(tmp_path, env01, pour, monkeypatch):
    replaced, synced = [], []
    real_replace, real_fsync = os.replace, os.fsync

    def replace(src, dst):
        replaced.append((os.fspath(src), os.fspath(dst)))
        real_replace(src, dst)

    def fsync(fd):
        synced.append(os.path.isdir(f"/proc/self/fd/{fd}"))
        real_fsync(fd)

    monkeypatch.setattr(writer_module.os, "replace", replace)
    monkeypatch.setattr(writer_module.os, "fsync", fsync)
    RecordWriter(tmp_path).append(person_record(env01, POUR, pour))
    [(src, dst)] = replaced
    assert os.path.dirname(src) == os.fspath(tmp_path) and os.path.basename(src).startswith(".w0-env01.jsonl.")
    assert dst == os.fspath(tmp_path / "w0-env01.jsonl")
    assert synced == [False, True]  # the file's content, then the folder's entry


def test_a_rename_that_fails_after_it_happened_reports_its_own_error(tmp_path, env01, pour, monkeypatch):
    real = os.replace

    def late(src, dst):
        real(src, dst)
        raise OSError("reported late")

    monkeypatch.setattr(writer_module.os, "replace", late)
    with pytest.raises(OSError, match="^reported late$"):  # not the temporary file's absence
        RecordWriter(tmp_path).append(person_record(env01, POUR, pour))


def test_a_refused_record_is_named_by_its_log_file_and_line_zero(tmp_path, env01, pour):
    short = person_record(env01, POUR, pour[:-1])  # replays, but short of the goal
    with pytest.raises(LogError) as refused:
        RecordWriter(tmp_path).append(short)
    assert refused.value.path == str(tmp_path / "w0-env01.jsonl") and refused.value.line == 0
    assert str(refused.value).startswith(f"{tmp_path / 'w0-env01.jsonl'}:0: ")


WATER = ("move_close(obj20)", "grasp(obj27)", "hold_above(obj27,obj14)", "release(obj27)")  # the liquid itself


def test_an_unsafe_step_is_found_by_replaying_from_the_records_first_state(tmp_path, env01):
    actions = [Action.parse(t) for t in WATER]
    record = person_record(env01, Task("pour_to", ("obj27", "obj14")), actions)
    with pytest.raises(LogError) as refused:
        RecordWriter(tmp_path / "people").append(record)
    assert (refused.value.path, refused.value.line, refused.value.field) == (
        str(tmp_path / "people" / "w0-env01.jsonl"), 0, "steps[1]")
    assert not (tmp_path / "people").exists()
    one = {**record, "steps": [record["steps"][1]]}  # the grasp alone, from the world it was made in
    with pytest.raises(LogError) as alone:
        check_safe(LoggedRecord(tmp_path / "x.jsonl", 7, one))
    assert (alone.value.path, alone.value.line, alone.value.field) == (str(tmp_path / "x.jsonl"), 7, "steps[0]")
    assert alone.value.message.startswith("grasp(water): it breaks the safety rule")
    check_safe(LoggedRecord(tmp_path / "x.jsonl", 7, {**record, "steps": record["steps"][2:]}))  # safe from there


def test_a_closed_writer_refuses_new_records_and_writes_nothing(tmp_path, env01, pour):
    writer = RecordWriter(tmp_path / "people")
    writer.close()
    with pytest.raises(WriterClosed, match="^the server is stopping; the demonstration was not recorded$"):
        writer.append(person_record(env01, POUR, pour))
    assert not (tmp_path / "people").exists()


def test_a_record_whose_environment_id_is_a_path_is_refused_before_anything_is_written(tmp_path, env01, pour):
    record = {**person_record(env01, POUR, pour), "env_id": "../escape"}
    with pytest.raises(ValueError, match="cannot name a log file"):
        RecordWriter(tmp_path / "people").append(record)
    assert listing(tmp_path) == []


def test_a_person_record_names_its_participant_and_corrections_only_when_given(env01, pour):
    plain = person_record(env01, POUR, pour)
    assert re.fullmatch(rf"{re.escape(plain['scenario_id'])}/person-[0-9a-f]{{12}}", plain["demo_id"])
    assert "participant" not in plain and "corrected" not in plain
    named = person_record(env01, POUR, pour, "p7", corrected=[3, 0, 2])
    assert re.fullmatch(rf"{re.escape(named['scenario_id'])}/p7-[0-9a-f]{{12}}", named["demo_id"])
    assert named["participant"] == "p7" and named["corrected"] == [0, 2, 3]
    assert person_record(env01, POUR, pour, corrected=[])["corrected"] == []
    assert "participant" not in person_record(env01, POUR, pour, "")
    assert plain["demo_id"] != person_record(env01, POUR, pour)["demo_id"]  # the same scenario twice: two ids
    assert plain["env_id"] == "w0-env01"


# --- the environments ----------------------------------------------------------------------------------------------

def test_a_world_environment_is_the_catalog_environment_as_that_world_draws_it():
    for seed, env_id in [(0, "env01"), (3, "env05"), (MAX_SEED, "env13")]:
        env = world_environment(seed, env_id)
        rng = np.random.default_rng(seed)
        for spec in ENVIRONMENTS:  # each environment's jitter depends on those drawn before it
            state = build_environment(spec, rng)
            if spec.id == env_id:
                break
        assert env.env_id == f"w{seed}-{env_id}" and env.label == f"{env_id} of world {seed}"
        assert state_to_dict(env.state) == state_to_dict(state)
        assert sorted(env.state.specs) == sorted(state.specs)
    assert state_to_dict(world_environment(1, "env01").state) != state_to_dict(world_environment(0, "env01").state)


@pytest.mark.parametrize("seed", [-1, MAX_SEED + 1])
def test_a_world_seed_outside_the_range_is_refused(seed):
    assert MAX_SEED == 2**31 - 1
    with pytest.raises(ValueError, match=rf"world seed must be a whole number from 0 to {MAX_SEED}, got {seed}$"):
        world_environment(seed, "env01")


def test_an_unknown_environment_is_refused_naming_the_known_ones():
    with pytest.raises(ValueError, match=r"unknown environment 'env99'; known: env01, env02, .*env13$"):
        world_environment(0, "env99")


def test_an_environment_file_gets_a_safe_id_with_a_hash_of_its_content(env01):
    text = environment_text(env01.state)
    env = file_environment("kitchen.json", text)
    assert re.fullmatch(r"kitchen-[0-9a-f]{8}", env.env_id) and env.label == "kitchen.json"
    assert state_to_dict(env.state) == state_to_dict(env01.state)
    assert file_environment("kitchen.json", text).env_id == env.env_id  # the same content, the same id
    other = file_environment("kitchen.json", environment_text(world_environment(1, "env01").state))
    assert other.env_id != env.env_id and other.env_id.startswith("kitchen-")
    digest = env.env_id.rsplit("-", 1)[1]
    assert file_environment("../../a b/my kitchen!.json", text).env_id == f"my_kitchen-{digest}"
    assert file_environment("../../a b/my kitchen!.json", text).label == "my kitchen!.json"
    assert file_environment("..json", text).env_id == f"environment-{digest}"  # a stem with nothing safe in it
    assert file_environment("-_é_-.json", text).env_id == f"environment-{digest}"
    assert file_environment("_x-.json", text).env_id == f"x-{digest}"
    assert file_environment("k" * 50 + ".json", text).env_id == f"{'k' * 40}-{digest}"
    assert file_environment("kitchen", text).env_id == f"kitchen-{digest}"
    assert file_environment("Kitchen_2.json", text).env_id == f"Kitchen_2-{digest}"  # capitals and digits kept
    assert file_environment("Xk-X.json", text).env_id == f"Xk-X-{digest}"


def test_an_environment_files_id_stays_the_same_across_versions(env01):
    """People's logs are filed under the id: the same file must keep its id, or its new records go to another
    log. The hash is of the objects and the state as the simulator reads them, with sorted keys, so neither the
    file's key order nor its spacing changes it."""
    text = environment_text(env01.state)
    assert file_environment("kitchen.json", text).env_id == "kitchen-e9735fa7"
    shuffled = json.loads(text)
    shuffled["state"] = dict(reversed(list(shuffled["state"].items())))
    shuffled["state"]["objects"] = dict(reversed(list(shuffled["state"]["objects"].items())))
    assert file_environment("kitchen.json", json.dumps(shuffled, indent=3)).env_id == "kitchen-e9735fa7"
    for name in ("kitchen.json", "../../a b/my kitchen!.json", "..json", "k" * 50 + ".json"):
        assert SAFE_NAME.match(file_environment(name, text).env_id)


def test_an_environment_file_whose_supports_form_a_loop_is_refused(env01):
    env = json.loads(environment_text(env01.state))
    env["state"]["objects"]["obj02"]["support"] = "obj20"
    with pytest.raises(ValueError, match=r"kitchen.json:1: state.objects.obj\d+.support: the objects it rests on form "
                                         r"a loop through obj\d+$"):
        file_environment("kitchen.json", json.dumps(env))


def test_an_object_resting_on_a_loop_it_is_not_part_of_is_refused(env01):
    env = json.loads(environment_text(env01.state))
    objects = env["state"]["objects"]
    objects["obj01"].update(support="obj02", relation="on")  # obj01, the first object, rests on the loop
    objects["obj02"].update(support="obj08", relation="on")
    objects["obj08"].update(support="obj02", relation="on")
    with pytest.raises(ValueError, match=r"^k.json:1: state.objects.obj01.support: the objects it rests on form a "
                                         r"loop through obj02$"):
        file_environment("k.json", json.dumps(env))


def test_a_named_file_is_read_as_utf8_whatever_the_locale(tmp_path, env01, monkeypatch):
    (tmp_path / "flat.json").write_text(environment_text(env01.state), encoding="utf-8")
    encodings = []
    real = pathlib.Path.read_text

    def spy(self, encoding=None, *args, **kwargs):
        if self.name == "flat.json":
            encodings.append(encoding)
        return real(self, encoding, *args, **kwargs)

    monkeypatch.setattr(pathlib.Path, "read_text", spy)
    read_named(tmp_path, "flat.json")
    assert len(encodings) == 1 and encodings[0] is not None and codecs.lookup(encodings[0]).name == "utf-8"


def test_the_named_files_are_the_json_files_with_safe_names_directly_in_the_folder(tmp_path, env01):
    folder = tmp_path / "environments"
    assert named_files(folder) == []  # no folder: no names
    folder.mkdir()
    text = environment_text(env01.state)
    for name in ("b.json", "a.json", "a b.json", ".hidden.json", "notes.txt", "x.json.bak", "two.dots.json"):
        (folder / name).write_text(text)
    (folder / "dir.json").mkdir()
    (folder / "sub").mkdir()
    (folder / "sub" / "c.json").write_text(text)
    (tmp_path / "outside.json").write_text(text)
    assert named_files(folder) == ["a.json", "b.json"]
    assert named_files(folder / "a.json") == []  # a file is no folder


def test_only_a_listed_name_is_read_and_any_other_is_refused_unopened(tmp_path, env01):
    folder = tmp_path / "environments"
    folder.mkdir()
    (folder / "flat.json").write_text(environment_text(env01.state), encoding="utf-8")
    (tmp_path / "outside.json").write_text(environment_text(env01.state))
    env = read_named(folder, "flat.json")
    assert env.env_id.startswith("flat-") and env.label == "flat.json"
    assert state_to_dict(env.state) == state_to_dict(env01.state)
    for name in ("../outside.json", "sub/flat.json", "flat", "FLAT.json", str(folder / "flat.json")):
        with pytest.raises(ValueError, match=rf"no environment file {re.escape(repr(name))} in environments/; "
                                             "choose one of the list"):
            read_named(folder, name)
