"""Stages record into MLflow: runs, parameters, metrics, children and artifacts read back."""

import json
import os
import subprocess
from pathlib import Path

import pytest
from mlflow.tracking import MlflowClient
from params_files import selection_at

from taskseq.cli import main
from taskseq.demonstrations.ingest import write_tables
from taskseq.features.dataset import write_features
from taskseq.track.mlflow_runs import EXPERIMENT, locks_md5


@pytest.fixture
def store(tmp_path, monkeypatch):
    uri = f"sqlite:///{tmp_path / 'mlflow.db'}"
    monkeypatch.setenv("MLFLOW_TRACKING_URI", uri)
    return MlflowClient(tracking_uri=uri)


def runs(client, stage=None):
    exp = client.get_experiment_by_name(EXPERIMENT)
    query = f"tags.`dvc.stage` = '{stage}'" if stage else ""
    return client.search_runs([exp.experiment_id], filter_string=query)


def test_a_stage_opens_one_run_with_params_tags_and_metrics(store, benchmark_logs, tmp_path):
    out, metrics = tmp_path / "processed", tmp_path / "dataset.json"
    assert main(["ingest", "--input", str(benchmark_logs), "--output", str(out), "--metrics", str(metrics)]) == 0
    (run,) = runs(store, "ingest")
    assert run.info.status == "FINISHED" and run.info.run_name == "ingest"
    assert run.data.tags["dvc.stage"] == "ingest" and len(run.data.tags["data.hash"]) == 32
    head = subprocess.run(["git", "rev-parse", "HEAD"], capture_output=True, text=True).stdout.strip() or "unknown"
    assert run.data.tags["git.commit"] == run.data.tags["mlflow.source.git.commit"] == head
    assert run.data.params["cli.input"] == str(benchmark_logs)
    assert run.data.metrics["sequences"] == json.loads(metrics.read_text())["sequences"] == 127


def test_a_failed_stage_leaves_its_run_failed(store, tmp_path):
    bad = tmp_path / "raw"
    bad.mkdir()
    (bad / "x.jsonl").write_text("{broken\n")
    assert main(["ingest", "--input", str(bad), "--output", str(tmp_path / "o"), "--metrics", str(tmp_path / "m")]) == 1
    (run,) = runs(store, "ingest")
    assert run.info.status == "FAILED"


def test_crossval_has_a_child_run_per_method_with_the_same_keys(store, benchmark_tables, benchmark_steps, tmp_path):
    write_tables(benchmark_tables[0], tmp_path / "processed")
    write_features(*benchmark_steps, tmp_path / "features")
    code = main(["crossval", "--features", str(tmp_path / "features"), "--processed", str(tmp_path / "processed"),
                 "--set", "crossval.folds=2", "--methods", "chance", "multiclass",
                 "--output", str(tmp_path / "reports")])
    assert code == 0
    (parent,) = runs(store, "crossval")
    children = [r for r in runs(store) if r.data.tags.get("mlflow.parentRunId") == parent.info.run_id]
    assert sorted(c.info.run_name for c in children) == ["chance", "multiclass"]
    keys = [set(c.data.metrics) for c in children]
    assert "average_prim" in keys[0] & keys[1] and "move_close_prim" in keys[0] & keys[1]
    artifacts = {a.path for a in store.list_artifacts(parent.info.run_id)}
    assert {"table1.csv", "table1.tex", "metrics.json"} <= artifacts
    local = store.download_artifacts(parent.info.run_id, "table1.csv", str(tmp_path / "dl"))
    with open(local) as fh:
        assert fh.read() == (tmp_path / "reports" / "table1.csv").read_text()


def test_no_mlflow_flag_records_nothing(store, benchmark_logs, tmp_path):
    out = tmp_path / "processed"
    assert main(["--no-mlflow", "ingest", "--input", str(benchmark_logs), "--output", str(out),
                 "--metrics", str(tmp_path / "m.json")]) == 0
    assert store.get_experiment_by_name(EXPERIMENT) is None
    assert os.environ["MLFLOW_TRACKING_URI"].startswith("sqlite:///")


def test_child_runs_carry_what_tells_them_apart_and_their_programs(store, benchmark_tables, benchmark_steps,
                                                                    tmp_path):
    write_tables(benchmark_tables[0], tmp_path / "processed")
    write_features(*benchmark_steps, tmp_path / "features")
    code = main(["crossval", "--features", str(tmp_path / "features"), "--processed", str(tmp_path / "processed"),
                 "--set", "crossval.folds=2", "--methods", "multiclass", "only_edge", "--selection",
                 str(selection_at(tmp_path / "selection.json", 2.5)),
                 "--world-seed", "7", "--recordings", "0", "--output", str(tmp_path / "reports")])
    assert code == 0
    (parent,) = runs(store, "crossval")
    status = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], capture_output=True, text=True)
    dirty = "unknown" if status.returncode else str(bool(status.stdout.strip())).lower()
    assert parent.data.tags["git.dirty"] == dirty
    # the run's tags describe the folder it ran in (tests/test_provenance_behaviour.py)
    assert parent.data.tags["dvc.lock.md5"] == locks_md5()
    exp = store.get_experiment_by_name(EXPERIMENT)
    assert exp.tags["mlflow.experimentKind"] == "custom_model_development"  # the UI opens on the runs table
    children = {r.info.run_name: r for r in runs(store) if r.data.tags.get("mlflow.parentRunId") == parent.info.run_id}
    edge = children["only_edge"].data.params
    assert edge["method"] == "only_edge" and edge["feature_set"] == "edge" and edge["C"] == "2.5"
    assert edge["world_seed"] == children["multiclass"].data.params["world_seed"] == "7"
    local = store.download_artifacts(children["only_edge"].info.run_id, "sequences.json", str(tmp_path / "dl"))
    table = json.loads(Path(local).read_text())
    with (tmp_path / "reports" / "crossval_sequences.csv").open() as fh:
        written = [line for line in fh if line.startswith("only_edge,")]
    assert "scenario" in table["columns"] and len(table["data"]) == len(written) > 100  # every program of it


def test_train_logs_the_objective_and_gap_of_every_iteration(store, benchmark_steps, tmp_path):
    write_features(*benchmark_steps, tmp_path / "features")
    assert main(["train", "--features", str(tmp_path / "features"), "--set", "train.method=only_edge",
                 "--model", str(tmp_path / "m.npz")]) == 0
    (run,) = runs(store, "train")
    gaps = store.get_metric_history(run.info.run_id, "gap")
    assert len(gaps) == int(run.data.metrics["iterations"]) and [m.step for m in gaps] == list(range(len(gaps)))
    assert gaps[-1].value <= gaps[0].value


def test_under_dvc_the_store_is_the_repositorys_even_from_a_temporary_copy(monkeypatch, tmp_path):
    from taskseq.track.mlflow_runs import tracking_uri

    monkeypatch.delenv("MLFLOW_TRACKING_URI")
    monkeypatch.setenv("DVC_ROOT", str(tmp_path / "repo"))
    monkeypatch.chdir(tmp_path)
    assert tracking_uri() == f"sqlite:///{tmp_path / 'repo' / 'mlflow.db'}"


def test_from_a_subfolder_of_a_dvc_project_the_store_is_the_projects_and_outside_one_there_is_none(monkeypatch,
                                                                                                   tmp_path):
    from taskseq.track.mlflow_runs import tracking_uri

    monkeypatch.delenv("MLFLOW_TRACKING_URI")
    monkeypatch.delenv("DVC_ROOT", raising=False)
    (tmp_path / "repo" / ".dvc").mkdir(parents=True)
    (tmp_path / "repo" / "data" / "worlds").mkdir(parents=True)
    monkeypatch.chdir(tmp_path / "repo" / "data" / "worlds")
    assert tracking_uri() == f"sqlite:///{tmp_path / 'repo' / 'mlflow.db'}"
    monkeypatch.chdir(tmp_path)
    assert tracking_uri() is None
    monkeypatch.setenv("MLFLOW_TRACKING_URI", "sqlite:///elsewhere.db")
    assert tracking_uri() == "sqlite:///elsewhere.db"


def test_a_run_from_a_subfolder_is_tagged_with_the_projects_lock_files(monkeypatch, tmp_path):
    from taskseq.track.mlflow_runs import locks_md5, provenance

    monkeypatch.delenv("DVC_ROOT", raising=False)
    (tmp_path / "repo" / ".dvc").mkdir(parents=True)
    (tmp_path / "repo" / "dvc.lock").write_text("schema: '2.0'\nstages: {}\n")
    (tmp_path / "repo" / "data").mkdir()
    monkeypatch.chdir(tmp_path / "repo" / "data")
    assert provenance("generate", [])["dvc.lock.md5"] == locks_md5(tmp_path / "repo") != "none"


def test_a_stage_run_by_hand_outside_a_dvc_project_writes_only_its_outputs_and_says_it_is_not_recorded(
        monkeypatch, tmp_path, capfd):
    monkeypatch.delenv("MLFLOW_TRACKING_URI")
    monkeypatch.delenv("DVC_ROOT", raising=False)
    here = tmp_path / "by-hand"
    here.mkdir()
    monkeypatch.chdir(here)
    assert main(["generate", "--world-seed", "0", "--output", "raw"]) == 0
    assert sorted(p.name for p in here.iterdir()) == ["raw"]  # no mlflow.db, no mlartifacts
    assert "this run is not recorded in MLflow" in capfd.readouterr().err


def test_a_store_that_refuses_the_run_fails_the_stage_with_one_line(monkeypatch, benchmark_logs, tmp_path, capfd):
    blocked = tmp_path / "not-a-folder"
    blocked.write_text("a file where the store's folder should be")
    monkeypatch.setenv("MLFLOW_TRACKING_URI", f"sqlite:///{blocked / 'mlflow.db'}")
    out = tmp_path / "processed"
    assert main(["ingest", "--input", str(benchmark_logs), "--output", str(out),
                 "--metrics", str(tmp_path / "m.json")]) == 1
    lines = [line for line in capfd.readouterr().err.splitlines() if line.startswith("error")]
    assert len(lines) == 1 and lines[0].startswith(f"error: taskseq ingest: MLflow store sqlite:///{blocked}")
    assert lines[0].endswith("its run is not recorded whole")
