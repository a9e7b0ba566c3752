"""scripts/veil_timing.py: the VEIL pipeline's time read back from MLflow runs as the stages record them."""

from __future__ import annotations

import importlib.util
import json
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
spec = importlib.util.spec_from_file_location("veil_timing", ROOT / "scripts" / "veil_timing.py")
veil_timing = importlib.util.module_from_spec(spec)
spec.loader.exec_module(veil_timing)


def _record(client, experiment: str, name: str, start: int, seconds: float, parent: str | None = None,
            metric: float | None = None, status: str = "FINISHED") -> str:
    tags = {"mlflow.runName": name} | ({"mlflow.parentRunId": parent} if parent else {})
    run = client.create_run(experiment, start_time=start, tags=tags, run_name=name)
    if metric is not None:
        client.log_metric(run.info.run_id, "seconds", metric)
    client.set_terminated(run.info.run_id, status, end_time=start + int(1000 * seconds))
    return run.info.run_id


def test_the_latest_finished_run_of_each_stage_and_the_methods_of_its_evaluation(tmp_path: Path,
                                                                                  monkeypatch) -> None:
    from mlflow.tracking import MlflowClient

    uri = f"sqlite:///{tmp_path / 'mlflow.db'}"
    client = MlflowClient(uri)
    experiment = client.create_experiment("veil")
    now = int(time.time() * 1000)
    _record(client, experiment, "veil-evaluate", now - 10_000_000, 999.0)  # an older run: not read
    evaluate = _record(client, experiment, "veil-evaluate", now, 400.0)
    _record(client, experiment, "veil-evaluate", now + 5_000_000, 3.0, status="FAILED")  # failed: not read
    _record(client, experiment, "mrf_categories", now, 1.0, parent=evaluate, metric=300.0)
    _record(client, experiment, "chance", now, 1.0, parent=evaluate, metric=20.0)
    _record(client, experiment, "veil-import", now, 2.0)
    _record(client, experiment, "veil-train", now, 80.0)
    out = tmp_path / "timing.json"
    monkeypatch.setattr("sys.argv", ["veil_timing.py", "--tracking-uri", uri, "--output", str(out)])
    assert veil_timing.main() == 0
    report = json.loads(out.read_text())
    assert report["stages"] == {"import": 2.0, "evaluate": 400.0, "train": 80.0}
    assert report["total"] == 482.0
    assert report["evaluate_methods"] == {"mrf_categories": 300.0, "chance": 20.0}


def test_a_store_without_the_pipelines_runs_names_the_run_it_lacks(tmp_path: Path) -> None:
    from mlflow.tracking import MlflowClient

    uri = f"sqlite:///{tmp_path / 'mlflow.db'}"
    MlflowClient(uri).create_experiment("other")
    with pytest.raises(SystemExit, match="veil-import"):
        veil_timing.timing(uri)
