"""Ingest: the round trip, and a clear error for every kind of bad input."""

import json
import shutil

import pytest

from taskseq.cli import main
from taskseq.demonstrations.ingest import load_logs, read_tables, records_from_tables, write_tables
from taskseq.demonstrations.validate import LogError


def test_log_to_parquet_to_log_round_trip(benchmark_tables, tmp_path):
    tables, records = benchmark_tables
    write_tables(tables, tmp_path / "processed")
    assert records_from_tables(read_tables(tmp_path / "processed")) == [r.record for r in records]



def test_a_world_is_decoded_once_while_its_tables_stay_and_again_when_they_change(benchmark_tables, tmp_path):
    from taskseq.demonstrations.benchmark import load_benchmark

    tables, records = benchmark_tables
    write_tables(tables, tmp_path / "processed")
    first = load_benchmark(tmp_path / "processed")
    assert load_benchmark(str(tmp_path / "processed")) is first  # the same tables: the one decoded benchmark
    fewer = {t: table.slice(0, 1) if t == "sequences" else table for t, table in tables.items()}
    write_tables(fewer, tmp_path / "processed")
    again = load_benchmark(tmp_path / "processed")
    assert again is not first and len(again.records) == 1 < len(first.records)
    assert [r["demo_id"] for r in again.records] == [records[0].record["demo_id"]]

def test_ingest_writes_tables_and_metrics(benchmark_logs, tmp_path):
    out, metrics = tmp_path / "processed", tmp_path / "reports" / "dataset.json"
    assert main(["ingest", "--input", str(benchmark_logs), "--output", str(out), "--metrics", str(metrics)]) == 0
    assert sorted(p.name for p in out.iterdir()) == [
        "environments.parquet", "objects.parquet", "scenarios.parquet", "sequences.parquet", "states.parquet",
        "steps.parquet",
    ]
    assert json.loads(metrics.read_text())["sequences"] == 127


@pytest.fixture
def one_log(benchmark_logs, tmp_path):
    """A folder holding a copy of one generated log file; returns (folder, file, records)."""
    folder = tmp_path / "raw"
    folder.mkdir()
    src = sorted(benchmark_logs.glob("*.jsonl"))[0]
    shutil.copy(src, folder / src.name)
    lines = (folder / src.name).read_text().splitlines()
    return folder, folder / src.name, [json.loads(x) for x in lines]


def rewrite(path, records, line_text=None, line_no=3):
    lines = [json.dumps(r) for r in records]
    if line_text is not None:
        lines[line_no - 1] = line_text
    path.write_text("\n".join(lines) + "\n")


def _set(rec, path, value):
    *head, last = path
    for key in head:
        rec = rec[key]
    rec[last] = value


def _del(rec, path):
    *head, last = path
    for key in head:
        rec = rec[key]
    del rec[last]


def _first_move(rec):
    """Make the first step a grasp from far away: infeasible."""
    rec["steps"][0]["primitive"] = "grasp"


def _far_pose(rec):
    obj = rec["steps"][1]["args"][0] if rec["steps"][1]["args"] else rec["objects"][1]["id"]
    rec["steps"][1]["state"]["objects"][obj]["pose"][0] += 0.5


CASES = {
    "missing field": (lambda r: _del(r, ["task"]), "(record)", "'task' is a required property"),
    "mistyped field": (lambda r: _set(r, ["steps", 2, "args"], "obj14"), "steps[2].args", "is not of type 'array'"),
    "unknown primitive": (lambda r: _set(r, ["steps", 1, "primitive"], "teleport"), "steps[1].primitive", "teleport"),
    "unknown object": (lambda r: _set(r, ["steps", 1, "args", 0], "obj99"), "steps[1].args[0]", "unknown object"),
    "negative size": (lambda r: _set(r, ["objects", 3, "size", 1], -0.2), "objects[3].size[1]", "minimum"),
    "NaN": (lambda r: _set(r, ["objects", 2, "size", 0], float("nan")), "objects[2].size[0]", "finite"),
    "infeasible step": (_first_move, "steps[0]", "infeasible"),
    "state differs from replay": (_far_pose, "steps[1].state.objects", "replaying"),
    "wrong attribute": (lambda r: _set(r, ["objects", 4, "attributes", "volume"], 9.0), "objects[4].attributes.volume",
                        "does not match"),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_bad_record_names_file_line_and_field_and_writes_nothing(case, one_log, tmp_path, capsys):
    folder, path, records = one_log
    mutate, field, message = CASES[case]
    mutate(records[2])
    rewrite(path, records)
    with pytest.raises(LogError) as err:
        load_logs(folder)
    assert (err.value.path, err.value.line) == (str(path), 3)
    assert err.value.field.startswith(field), err.value
    assert message in err.value.message
    out, metrics = tmp_path / "processed", tmp_path / "dataset.json"
    code = main(["ingest", "--input", str(folder), "--output", str(out), "--metrics", str(metrics)])
    assert code == 1
    stderr = capsys.readouterr().err
    assert f"{path}:3: {err.value.field}" in stderr and "nothing was written" in stderr
    assert not out.exists() and not metrics.exists()


def test_broken_json_is_reported_with_its_line(one_log, tmp_path):
    folder, path, records = one_log
    rewrite(path, records, line_text='{"format": "taskseq.demonstration/1", "demo_id": ', line_no=2)
    with pytest.raises(LogError, match=rf"{path.name}:2: \(line\): not valid JSON"):
        load_logs(folder)


def test_failed_ingest_leaves_previous_output_untouched(benchmark_logs, one_log, tmp_path):
    out, metrics = tmp_path / "processed", tmp_path / "dataset.json"
    assert main(["ingest", "--input", str(benchmark_logs), "--output", str(out), "--metrics", str(metrics)]) == 0
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    folder, path, records = one_log
    _del(records[0], ["steps"])
    rewrite(path, records)
    metrics_before = metrics.read_bytes()
    assert main(["ingest", "--input", str(folder), "--output", str(out), "--metrics", str(metrics)]) == 1
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before
    assert metrics.read_bytes() == metrics_before
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []


def test_duplicate_demo_ids_are_refused(one_log):
    folder, path, records = one_log
    records[1]["demo_id"] = records[0]["demo_id"]
    rewrite(path, records)
    with pytest.raises(LogError, match=r":2: demo_id: .* already used"):
        load_logs(folder)


def test_replay_reports_every_bad_record(one_log, capsys):
    folder, path, records = one_log
    _first_move(records[0])
    _first_move(records[2])
    rewrite(path, records)
    assert main(["replay", str(folder)]) == 1
    captured = capsys.readouterr()
    assert f"{path}:1: steps[0]" in captured.err and f"{path}:3: steps[0]" in captured.err
    assert "with problems" in captured.out and f"{len(records) - 2} demonstrations replay exactly" in captured.out


def test_replay_names_an_environment_file_and_a_log_without_demonstrations(tmp_path, capsys):
    environment = tmp_path / "room.json"
    environment.write_text('{\n "objects": [],\n "state": {}\n}\n')
    assert main(["replay", str(environment)]) == 2
    assert (f"{environment}: not a log of demonstrations (JSON Lines, .jsonl); replay re-executes the sequences a "
            "log records, and a .json file is an environment") in capsys.readouterr().err
    (tmp_path / "empty.jsonl").write_text("\n")
    assert main(["replay", str(tmp_path)]) == 2
    assert f"{tmp_path}: holds no demonstration: its log files are empty" in capsys.readouterr().err


def test_empty_folder_is_a_clear_error(tmp_path, capsys):
    args = ["ingest", "--input", str(tmp_path), "--output", str(tmp_path / "out"), "--metrics", str(tmp_path / "m")]
    assert main(args) == 1
    assert "no *.jsonl log files" in capsys.readouterr().err


def test_ingest_and_train_run_by_hand_write_only_where_they_are_told(benchmark_logs, benchmark_steps, tmp_path,
                                                                      monkeypatch):
    """In a checkout, running the commands on one's own data leaves the pipeline's reports/ and data/ alone."""
    from taskseq.cli import main
    from taskseq.features.dataset import write_features

    checkout = tmp_path / "checkout"
    (checkout / "reports").mkdir(parents=True)
    (checkout / "reports" / "dataset.json").write_text('{"committed": true}\n')
    (checkout / "reports" / "train.json").write_text('{"committed": true}\n')
    mine = tmp_path / "mine"
    write_features(*benchmark_steps, mine / "features")
    monkeypatch.chdir(checkout)
    before = {p: p.read_bytes() for p in checkout.rglob("*") if p.is_file()}
    assert main(["ingest", "--input", str(benchmark_logs), "--output", str(mine / "processed")]) == 0
    assert main(["train", "--features", str(mine / "features"), "--set", "train.method=only_edge",
                 "--model", str(mine / "model.npz")]) == 0
    after = {p: p.read_bytes() for p in checkout.rglob("*") if p.is_file()}
    assert after == before
    assert (mine / "processed").is_dir() and (mine / "model.npz").exists()


def _schema_nodes(node, where="schema"):
    """Every subschema of the demonstration schema, with where it is."""
    yield where, node
    for key, value in node.items():
        if key in ("properties", "$defs"):
            for name, child in value.items():
                yield from _schema_nodes(child, f"{where}.{key}.{name}")
        elif key in ("items", "additionalProperties") and isinstance(value, dict):
            yield from _schema_nodes(value, f"{where}.{key}")
        elif key == "oneOf":
            for i, child in enumerate(value):
                yield from _schema_nodes(child, f"{where}.oneOf[{i}]")


def test_the_schema_keeps_to_keywords_whose_meaning_draft_7_shares():
    """The fast validator reads the schema as draft 7: a keyword that draft 2020-12 reads otherwise (`prefixItems`,
    a `$ref` with siblings, `items` as a list) would let it accept what the reference refuses."""
    from taskseq.demonstrations.records import load_schema
    from taskseq.demonstrations.validate import SAME_IN_DRAFT_7

    for where, node in _schema_nodes(load_schema()):
        assert set(node) <= SAME_IN_DRAFT_7, (where, set(node) - SAME_IN_DRAFT_7)
        assert "$ref" not in node or set(node) == {"$ref"}, where
        assert not isinstance(node.get("items"), list), where


def _mutations(record, rng, count):
    """`count` copies of `record`, each with one field deleted, retyped, negated, emptied or one key added."""
    paths = []

    def walk(value, path):
        paths.append(path)
        items = value.items() if isinstance(value, dict) else enumerate(value) if isinstance(value, list) else ()
        for key, child in items:
            walk(child, [*path, key])

    walk(record, [])
    replacements = ["", "x", "x\n", 0, -1, 1, 1.0, 1.5, -0.25, True, False, None, [], ["x"], [0, 0], {}, {"x": 1}]
    for _ in range(count):
        copy = json.loads(json.dumps(record))
        path = paths[rng.randrange(1, len(paths))]
        how = rng.randrange(3)
        if how == 0 and isinstance(path[-1], str):
            _del(copy, path)
        elif how == 1 and isinstance(_get(copy, path), dict):
            _get(copy, path)["unexpected"] = 1
        else:
            _set(copy, path, rng.choice(replacements))
        yield copy


def _get(rec, path):
    for key in path:
        rec = rec[key]
    return rec


def test_the_fast_validator_never_accepts_what_the_reference_refuses(one_log):
    """1,000 one-field mutations of a demonstration (a correction and a participant added, so that every keyword of
    the schema is reached): whatever the compiled schema accepts, jsonschema accepts too."""
    import random

    from fastjsonschema import JsonSchemaValueException

    from taskseq.demonstrations.validate import _VALIDATOR, _accepts

    fast = _accepts()
    _, _, records = one_log
    record = json.loads(json.dumps(records[2]))
    record["participant"] = "p01"
    record["corrected"] = [0, 1]
    assert _VALIDATOR.is_valid(record)
    verdicts = []
    for copy in _mutations(record, random.Random(0), 1000):
        reference = _VALIDATOR.is_valid(copy)
        try:
            fast(copy)
            accepted = True
        except JsonSchemaValueException:  # anything else it raised would fail the test
            accepted = False
        assert reference or not accepted, copy
        verdicts.append((accepted, reference))
    assert 100 < sum(r for _, r in verdicts) < len(verdicts) - 100  # both kinds, many of each
    assert sum(a != r for a, r in verdicts) <= 20  # it refuses little that the reference accepts (`$` and newline)


def test_arrays_nested_past_the_compiled_validators_depth_still_get_a_named_error(one_log):
    folder, path, records = one_log
    nested = 0
    for _ in range(700):
        nested = [nested]
    records[2]["corrected"] = nested
    rewrite(path, records)
    with pytest.raises(LogError) as err:
        load_logs(folder)
    assert err.value.line == 3 and err.value.field.startswith("corrected")
