"""The command line as a user meets it: every subcommand's help, `generate` and `bench` on tiny inputs."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from taskseq.cli import build_parser, main
from taskseq.demonstrations.ingest import load_logs, write_tables

SUBCOMMANDS = build_parser()._subparsers._group_actions[0].choices  # name -> parser, as the CLI builds them


def test_the_subcommands_are_the_documented_ones():
    assert set(SUBCOMMANDS) == {"generate", "replay", "ingest", "features", "train", "plan", "crossval", "noise",
                                "feedback", "recipes", "fold_models", "choose_C", "select", "aggregate", "report",
                                "pddl", "bench", "scaling", "dev_world", "drawn_world", "scenes_world", "scenes",
                                "people", "teach", "serve", "layout", "stats", "veil", "cache"}


def test_the_top_level_help_lists_every_subcommand(capsys):
    with pytest.raises(SystemExit) as end:
        main(["--help"])
    assert end.value.code == 0
    text = capsys.readouterr().out
    for name, parser in SUBCOMMANDS.items():
        assert f"    {name}" in text and parser.description.split(":")[0][:40] in " ".join(text.split())


@pytest.mark.parametrize("name", list(SUBCOMMANDS))
def test_every_subcommand_has_help_with_its_description_and_options(name, capsys):
    with pytest.raises(SystemExit) as end:
        main([name, "--help"])
    assert end.value.code == 0
    text = capsys.readouterr().out
    assert text.startswith(f"usage: taskseq {name}")
    assert " ".join(SUBCOMMANDS[name].description.split()) in " ".join(text.split())
    for action in SUBCOMMANDS[name]._actions:
        for flag in action.option_strings:
            assert flag in text, f"{name}: {flag} missing from its help"


def test_the_installed_command_answers_help():
    exe = Path(sys.executable).with_name("taskseq")
    out = subprocess.run([str(exe), "generate", "--help"], capture_output=True, text=True, check=True).stdout
    assert out.startswith("usage: taskseq generate")


def test_generate_writes_the_same_logs_as_the_library_and_nothing_else(benchmark_logs, tmp_path, capsys):
    out = tmp_path / "raw"
    assert main(["--no-mlflow", "generate", "--world-seed", "0", "--output", str(out)]) == 0
    assert list(tmp_path.iterdir()) == [out]
    ours, theirs = sorted(out.iterdir()), sorted(benchmark_logs.iterdir())
    assert [p.name for p in ours] == [p.name for p in theirs]
    assert all(a.read_bytes() == b.read_bytes() for a, b in zip(ours, theirs, strict=True))
    n = sum(len(p.read_text().splitlines()) for p in ours)
    assert f"wrote {n} demonstrations in {len(ours)} files to {out}" in capsys.readouterr().out


def test_generate_with_another_seed_draws_another_world(benchmark_logs, tmp_path):
    out = tmp_path / "raw"
    assert main(["--no-mlflow", "generate", "--world-seed", "1", "--output", str(out)]) == 0
    name = sorted(p.name for p in benchmark_logs.iterdir())[0]
    assert (out / name).read_bytes() != (benchmark_logs / name).read_bytes()


@pytest.mark.parametrize("name", ["generate", "drawn_world"])
def test_a_stage_that_draws_a_world_requires_its_seed_and_says_so(name, tmp_path, capsys):
    """The seed decides the world these stages draw: their help says so, and a missing or negative one is refused by
    the option's name before anything runs."""
    assert "the world to draw" in " ".join(SUBCOMMANDS[name].format_help().split())
    for seed, message in (([], "the following arguments are required: --world-seed"),
                          (["--world-seed", "-1"], "argument --world-seed: expected a whole number, 0 or more, got "
                                                   "'-1'")):
        with pytest.raises(SystemExit) as end:
            main(["--no-mlflow", name, *seed, "--output", str(tmp_path / "out")])
        assert end.value.code == 2 and message in capsys.readouterr().err
    assert not any(tmp_path.iterdir())
    # elsewhere the seed only labels the runs, and the help says that instead
    assert "changes no result" in " ".join(SUBCOMMANDS["crossval"].format_help().split())


def test_a_missing_feature_folder_is_named_as_such(tmp_path, capsys):
    model = tmp_path / "m.npz"
    code = main(["--no-mlflow", "train", "--features", str(tmp_path / "nothere"), "--model", str(model),
                 "--set", "train.method=full"])
    err = capsys.readouterr().err
    assert code == 1 and f"error: {tmp_path / 'nothere'}: not a feature folder (no such folder; `taskseq features` " \
                          "writes one)" in err and not model.exists()
    code = main(["--no-mlflow", "train", "--features", str(tmp_path), "--model", str(model), "--set",
                 "train.method=full"])
    assert code == 1 and "not a feature folder (it holds no steps.parquet" in capsys.readouterr().err


@pytest.fixture(scope="module")
def one_environment(benchmark_logs, tmp_path_factory) -> Path:
    """The Parquet tables of a single environment's demonstrations."""
    root = tmp_path_factory.mktemp("one")
    (root / "raw").mkdir()
    shutil.copy(benchmark_logs / "env01.jsonl", root / "raw")
    tables, _ = load_logs(root / "raw")
    write_tables(tables, root / "processed")
    return root / "processed"


def test_bench_on_one_environment(one_environment, tmp_path, capsys):
    out = tmp_path / "bench.json"
    assert main(["bench", "--processed", str(one_environment), "--set", "train.tol=0.01", "--set", "train.max_iter=40",
                 "--set", "train.n_slacks=2",
                 "--repeats", "2", "--output", str(out)]) == 0
    b = json.loads(out.read_text())
    runs = b["train"]["runs"]
    # each gap of the sweep with the configured and the 1-slack cut, the configured gap, then the relations model
    assert [(r["features"], r["tol"], r["n_slacks"]) for r in runs] == [
        ("full", 1e-3, 2), ("full", 1e-3, 1), ("full", 1e-4, 2), ("full", 1e-4, 1), ("full", 0.01, 2),
        ("relations", 0.01, 2)]
    assert all(r["excess"] >= -1e-9 for r in runs if r["features"] == "full")  # none below the certified bound
    assert b["train"]["lower_bound"] <= min(r["primal_objective"] for r in runs if r["features"] == "full")
    latency = b["latency"]
    assert sorted(latency, key=int) == ["10", "15", "25", "50", "100"]
    candidates = [latency[n]["candidates"] for n in sorted(latency, key=int)]
    assert candidates == sorted(candidates) and candidates[0] < candidates[-1]
    assert all(v["inference_ms"] > 0 and v["step_ms"] > 0 for v in latency.values())
    text = capsys.readouterr().out
    assert f"training on {b['train']['steps']} steps, C=3.0" in text and f"written to {out}" in text
